// One seed, one result on any x86-64 machine (src/cli/pinned_numerics.hpp): a fold rollout of make demo's setting and
// a short learning run give the digest committed below and the record in test/data, in this process, in one that
// sees a CPU with nothing beyond SSE3 (glibc's masks) and with another CPU's cache sizes given to Eigen then pinned
// over, and (on a CPU with FMA) not in one whose libm is left unpinned.
//
// A change that moves a fold rollout by one bit changes these: if the change is meant, the failure prints the new
// digest, or writes the new learning record (test/data/reproducibility_learning.txt); commit it and say what moved.
// The learning's record is committed whole, so that a machine where it differs names the first rollout that does,
// and whether its sampled parameters or only its outcome moved.
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/digest.hpp"

#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#if defined(__x86_64__)
#include <sys/platform/x86.h>
#endif

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

const std::string kSource = BIMANUAL_SKILLS_SOURCE_DIR;
// Measured on an Intel Xeon (AVX-512, FMA), and with every CPU feature beyond SSE3 masked (below).
constexpr const char* kRolloutDigest = "b183d5a43ca28cdb";
const std::string kLearningRecord = kSource + "/test/data/reproducibility_learning.txt";

br::FoldLearningConfig demoConfig() {
  return br::FoldLearningConfig::fromYamlFile(kSource + "/config/fold_demo.yaml");
}

template <typename Matrix>
void addMatrix(bimanual_skills::io::Digest& digest, const Matrix& m) {
  digest.add(m.data(), sizeof(typename Matrix::Scalar) * static_cast<std::size_t>(m.size()));
}

void addImage(bimanual_skills::io::Digest& digest, const cv::Mat& image) {
  for (int row = 0; row < image.rows; ++row) digest.add(image.ptr(row), image.cols * image.elemSize());
}

/// A learning directory's record without its wall-clock column, one line per rollout in the order of its key (threads
/// finish in any order): the digest of its sampled parameters (rollout_parameters.csv), then its rollouts.csv row.
std::vector<std::string> learningRecord(const std::string& dir) {
  std::vector<std::string> lines;
  for (bimanual_skills::testing::CsvRow& row : bimanual_skills::testing::readCsv(dir + "/rollouts.csv")) {
    row.erase("wall_seconds");
    std::string line = "rollout \"" + row["algorithm"] + "\"," + row["run"] + "," + row["epoch"] + "," + row["kind"] +
                       "," + row["index"] + " ";
    for (const char* key : {"algorithm", "run", "epoch", "kind", "index"}) row.erase(key);
    for (const auto& [column, value] : row) line += column + "=" + value + ";";
    lines.push_back(line);
  }
  std::ifstream parameters(dir + "/rollout_parameters.csv");
  std::string line;
  std::getline(parameters, line);  // the header
  while (std::getline(parameters, line)) {
    // The key is the first five cells (algorithm, run, epoch, kind, index); the algorithm's name is quoted.
    std::size_t at = line.find('"', 1);
    for (int cell = 0; cell < 5 && at != std::string::npos; ++cell) at = line.find(',', at + 1);
    bimanual_skills::io::Digest digest;
    digest.add(at == std::string::npos ? std::string() : line.substr(at));
    lines.push_back("parameters " + line.substr(0, at) + " " + digest.hex());
  }
  std::sort(lines.begin(), lines.end());
  return lines;
}

std::vector<std::string> readLines(const std::string& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

/// This test program run again with `environment` (NAME=VALUE ... or env's -u NAME) on the digest tests; its status.
int digestTestsWith(const std::string& environment) {
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe").string();
  return bimanual_skills::testing::runQuietly("env " + environment + " " + exe +
                                              " --gtest_filter='Reproducibility.*Committed*'");
}

}  // namespace

TEST(Reproducibility, NumericsArePinned) {
  EXPECT_EQ(bimanual_skills::cli::numericsState(), "pinned");
}

TEST(Reproducibility, FoldRolloutGivesTheCommittedDigest) {
  const br::FoldLearningConfig config = br::withSimulationRenderer(demoConfig());
  br::FoldRolloutTask task(config.task, config.reward);
  const br::RolloutResult result = task.run(task.initialParameters(), 12345u);
  ASSERT_TRUE(result.ok) << result.reason;
  bimanual_skills::io::Digest digest;
  digest.add(&result.reward, sizeof result.reward);
  addMatrix(digest, result.terms);
  addMatrix(digest, task.lastRollout().cloth_vertices);
  addImage(digest, task.reward().bgr());
  addImage(digest, task.reward().depth());
  EXPECT_EQ(digest.hex(), kRolloutDigest) << "the demonstration's rollout (seed 12345): R = " << result.reward;
}

/// make demo's setting, 1 update x 3 rollouts, learnt here: "" when its record is the committed one, else where it
/// first differs (the record is left in a file named there).
std::string shortLearningDifference() {
  br::FoldLearningConfig config = demoConfig();
  config.updates = 1;
  config.rollouts = 3;
  config.reuse = 3;
  const std::string dir = ::testing::TempDir() + "/reproducibility_learning_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  {
    br::FoldLearner learner(config, dir);
    learner.learn();
  }
  const std::vector<std::string> record = learningRecord(dir);
  const std::vector<std::string> expected = readLines(kLearningRecord);
  if (record.empty()) return "no record in " + dir;
  if (record == expected) {
    std::filesystem::remove_all(dir);
    return "";
  }
  const std::string written = dir + "/reproducibility_learning.txt";
  std::ofstream out(written);
  for (const std::string& line : record) out << line << '\n';
  std::size_t k = 0;
  while (k < record.size() && k < expected.size() && record[k] == expected[k]) ++k;
  std::ostringstream message;
  message << "make demo's setting, 1 update x 3 rollouts, seed " << config.seed << ": the record (" << written
          << ") differs from " << kLearningRecord << " first at line " << k + 1 << " of " << record.size()
          << ":\n  here:      " << (k < record.size() ? record[k] : "(none)")
          << "\n  committed: " << (k < expected.size() ? expected[k] : "(none)");
  return message.str();
}

TEST(Reproducibility, ShortLearningGivesTheCommittedRecord) {
  EXPECT_EQ(shortLearningDifference(), "");
}

// Eigen blocks its products by the cache sizes the CPU reports, and the blocking orders their sums: with an AMD
// EPYC's (what Eigen read there) the learning's first policy moves; the program's pin puts the committed one back.
TEST(Reproducibility, TheSameWhateverCachesTheCpuReports) {
  Eigen::setCpuCacheSizes(32 * 1024, 512 * 1024, 32 * 1024 * 1024);
  EXPECT_NE(shortLearningDifference(), "") << "Eigen's blocking no longer moves the learning: the pin is not needed";
  char program[] = "test_reproducibility";
  char* argv[] = {program, nullptr};
  bimanual_skills::cli::pinNumerics(argv);  // returns: libm and OpenCV are pinned in this process already
  EXPECT_TRUE(bimanual_skills::cli::eigenPinned());
  EXPECT_EQ(shortLearningDifference(), "");
}

TEST(Reproducibility, TheSameOnABaselineCpu) {
  // What glibc would choose on the first x86-64 CPUs (SSE2, SSE3); OpenCV keeps to its baseline anyway (this
  // process's mask is inherited).
  EXPECT_EQ(digestTestsWith("GLIBC_TUNABLES=glibc.cpu.hwcaps=-FMA,-FMA4,-AVX512F,-AVX2,-AVX,-SSE4_2,-SSE4_1,-SSSE3"),
            0);
}

TEST(Reproducibility, OtherBitsWithLibmUnpinned) {
#if defined(__x86_64__)
  if (!CPU_FEATURE_PRESENT(FMA)) GTEST_SKIP() << "this CPU has no FMA: its libm runs the pinned code anyway";
#else
  GTEST_SKIP() << "not x86-64";
#endif
  // The marker says "already re-executed": the program warns and runs with libm's FMA code.
  EXPECT_NE(digestTestsWith(std::string("-u GLIBC_TUNABLES ") + bimanual_skills::cli::kPinnedMarker + "=1"), 0);
}
