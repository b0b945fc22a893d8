// Smoke test of the experiment programs (ik_benchmark, ps_benchmark, dr_benchmark, rollout_benchmark,
// workspace_benchmark, fold_benchmark, track_benchmark) in --quick
// mode: they run, write summary.json with every field, CSV, PNG and tables.md, reject bad arguments with exit code 2
// (--help: usage, 0), dr_benchmark writes the same results with any number of jobs, and rollout_benchmark (its own
// ROS master and rollout_worker processes) gets from the workers the results of the threads, bit for bit (else it
// exits 1). No assertion on time.
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace fs = std::filesystem;

using bimanual_skills::testing::csvNumber;
using bimanual_skills::testing::CsvRow;
using bimanual_skills::testing::readCsv;
using bimanual_skills::testing::readTextFile;
using bimanual_skills::testing::runQuietly;

TEST(IkBenchmarkSmoke, QuickRunWritesEveryOutput) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_ik_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(IK_BENCHMARK) + " --experiment all --seed 3 --quick --out " + out.string()), 0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field :
       {"\"solver\"", "\"setting\"", "\"samples\"", "\"success_rate\"", "\"within_limits_rate\"", "\"median_us\"",
        "\"p99_us\"", "\"mean_iterations\"", "\"mean_residual_failed\"", "\"seed\": 3", "\"CTP+SD+SVF\"", "\"KDL\"",
        "\"robot\": \"wam\"", "\"excess_median_rad\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  for (const char* file :
       {"table34.csv", "table35.csv", "fig35.csv", "fig32.csv", "fig33.csv", "tracik.csv", "table34.png", "table35.png",
        "fig35.png", "fig32.png", "fig33.png", "fig34.png", "tracik.png", "closest.csv", "tables.md"}) {
    EXPECT_TRUE(fs::exists(out / file) && fs::file_size(out / file) > 0) << file;
  }
  fs::remove_all(out);
}

TEST(IkBenchmarkSmoke, BadArgumentsAreRejected) {
  const std::string program = IK_BENCHMARK;
  EXPECT_EQ(runQuietly(program + " --experiment nope --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment table34 --seed -4 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment table34 --seed 1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment table34 --seed 1 --out /tmp/x --fast"), 2);
}

TEST(PsBenchmarkSmoke, QuickRunWritesEveryOutput) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_ps_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(PS_BENCHMARK) + " --experiment all --runs 2 --seed 3 --quick --out " + out.string()),
            0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"algorithm\": \"REPS\"", "\"algorithm\": \"DREPS\"", "\"algorithm\": \"nDREPS\"",
                            "\"algorithm\": \"PI2-CMA\"", "\"runs\": 2", "\"satisfactory_runs\"",
                            "\"mean_unsatisfactory_reward\"", "\"plateau_runs\"", "\"seed\": 3", "\"dimension\": 100",
                            "\"runs_ending_at_an_optimum\"", "\"mean_final_stddev\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  for (const char* experiment : {"multimodal2d", "multimodal20", "multimodal50", "multimodal100", "bottles617",
                                 "bottles", "circle", "pi2viapoint"}) {
    for (const char* extension : {".csv", ".png"}) {
      const fs::path file = out / (std::string(experiment) + extension);
      EXPECT_TRUE(fs::exists(file) && fs::file_size(file) > 0) << file;
    }
  }
  EXPECT_NE(readTextFile(out / "tables.md").find("### multimodal_scale"), std::string::npos);
  fs::remove_all(out);
}

TEST(PsBenchmarkSmoke, TheWamBottleTaskLearnsOnThreadsAndWritesItsPaths) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_ps_benchmark_wam_bottles";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(PS_BENCHMARK) +
                       " --experiment wam_bottles --runs 1 --seed 3 --jobs 2 --quick --out " + out.string()),
            0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"experiment\": \"wam_bottles\"", "\"algorithm\": \"DREPS\"", "\"satisfactory_runs\"",
                            "\"failed_rollout_share\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  for (const char* file : {"wam_bottles.csv", "wam_bottles_paths.csv", "wam_bottles.png", "wam_bottles_paths.png"}) {
    EXPECT_TRUE(fs::exists(out / file) && fs::file_size(out / file) > 0) << file;
  }
  // One path per algorithm and run, its samples from the line's start to beyond its goal.
  const std::string paths = readTextFile(out / "wam_bottles_paths.csv");
  EXPECT_NE(paths.find("wam_bottles,REPS,0,Ok,"), std::string::npos);
  EXPECT_NE(paths.find("wam_bottles,DREPS,0,Ok,"), std::string::npos);
  fs::remove_all(out);
}

TEST(PsBenchmarkSmoke, GuidedLearningWritesItsFiguresTheSameOnOneThreadOrTwo) {
  const fs::path one = fs::temp_directory_path() / "bimanual_skills_ps_benchmark_guided1";
  const fs::path two = fs::temp_directory_path() / "bimanual_skills_ps_benchmark_guided2";
  fs::remove_all(one);
  fs::remove_all(two);
  const std::string command = std::string(PS_BENCHMARK) + " --experiment wam_guided --seed 3 --quick";
  ASSERT_EQ(runQuietly(command + " --jobs 1 --out " + one.string()), 0);
  ASSERT_EQ(runQuietly(command + " --jobs 2 --out " + two.string()), 0);
  const std::string summary = readTextFile(one / "summary.json");
  for (const char* field : {"\"experiment\": \"wam_guided\"", "\"algorithm\": \"Guided\"", "\"satisfactory_runs\"",
                            "\"guided_runs_satisfactory\"", "\"guided_alignment_cost_after\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  for (const char* file : {"wam_guided_runs.csv", "wam_guided_aligned.csv", "wam_guided_paths.csv",
                           "wam_guided_paths.png", "wam_guided_alignment.png", "tables.md"}) {
    EXPECT_TRUE(fs::exists(one / file) && fs::file_size(one / file) > 0) << file;
  }
  for (const char* file : {"wam_guided_runs.csv", "wam_guided_aligned.csv", "wam_guided_paths.csv"}) {
    EXPECT_EQ(readTextFile(one / file), readTextFile(two / file)) << file;
  }
  EXPECT_NE(readTextFile(one / "wam_guided_paths.csv").find("wam_guided,Guided,1,Ok,"), std::string::npos);
  // The comparison with REPS' and DREPS' counts: a table and Holm-corrected tests; bad counts are refused.
  const std::string compare = std::string("/usr/bin/python3 ") + GUIDED_COMPARISON + " " + one.string();
  ASSERT_EQ(runQuietly(compare + " --counts REPS=1/20,DREPS=5/20"), 0);
  const std::string table = readTextFile(one / "guided_comparison.md");
  EXPECT_NE(table.find("| REPS | 1 of 20 |"), std::string::npos) << table;
  EXPECT_NE(table.find("DREPS: satisfactory"), std::string::npos) << table;
  EXPECT_NE(table.find("Holm p"), std::string::npos) << table;
  EXPECT_NE(runQuietly(compare + " --counts REPS=21/20"), 0);
  EXPECT_NE(runQuietly(compare + " --counts nonsense"), 0);
  fs::remove_all(one);
  fs::remove_all(two);
}

TEST(PsBenchmarkSmoke, BadArgumentsAreRejected) {
  const std::string program = PS_BENCHMARK;
  EXPECT_EQ(runQuietly(program + " --experiment nope --runs 2 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment bottles --runs 0 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment bottles --runs -3 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment bottles --seed 1"), 2);
}

TEST(DrBenchmarkSmoke, QuickRunWritesEveryOutput) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(DR_BENCHMARK) + " --experiment all --runs 2 --seed 3 --jobs 2 --quick --out " +
                       out.string()),
            0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"experiment\": \"estep\"",
                            "\"speedup\"",
                            "\"max_difference_means\"",
                            "\"method\"",
                            "\"kl\"",
                            "\"algorithm\": \"EM\"",
                            "\"algorithm\": \"PCA\"",
                            "\"rho_mean\"",
                            "\"algorithm\": \"ProMP+REPS\"",
                            "\"algorithm\": \"DMP+REPS\"",
                            "\"algorithm\": \"EM-ProMP(8)\"",
                            "\"algorithm\": \"DR-DMP_CMU(2)\"",
                            "\"algorithm\": \"DR-DMP_MCMU(2,5)\"",
                            "\"algorithm\": \"IDR-DMP_MCMU(2)\"",
                            "\"algorithm\": \"DR-DMP0(7)\"",
                            "\"algorithm\": \"DR-DMP0_MCMU(3,1)\"",
                            "\"algorithm\": \"IDR-DMP_CMU\"",
                            "\"algorithm\": \"EM DR-DMP(3)\"",
                            "\"experiment\": \"optima\"",
                            "\"optimum_reward\"",
                            "\"experiment\": \"nao_walking\"",
                            "\"algorithm\": \"coupling\"",
                            "\"final_reward\"",
                            "\"runs\": 2",
                            "\"seed\": 3"}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  for (const char* file : {"em_vs_pca.csv",       "planar15.csv",
                           "planar10.csv",        "wam_circle.csv",
                           "em_vs_pca.png",       "planar15.png",
                           "planar10.png",        "wam_circle.png",
                           "optima.csv",          "tables.md",
                           "planar10_target.csv", "wam_circle_target.csv",
                           "planar10_paths.png",  "wam_circle_paths.png",
                           "optima_progress.csv", "optima_progress.png",
                           "nao_walks.csv",       "nao_strides.csv",
                           "nao_fit.csv",         "nao_distribution.csv",
                           "nao_correlation.csv", "nao_distribution.png",
                           "nao_correlation.png", "nao_fit.png"}) {
    EXPECT_TRUE(fs::exists(out / file) && fs::file_size(out / file) > 0) << file;
  }
  // The NAO walks: 13 strides of 100 samples; four synergies fit them far better than one; the hip rolls move
  // together (the torso sways over the stance foot).
  EXPECT_EQ(readCsv(out / "nao_strides.csv").size(), 1300u);
  std::map<int, double> nao_error;
  for (const CsvRow& r : readCsv(out / "nao_fit.csv"))
    nao_error[static_cast<int>(csvNumber(r, "r"))] = csvNumber(r, "rms_mean_error_deg");
  ASSERT_TRUE(nao_error.count(1) && nao_error.count(4));
  EXPECT_LT(nao_error[4], 0.2 * nao_error[1]);
  for (const CsvRow& r : readCsv(out / "nao_correlation.csv")) {
    if (r.at("joint_i") == "LHipRoll" && r.at("joint_j") == "RHipRoll") {
      EXPECT_GT(csvNumber(r, "data"), 0.9);
    }
  }
  // The first run's paths: every algorithm's mean policy before and after learning, one row per sample.
  for (const auto& [experiment, header, samples] :
       {std::tuple{"planar10", "algorithm,policy,sample,q1,q2,q3,q4,q5,q6,q7,q8,q9,q10", 101},
        std::tuple{"wam_circle", "algorithm,policy,sample,x,y,z", 201}}) {
    std::istringstream paths(readTextFile(out / (std::string(experiment) + "_paths.csv")));
    std::string line;
    std::getline(paths, line);
    EXPECT_EQ(line, header);
    std::map<std::string, int> rows;
    while (std::getline(paths, line)) {
      const std::size_t policy = line.find(',', line.rfind('"')) + 1;  // algorithm names are quoted
      ++rows[line.substr(0, line.find(',', policy))];
    }
    EXPECT_FALSE(rows.empty()) << experiment;
    for (const auto& [key, count] : rows) EXPECT_EQ(count, samples) << experiment << ' ' << key;
  }
  // optima.csv: the circle demonstration's DMP moves the tool about once round the circle (0.754 m), before and after
  // L-BFGS; the reward with all latent weights zero is a finite cost.
  const std::vector<CsvRow> optima = readCsv(out / "optima.csv");
  const auto row = std::find_if(optima.begin(), optima.end(), [](const CsvRow& r) {
    return r.at("task") == "wam_circle" && r.at("algorithm") == "DR-DMP0(7)";
  });
  ASSERT_NE(row, optima.end());
  for (const char* path : {"initial_path_length", "optimum_path_length"}) {
    EXPECT_GT(csvNumber(*row, path), 0.6) << path;
    EXPECT_LT(csvNumber(*row, path), 0.95) << path;
  }
  EXPECT_TRUE(std::isfinite(csvNumber(*row, "zero_weights_reward")));
  EXPECT_LT(csvNumber(*row, "zero_weights_reward"), 0.0);
  fs::remove_all(out);
}

TEST(DrBenchmarkSmoke, ResultsDoNotDependOnTheNumberOfJobs) {
  const fs::path one = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_jobs1";
  const fs::path three = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_jobs3";
  const std::string command = std::string(DR_BENCHMARK) + " --experiment planar10 --runs 3 --seed 5 --quick";
  ASSERT_EQ(runQuietly(command + " --jobs 1 --out " + one.string()), 0);
  ASSERT_EQ(runQuietly(command + " --jobs 3 --out " + three.string()), 0);
  const std::string csv = readTextFile(one / "planar10.csv");
  EXPECT_GT(csv.size(), 1000u);
  EXPECT_EQ(csv, readTextFile(three / "planar10.csv"));
  fs::remove_all(one);
  fs::remove_all(three);
}

TEST(DrBenchmarkSmoke, BadArgumentsAreRejected) {
  const std::string program = DR_BENCHMARK;
  EXPECT_EQ(runQuietly(program + " --help"), 0);
  EXPECT_EQ(runQuietly(program + " --experiment nope --runs 2 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --runs 0 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --jobs 0 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --jobs -2 --seed 1 --out /tmp/x"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --fast"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --covariance-memory 1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --adapted-covariance "
                                 "--covariance-memory 0.5"),
            2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --exploration -1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --exploration nan"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --epsilon 0"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --reuse -1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment wam_circle --seed 1 --out /tmp/x --forcing-variance inf"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --relative-prior 0"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --kernels 1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --out /tmp/x --rollouts 1"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment wam_circle --seed 1 --out /tmp/x --demonstration hand"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment wam_circle --seed 1 --out /tmp/x --circle square"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment wam_circle --seed 1 --out /tmp/x --alpha-z 0"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --quick --out /tmp/x --algorithms PoWER"), 1);
  // planar10's steps of 0.01 s over 1 s are unstable from α_z ≈ 166 on (optima optimises planar10's DMPs too).
  EXPECT_EQ(runQuietly(program + " --experiment planar10 --seed 1 --quick --out /tmp/x --alpha-z 200"), 2);
  EXPECT_EQ(runQuietly(program + " --experiment optima --seed 1 --quick --out /tmp/x --alpha-z 200"), 2);
}

TEST(DrBenchmarkSmoke, AnExperimentWritesOnlyItsOwnFiles) {
  // em_vs_pca run into a directory that holds optima's results leaves them alone.
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_own_files";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(DR_BENCHMARK) + " --experiment em_vs_pca --seed 1 --quick --out " + out.string()),
            0);
  std::set<std::string> files;
  for (const auto& entry : fs::directory_iterator(out)) files.insert(entry.path().filename().string());
  EXPECT_EQ(files, (std::set<std::string>{"em_vs_pca.csv", "em_vs_pca.png", "summary.json", "tables.md"}));
  fs::remove_all(out);
}

TEST(DrBenchmarkSmoke, OverridesAreRecordedInTheSummary) {
  // --demonstration task perturbs the circle on the tool, --circle nominal measures from the circle it was made
  // from; summary.json says which demonstration and circle each row learned, and with which settings.
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_task_demonstration";
  ASSERT_EQ(
      runQuietly(
          std::string(DR_BENCHMARK) + " --experiment wam_circle --runs 2 --seed 5 --quick --jobs 2 " +
          "--demonstration task --circle nominal --kernels 12 --alpha-z 50 --epsilon 0.7 --algorithms \"DR-DMP0(7)\" " +
          "--out " + out.string()),
      0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field :
       {"\"demonstration\": \"task\"", "\"circle\": \"nominal\"", "\"kernels\": 12", "\"alpha_z\": 50",
        "\"beta_z\": 12.5", "\"epsilon\": 0.7", "\"reuse\": 80", "\"covariance_memory\": 0.9",
        "\"forcing_variance\": 100", "\"covariance_rule\": \"reps\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field << " missing from " << summary;
  }
  EXPECT_EQ(summary.find("\"demonstration\": \"joint\""), std::string::npos) << summary;
  fs::remove_all(out);
}

TEST(DrBenchmarkSmoke, AdaptedCovarianceRunsBesideTheEmVariants) {
  // --adapted-covariance applies to the REPS-based rules; the EM variants keep their own covariance.
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_adapted";
  ASSERT_EQ(runQuietly(std::string(DR_BENCHMARK) + " --experiment wam_circle --runs 2 --seed 5 --quick --jobs 2 " +
                       "--adapted-covariance --algorithms \"DR-DMP0(7),DR-DMP_MCMU(3,2),EM DR-DMP(3)\" --out " +
                       out.string()),
            0);
  const std::string csv = readTextFile(out / "wam_circle.csv");
  EXPECT_NE(csv.find("\"DR-DMP0(7)\""), std::string::npos);
  EXPECT_NE(csv.find("\"DR-DMP_MCMU(3,2)\""), std::string::npos);
  EXPECT_NE(csv.find("\"EM DR-DMP(3)\""), std::string::npos);
  fs::remove_all(out);
}

TEST(DrBenchmarkSmoke, AlgorithmsSelectsTheVariantsToRun) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_dr_benchmark_algorithms";
  ASSERT_EQ(runQuietly(std::string(DR_BENCHMARK) + " --experiment planar10 --runs 2 --seed 5 --quick --jobs 2 " +
                       "--algorithms \"IDR-DMP_CMU,DR-DMP_MCMU(2,5),DR-DMP_CMU(2)\" --out " + out.string()),
            0);
  const std::string csv = readTextFile(out / "planar10.csv");
  EXPECT_NE(csv.find("\"IDR-DMP_CMU\""), std::string::npos);
  EXPECT_NE(csv.find("\"DR-DMP_CMU(2)\""), std::string::npos);
  EXPECT_NE(csv.find("\"DR-DMP_MCMU(2,5)\""), std::string::npos);  // a comma inside the name
  EXPECT_EQ(csv.find("\"DR-DMP_CMU(10)\""), std::string::npos);
  EXPECT_EQ(csv.find("\"DR-DMP_MCMU(2,2)\""), std::string::npos);
  EXPECT_EQ(csv.find("IDR-DMP_MCMU"), std::string::npos);
  fs::remove_all(out);
}

TEST(RolloutBenchmarkSmoke, WorkersGiveTheResultsOfThreads) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_rollout_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(ROLLOUT_BENCHMARK) + " --experiment overhead --rollouts 2 --seed 3 --quick --out " +
                       out.string()),
            0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"task\": \"quadratic\"", "\"task\": \"planar_viapoint\"", "\"task\": \"fold\"",
                            "\"dispatch_ms_per_rollout\"", "\"identical\": true", "\"seed\": 3"}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  EXPECT_EQ(summary.find("\"identical\": false"), std::string::npos);
  for (const char* file : {"rollout_benchmark.csv", "tables.md"}) {
    EXPECT_TRUE(fs::exists(out / file) && fs::file_size(out / file) > 0) << file;
  }
  EXPECT_EQ(
      runQuietly(std::string(ROLLOUT_BENCHMARK) + " --experiment overhead --workers 0 --seed 1 --out " + out.string()),
      2);
  fs::remove_all(out);
}

TEST(RolloutBenchmarkSmoke, ThreadsGiveTheResultsOfOneThreadWithoutAMaster) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_rollout_benchmark_threads_smoke";
  fs::remove_all(out);
  // No ROS master at this URI: the threads experiment needs none.
  ASSERT_EQ(runQuietly("ROS_MASTER_URI=http://localhost:1 " + std::string(ROLLOUT_BENCHMARK) +
                       " --experiment threads --threads 2 --rollouts 2 --seed 3 --quick --out " + out.string()),
            0);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"experiment\": \"threads\"", "\"count\": 1", "\"count\": 2", "\"speedup\"",
                            "\"efficiency\"", "\"arithmetic_speedup\"", "\"identical\": true"}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  EXPECT_EQ(summary.find("\"identical\": false"), std::string::npos);
  EXPECT_NE(readTextFile(out / "tables.md").find("speed-up"), std::string::npos);
  EXPECT_TRUE(fs::exists(out / "threads.png"));
  EXPECT_EQ(
      runQuietly(std::string(ROLLOUT_BENCHMARK) + " --experiment threads --threads 1,0 --seed 1 --out " + out.string()),
      2);
  fs::remove_all(out);
}

TEST(WorkspaceBenchmarkSmoke, QuickRunWritesEveryOutput) {
  const fs::path out = fs::temp_directory_path() / "bimanual_skills_workspace_benchmark_smoke";
  fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(WORKSPACE_BENCHMARK) + " --experiment all --seed 3 --quick --jobs 2 --cache " +
                       (out / "cache").string() + " --write-config " + (out / "bimanual.yaml").string() + " --out " +
                       out.string()),
            0);
  // The placement found, as a configuration the bimanual URDF generator accepts.
  EXPECT_EQ(runQuietly("/usr/bin/python3 " + std::string(BIMANUAL_SKILLS_SOURCE_DIR) +
                       "/scripts/generate_bimanual_urdf.py --config " + (out / "bimanual.yaml").string() + " --out " +
                       (out / "placed.urdf").string()),
            0);
  EXPECT_NE(readTextFile(out / "placed.urdf").find("right_wam_base"), std::string::npos);
  // map wrote its map into the cache; the placement experiments (same settings with --quick) read it from there.
  EXPECT_EQ(std::distance(fs::directory_iterator(out / "cache"), fs::directory_iterator{}), 1);
  EXPECT_NE(readTextFile(out / "tables.md").find("workspace_benchmark"), std::string::npos);
  const std::string summary = readTextFile(out / "summary.json");
  for (const char* field : {"\"experiment\": \"map\"",
                            "\"resolution_m\": 0.2",
                            "\"orientations\": 10",
                            "\"seconds\"",
                            "\"reachable_voxels\"",
                            "\"spherical_wrist\": true",
                            "\"seed\": 3",
                            "\"experiment\": \"fig39\"",
                            "\"experiment\": \"fig310\"",
                            "\"best_dx\"",
                            "\"best_dz\"",
                            "\"quality\"",
                            "\"humanoid_quality\"",
                            "\"best_negative_dx\"",
                            "\"method\": \"GA\"",
                            "\"method\": \"ESCH\"",
                            "\"runs_reaching_ga_best\"",
                            "\"experiment\": \"quality\"",
                            "\"median_seconds\"",
                            "\"brute_force_seconds\""}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  // The indexed, vectorised F and the brute-force sum over every pair agree.
  const std::string difference_key = "\"relative_difference\": ";
  const std::size_t at = summary.find(difference_key);
  ASSERT_NE(at, std::string::npos);
  EXPECT_LT(std::stod(summary.substr(at + difference_key.size())), 1e-9);
  for (const char* file : {"map.csv", "map_slices.png", "fig39.csv", "fig39.png", "fig310.csv", "fig310.png",
                           "placement.csv", "placement.png", "tables.md"}) {
    EXPECT_TRUE(fs::exists(out / file) && fs::file_size(out / file) > 0) << file;
  }
  EXPECT_EQ(runQuietly(std::string(WORKSPACE_BENCHMARK) + " --experiment fig311 --seed 1 --out " + out.string()), 2);
  EXPECT_EQ(runQuietly(std::string(WORKSPACE_BENCHMARK) + " --experiment map --resolution 0.001 --seed 1 --out " +
                       out.string()),
            2);
  EXPECT_EQ(
      runQuietly(std::string(WORKSPACE_BENCHMARK) + " --experiment fig39 --step 0.001 --seed 1 --out " + out.string()),
      2);
  fs::remove_all(out);
}

TEST(FoldBenchmarkSmoke, QuickRunWritesEveryOutputTheSameOnAnyNumberOfJobs) {
  const fs::path one = fs::temp_directory_path() / "bimanual_skills_fold_benchmark_jobs1";
  const fs::path two = fs::temp_directory_path() / "bimanual_skills_fold_benchmark_jobs2";
  fs::remove_all(one);
  fs::remove_all(two);
  for (const auto& [out, jobs] : {std::pair{one, 1}, std::pair{two, 2}}) {
    ASSERT_EQ(runQuietly(std::string(FOLD_BENCHMARK) + " --experiment all --seed 2 --quick --jobs " +
                         std::to_string(jobs) + " --out " + out.string()),
              0);
  }
  for (const char* file : {"folds.csv", "ceiling.csv", "ranking.png", "folds.png", "tables.md", "folds/00_final.png",
                           "folds/00_final_depth.png", "folds/00_flat.png"}) {
    EXPECT_TRUE(fs::exists(one / file)) << file;
  }
  EXPECT_EQ(readTextFile(one / "folds.csv"), readTextFile(two / "folds.csv"));
  EXPECT_EQ(readTextFile(one / "ceiling.csv"), readTextFile(two / "ceiling.csv"));
  const std::string summary = readTextFile(one / "summary.json");
  for (const char* field : {"\"experiment\": \"ranking\"", "\"signal\": \"fold reward\"", "\"spearman\"",
                            "\"spearman_low\"", "\"experiment\": \"ceiling\"", "\"q_max\"", "\"seed\": 2"}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  const std::vector<CsvRow> folds = readCsv(one / "folds.csv");
  ASSERT_EQ(folds.size(), 4u);
  for (const CsvRow& row : folds) {
    EXPECT_EQ(row.at("outcome"), "Ok");
    EXPECT_GE(csvNumber(row, "fold_mismatch"), 0.0);
    EXPECT_EQ(csvNumber(row, "fold_r_fold"), csvNumber(row, "fold_mismatch"));  // the fold setting's weight is 1
  }
  EXPECT_NE(runQuietly(std::string(FOLD_BENCHMARK) + " --experiment folds --count 0 --out " + one.string()), 0);
  EXPECT_NE(summary.find("\"experiment\": \"repeatability\""), std::string::npos);
  EXPECT_NE(summary.find("\"numerics\": \"pinned\""), std::string::npos);
  EXPECT_EQ(readCsv(one / "repeatability.csv").size(), 3u);

  // The second family of strategies, and the final policies of a learning directory perturbed (here a hand-written
  // directory: one noise-free policy of the whole size, all zeros, and rows the experiment leaves out).
  fs::remove_all(two);
  ASSERT_EQ(runQuietly(std::string(FOLD_BENCHMARK) + " --experiment folds --family strategies --seed 2 --quick --out " +
                       two.string()),
            0);
  const std::vector<CsvRow> strategies = readCsv(two / "folds.csv");
  ASSERT_EQ(strategies.size(), 4u);
  EXPECT_TRUE(std::any_of(strategies.begin(), strategies.end(), [](const CsvRow& r) {
    return csvNumber(r, "right_arc") < 1.0 || csvNumber(r, "inward") > 0.0 || csvNumber(r, "hold_after") > 0.5;
  }));
  EXPECT_NE(readTextFile(two / "summary.json").find("\"family\": \"strategies\""), std::string::npos);
  const fs::path learning = fs::temp_directory_path() / "bimanual_skills_fold_smoke_learning";
  fs::create_directories(learning);
  {
    std::ofstream csv(learning / "rollout_parameters.csv");
    csv << "algorithm,run,epoch,kind,index,size,weights...\n";
    for (const char* prefix :
         {"\"DR-DMP0(12)\",0,3,policy,0,252", "\"DR-DMP0(12)\",0,3,sample,0,252", "\"IDR-DMP_CMU\",0,3,policy,0,84"}) {
      csv << prefix;
      for (int i = 0; i < (std::string(prefix).find(",84") != std::string::npos ? 84 : 252); ++i) csv << ",0";
      csv << '\n';
    }
  }
  // Without the runs' coordination (fold_learner's coordination.csv) the policies cannot be run: refused.
  EXPECT_NE(runQuietly(std::string(FOLD_BENCHMARK) + " --experiment learned --seed 2 --quick --from " +
                       learning.string() + " --out " + two.string()),
            0);
  {
    std::ofstream csv(learning / "coordination.csv");
    csv << "algorithm,run,matrix,row,values...\n";
    for (int i = 0; i < 12; ++i) {
      csv << "\"DR-DMP0(12)\",0,0," << i;
      for (int j = 0; j < 12; ++j) csv << ',' << (i == j ? 1 : 0);
      csv << '\n';
    }
  }
  ASSERT_EQ(runQuietly(std::string(FOLD_BENCHMARK) + " --experiment learned --seed 2 --quick --from " +
                       learning.string() + " --out " + two.string()),
            0);
  const std::vector<CsvRow> learned = readCsv(two / "learned.csv");
  ASSERT_EQ(learned.size(), 2u);  // the policy as learned and once perturbed
  EXPECT_EQ(learned[0].at("algorithm"), "DR-DMP0(12)");
  EXPECT_EQ(csvNumber(learned[0], "scale"), 0.0);
  EXPECT_GT(csvNumber(learned[1], "scale"), 0.0);
  EXPECT_NE(runQuietly(std::string(FOLD_BENCHMARK) + " --experiment learned --quick --out " + two.string()), 0);
  EXPECT_NE(
      runQuietly(std::string(FOLD_BENCHMARK) + " --experiment folds --family mirrored --quick --out " + two.string()),
      0);
  fs::remove_all(learning);
}

TEST(TrackBenchmarkSmoke, QuickRunWritesEveryOutputTheSameOnAnyNumberOfJobsAndResumes) {
  const fs::path one = fs::temp_directory_path() / "bimanual_skills_track_smoke_1";
  const fs::path two = fs::temp_directory_path() / "bimanual_skills_track_smoke_2";
  for (const fs::path& out : {one, two}) fs::remove_all(out);
  ASSERT_EQ(runQuietly(std::string(TRACK_BENCHMARK) + " --experiment tracking --seed 2 --quick --jobs 1 --out " +
                       one.string()),
            0);
  for (const char* file :
       {"paths.csv", "samples.csv", "summary.json", "error_by_speed.png", "paths.png", "tables.md"}) {
    EXPECT_TRUE(fs::exists(one / file) && fs::file_size(one / file) > 0) << file;
  }
  const std::string summary = readTextFile(one / "summary.json");
  for (const char* field : {"\"error_by_speed\"", "\"grasp_success\"", "\"error_p95_up_to_0_2_m_s\"",
                            "\"control_allocations\": 0", "\"seed\": 2"}) {
    EXPECT_NE(summary.find(field), std::string::npos) << field;
  }
  // Two jobs: the same records (in the order the paths ended); a run stopped after its first path resumes there.
  ASSERT_EQ(runQuietly(std::string(TRACK_BENCHMARK) + " --experiment tracking --seed 2 --quick --runs 1 --out " +
                       two.string()),
            0);
  ASSERT_EQ(runQuietly(std::string(TRACK_BENCHMARK) + " --experiment tracking --seed 2 --quick --jobs 2 --out " +
                       two.string()),
            0);
  const auto rows = [](const fs::path& file) {
    std::vector<std::string> lines;
    std::istringstream text(readTextFile(file));
    for (std::string line; std::getline(text, line);) lines.push_back(line);
    std::sort(lines.begin(), lines.end());
    return lines;
  };
  EXPECT_EQ(rows(one / "paths.csv"), rows(two / "paths.csv"));
  EXPECT_EQ(rows(one / "samples.csv"), rows(two / "samples.csv"));
  EXPECT_EQ(
      runQuietly(std::string(TRACK_BENCHMARK) + " --experiment tracking --seed 2 --latency -1 --out " + one.string()),
      2);
  for (const fs::path& out : {one, two}) fs::remove_all(out);
}
