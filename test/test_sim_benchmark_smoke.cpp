// Smoke test of sim_benchmark in --quick mode: it runs, writes summary.json with every field and the CSV, answers
// --help on stdout with status 0 and rejects bad arguments with status 2. No assertion on time.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace {

int run(const std::string& command) {
  const int status = std::system((command + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string readFile(const fs::path& path) {
  std::ifstream file(path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

}  // namespace

TEST(SimBenchmarkSmoke, QuickSpeedRunWritesEveryOutput) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(run(std::string(SIM_BENCHMARK) + " --experiment speed --seed 3 --quick --out " + out.string()), 0);
  const std::string summary = readFile(out / "summary.json");
  for (const char* field :
       {"\"program\": \"sim_benchmark\"", "\"seed\": 3", "\"setting\": \"two_arms\"", "\"setting\": \"two_arms_cloth\"",
        "\"realtime_factor\"", "\"bullet_share\"", "\"diverged\": false", "\"fold_on_top\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field << "\n" << summary;
  }
  EXPECT_EQ(summary.find("\"diverged\": true"), std::string::npos) << summary;
  const std::string csv = readFile(out / "speed.csv");
  EXPECT_EQ(csv.rfind("setting,cloth_step_s,", 0), 0u);
  EXPECT_NE(csv.find("\ntwo_arms,"), std::string::npos);
  EXPECT_NE(csv.find("\ntwo_arms_cloth,"), std::string::npos);
  fs::remove_all(out);
}

TEST(SimBenchmarkSmoke, HelpAndBadArguments) {
  const std::string program = SIM_BENCHMARK;
  const fs::path help = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_help.txt";
  const int status = std::system((program + " --help > " + help.string() + " 2>/dev/null").c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_NE(readFile(help).find("usage: sim_benchmark --experiment speed"), std::string::npos);
  EXPECT_EQ(run(program + " --experiment nope --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(run(program + " --experiment speed --seed -4 --out /tmp/x"), 2);
  EXPECT_EQ(run(program + " --experiment speed --seed 1"), 2);
  EXPECT_EQ(run(program + " --experiment speed --seed 1 --out /tmp/x --fast"), 2);
}
