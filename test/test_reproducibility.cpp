// One seed, one result on any x86-64 machine (src/cli/pinned_numerics.hpp): a fold rollout of make demo's setting and
// a short learning run give the digests committed below, in this process, in one that sees a CPU with nothing beyond
// SSE3 (glibc's masks), and (on a CPU with FMA) not in one whose libm is left unpinned.
//
// A change that moves a fold rollout by one bit changes these digests: if the change is meant, the failure prints
// the new ones; put them below and say in the commit what moved.
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
#include <string>
#include <vector>

namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

const std::string kSource = BIMANUAL_SKILLS_SOURCE_DIR;
// Measured on an Intel Xeon (AVX-512, FMA), and with every CPU feature beyond SSE3 masked (below).
constexpr const char* kRolloutDigest = "b183d5a43ca28cdb";
constexpr const char* kLearningDigest = "077ebc21546e039c";

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

/// The rows of a rollouts.csv, without the wall-clock column, in the order of their key (threads finish in any order).
std::string rolloutRows(const std::string& path) {
  std::vector<bimanual_skills::testing::CsvRow> rows = bimanual_skills::testing::readCsv(path);
  std::vector<std::string> lines;
  for (bimanual_skills::testing::CsvRow& row : rows) {
    row.erase("wall_seconds");
    std::string line;
    for (const auto& [column, value] : row) line += column + "=" + value + ";";
    lines.push_back(line);
  }
  std::sort(lines.begin(), lines.end());
  std::string all;
  for (const std::string& line : lines) all += line + "\n";
  return all;
}

/// This test program run again with `environment` (NAME=VALUE ... or env's -u NAME) on the digest tests; its status.
int digestTestsWith(const std::string& environment) {
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe").string();
  return bimanual_skills::testing::runQuietly("env " + environment + " " + exe +
                                              " --gtest_filter='Reproducibility.*CommittedDigest'");
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

TEST(Reproducibility, ShortLearningGivesTheCommittedDigest) {
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
  bimanual_skills::io::Digest digest;
  digest.add(rolloutRows(dir + "/rollouts.csv"));
  EXPECT_EQ(digest.hex(), kLearningDigest)
      << "make demo's setting, 1 update x 3 rollouts, seed " << config.seed << " (" << dir << "/rollouts.csv)";
  std::filesystem::remove_all(dir);
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
