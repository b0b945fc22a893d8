// Smoke test of sim_benchmark in --quick mode: each experiment runs, writes summary.json with every field, its CSV
// and PNG files; the quick friction and payload figures are sane (finite, ordered where the physics orders them);
// --help answers on stdout with status 0 and bad arguments get status 2. No assertion on time.
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

using bimanual_skills::testing::readCsv;
using bimanual_skills::testing::readTextFile;
using bimanual_skills::testing::runQuietly;

double number(const bimanual_skills::testing::CsvRow& row, const std::string& key) {
  return bimanual_skills::testing::csvNumber(row, key);
}

}  // namespace

TEST(SimBenchmarkSmoke, QuickSpeedRunWritesEveryOutput) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(SIM_BENCHMARK) + " --experiment speed --seed 3 --quick --out " + out.string()), 0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field :
       {"\"program\": \"sim_benchmark\"", "\"seed\": 3", "\"setting\": \"two_arms\"", "\"setting\": \"two_arms_cloth\"",
        "\"realtime_factor\"", "\"bullet_share\"", "\"diverged\": false", "\"fold_on_top\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field << "\n" << summary;
  }
  EXPECT_EQ(summary.find("\"diverged\": true"), std::string::npos) << summary;
  const std::string csv = readTextFile(out / "speed.csv");
  EXPECT_EQ(csv.rfind("setting,cloth_step_s,", 0), 0u);
  EXPECT_NE(csv.find("\ntwo_arms,"), std::string::npos);
  EXPECT_NE(csv.find("\ntwo_arms_cloth,"), std::string::npos);
  fs::remove_all(out);
}

TEST(SimBenchmarkSmoke, QuickFrictionRunWritesTable41AndTracking) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_friction";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(SIM_BENCHMARK) + " --experiment friction --seed 3 --quick --out " + out.string()),
            0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"experiment\": \"friction\"", "\"table\": \"4.1\"", "\"model\": \"initial\"",
                            "\"model\": \"basic\"", "\"model\": \"advanced\"", "\"table\": \"tracking\"",
                            "\"compensation\": \"none\"", "\"compensation\": \"advanced\"", "\"rms_rad_mean\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field << "\n" << summary;
  }
  EXPECT_EQ(summary.find("null"), std::string::npos) << summary;  // no NaN or infinity anywhere
  // Table 4.1: 3 models x 7 joints, finite errors, every joint excited by at least one validation run, max ≥ MAE.
  const auto errors = readCsv(out / "friction_errors.csv");
  ASSERT_EQ(errors.size(), 21u);
  for (const auto& row : errors) {
    EXPECT_GE(number(row, "validation_runs"), 1.0);
    EXPECT_TRUE(std::isfinite(number(row, "mae")));
    EXPECT_GT(number(row, "mae"), 0.0);
    EXPECT_GE(number(row, "max_error"), number(row, "mae"));
    EXPECT_LT(number(row, "mae"), 5.0) << row.at("model") << " joint " << row.at("joint");
  }
  // Tracking: friction compensation of either model must beat none on average (by far, even on quick data).
  std::map<std::string, double> mean;
  const auto tracking = readCsv(out / "friction_tracking.csv");
  ASSERT_EQ(tracking.size(), 21u);
  for (const auto& row : tracking) mean[row.at("compensation")] += number(row, "rms_rad") / 7.0;
  EXPECT_LT(mean["basic"], 0.7 * mean["none"]);
  EXPECT_LT(mean["advanced"], 0.7 * mean["none"]);
  EXPECT_LT(mean["none"], 0.1);  // the arm followed the runs (no divergence, no runaway)
  for (const char* file : {"friction_initial.yaml", "friction_basic.yaml", "friction_advanced.yaml",
                           "friction_example.csv", "friction_table41.png", "friction_example.png", "tables.md"}) {
    EXPECT_TRUE(fs::exists(out / file)) << file;
  }
  fs::remove_all(out);
}

TEST(SimBenchmarkSmoke, QuickPayloadRunEstimatesTheWeights) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_payload";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(SIM_BENCHMARK) + " --experiment payload --seed 3 --quick --out " + out.string()), 0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"experiment\": \"payload\"", "\"observer\": \"ours\"", "\"observer\": \"kdl\"",
                            "\"load_kg\": 0.0", "\"load_kg\": 2.0", "\"steady_error_pct\"", "\"transient_peak_n\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field << "\n" << summary;
  }
  EXPECT_EQ(summary.find("null"), std::string::npos) << summary;
  const auto rows = readCsv(out / "payload_summary.csv");
  ASSERT_GE(rows.size(), 4u);  // two observers, at least two loads
  for (const auto& row : rows) {
    // Even on the quick run's coarse friction model both observers see the weight within 15 % (0.75 N at 0 kg).
    EXPECT_LT(number(row, "steady_error_pct"), 15.0) << row.at("observer") << " " << row.at("load_kg") << " kg";
    EXPECT_NEAR(number(row, "steady_estimate_n"), number(row, "true_weight_n"), 0.15 * 9.81 * 2.0);
    EXPECT_GE(number(row, "transient_peak_n"), 0.0);
    EXPECT_LT(number(row, "transient_peak_n"), 20.0);
  }
  const auto series = readCsv(out / "payload.csv");
  EXPECT_GT(series.size(), 1000u);
  EXPECT_TRUE(fs::exists(out / "payload.png"));
  fs::remove_all(out);
}

TEST(SimBenchmarkSmoke, QuickFoldRolloutFollowsTheDemonstration) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_fold";
  fs::remove_all(out);
  ASSERT_EQ(
      runQuietly(std::string(SIM_BENCHMARK) + " --experiment fold_rollout --seed 3 --quick --out " + out.string()), 0);
  const auto rows = readCsv(out / "fold_rollout.csv");
  ASSERT_EQ(rows.size(), 2u);  // ED and CTP+SD+SVF
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("outcome"), "Ok") << row.at("ik_method");
    EXPECT_LT(number(row, "max_ik_error_m"), 0.005) << row.at("ik_method");
    EXPECT_LT(number(row, "max_tracking_error_rad"), 0.1) << row.at("ik_method");
    EXPECT_GT(number(row, "realtime_factor"), 0.0);
  }
  EXPECT_NE(readTextFile(out / "summary.json").find("\"experiment\": \"fold_rollout\""), std::string::npos);
  fs::remove_all(out);
}

// A new arm's friction in one command: the second robot's right arm identified (its plant, gains, limits and no
// cable pairs), the advanced model written where its robot file would name it, and compensating it tracks better.
TEST(SimBenchmarkSmoke, FrictionOfAnotherRobotsArmGoesWhereItsRobotFileNamesIt) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_robot_friction";
  fs::remove_all(out);
  fs::create_directories(out);
  const std::string robot = BIMANUAL_SKILLS_SOURCE_DIR "/config/robots/offset_wrist.yaml";
  ASSERT_EQ(runQuietly(std::string(SIM_BENCHMARK) + " --experiment friction --seed 3 --quick --out " + out.string() +
                       " --robot " + robot + " --arm right --friction-out " + (out / "right.yaml").string()),
            0);
  const bimanual_skills::dynamics::FrictionModel model =
      bimanual_skills::dynamics::loadFrictionModel((out / "right.yaml").string());
  EXPECT_EQ(model.joints.size(), 7u);
  EXPECT_NE(readTextFile(out / "right.yaml").find("--robot " + robot + " on its simulated right arm"),
            std::string::npos);
  std::map<std::string, double> mean;
  for (const auto& row : readCsv(out / "friction_tracking.csv")) mean[row.at("compensation")] += number(row, "rms_rad");
  EXPECT_LT(mean["advanced"], 0.5 * mean["none"]);
  // Fig. 4.2 is the WAM's: refused with the reason on another robot.
  EXPECT_EQ(runQuietly(std::string(SIM_BENCHMARK) + " --experiment payload --seed 3 --quick --out " + out.string() +
                       " --robot " + robot),
            1);
  // An arm its robot file does not have is refused.
  EXPECT_NE(runQuietly(std::string(SIM_BENCHMARK) + " --experiment friction --seed 3 --quick --out " + out.string() +
                       " --robot " + robot + " --arm middle"),
            0);
  fs::remove_all(out);
}

TEST(SimBenchmarkSmoke, SpeedAndFoldRunOnAnotherRobot) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_robot";
  fs::remove_all(out);
  const std::string robot = BIMANUAL_SKILLS_SOURCE_DIR "/config/robots/offset_wrist.yaml";
  for (const char* experiment : {"speed", "fold_rollout"}) {
    ASSERT_EQ(runQuietly(std::string(SIM_BENCHMARK) + " --experiment " + experiment + " --seed 3 --quick --out " +
                         out.string() + " --robot " + robot),
              0)
        << experiment;
  }
  for (const auto& row : readCsv(out / "fold_rollout.csv")) {
    EXPECT_EQ(row.at("outcome"), "Ok") << row.at("ik_method");
    EXPECT_LT(number(row, "max_tracking_error_rad"), 0.1) << row.at("ik_method");
  }
  fs::remove_all(out);
}

TEST(SimBenchmarkSmoke, HelpAndBadArguments) {
  const std::string program = SIM_BENCHMARK;
  const fs::path help = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_help.txt";
  const int status = std::system((program + " --help > " + help.string() + " 2>/dev/null").c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_NE(readTextFile(help).find(
                "usage: sim_benchmark --experiment speed|friction|payload|fold_rollout|scarf_rollout|all"),
            std::string::npos);
  EXPECT_EQ(runQuietly(program + " --experiment nope --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment speed --seed -4 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment speed --seed 1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment speed --seed 1 --out /tmp/x --fast"), 2);
}

TEST(SimBenchmarkSmoke, QuickScarfRolloutComparesItWithTheFold) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_sim_benchmark_scarf";
  fs::remove_all(out);
  ASSERT_EQ(
      runQuietly(std::string(SIM_BENCHMARK) + " --experiment scarf_rollout --seed 3 --quick --out " + out.string()), 0);
  const auto rows = readCsv(out / "scarf_rollout.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].at("task"), "fold");
  EXPECT_EQ(rows[1].at("task"), "scarf");
  EXPECT_EQ(number(rows[1], "cloth_nodes"), 180.0);
  EXPECT_GT(number(rows[0], "us_per_simulated_s_per_node_median"), 0.0);
  EXPECT_GT(number(rows[1], "us_per_simulated_s_per_node_median"), 0.0);
  for (const auto& row : rows) {  // the cloth's own steps: part of the rollout's time, not all of it
    EXPECT_GT(number(row, "cloth_us_per_simulated_s_per_node_median"), 0.0) << row.at("task");
    EXPECT_LT(number(row, "cloth_us_per_simulated_s_per_node_median"),
              number(row, "us_per_simulated_s_per_node_median"))
        << row.at("task");
    EXPECT_GT(number(row, "rest_us_per_simulated_s"), 0.0) << row.at("task");
  }
  EXPECT_EQ(number(rows[1], "control_allocations"), 0.0) << "the scarf's control part allocated";
  EXPECT_NE(readTextFile(out / "summary.json").find("\"experiment\": \"scarf_rollout\""), std::string::npos);
  fs::remove_all(out);
}
