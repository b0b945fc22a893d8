// rostest (test/ps_benchmark_workers.test): ps_benchmark's rollouts on rollout workers. The quick run of every
// experiment goes once in this process and once on the two workers of the test, and worker_0 is killed (SIGKILL) as
// soon as the first experiment is done: the run on the workers must finish on the survivor and write exactly the
// CSVs (learning curves) of the run in this process.
#include "cli/pinned_numerics.hpp"
#include "rollout_test_support.hpp"

#include <ros/ros.h>

#include <gtest/gtest.h>

#include <signal.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>

namespace fs = std::filesystem;
using bimanual_skills::test::lines;
using bimanual_skills::test::pidOf;

namespace {

bool contains(const std::vector<std::string>& text, const std::string& what) {
  for (const std::string& line : text) {
    if (line.find(what) != std::string::npos) return true;
  }
  return false;
}

}  // namespace

TEST(PsBenchmarkWorkers, TheCurvesOnWorkersAreThoseOfThisProcessDespiteADeadWorker) {
  std::string space = "/ps_workers";
  ros::param::get("~worker_namespace", space);
  const fs::path out = fs::temp_directory_path() / ("ps_benchmark_workers_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string common = std::string(PS_BENCHMARK) + " --experiment all --quick --seed 4 --out ";
  ASSERT_EQ(std::system((common + (out / "here").string() + " > " + (out.string() + "_here.log") + " 2>&1").c_str()),
            0);

  const int victim = pidOf(space + "/worker_0");
  ASSERT_GT(victim, 0);
  ASSERT_GT(pidOf(space + "/worker_1"), 0);
  const std::string log = out.string() + "_workers.log";
  int status = -1;
  std::thread run([&] {
    status = std::system((common + (out / "workers").string() + " --worker-namespace " + space +
                          " --worker-timeout 5 > " + log + " 2>&1")
                             .c_str());
  });
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(90.0);
  while (ros::WallTime::now() < deadline && !contains(lines(log), "multimodal2d on workers")) {
    ros::WallDuration(0.01).sleep();
  }
  const bool first_done = contains(lines(log), "multimodal2d on workers");
  EXPECT_TRUE(first_done) << "no report of the first experiment in " << log;
  if (first_done) {
    EXPECT_EQ(::kill(victim, SIGKILL), 0);
  }
  run.join();
  ASSERT_EQ(status, 0) << "see " << log;

  const std::vector<std::string> output = lines(log);
  EXPECT_TRUE(contains(output, "multimodal2d on workers: 7200 rollouts in 72 batches on up to 2 workers")) << log;
  EXPECT_TRUE(contains(output, "pi2viapoint on workers: 900 rollouts in 90 batches on up to 1 workers")) << log;
  // (6.16) in 100 dimensions: the workers build the task from the dimension the benchmark writes for them.
  EXPECT_TRUE(contains(output, "multimodal100 on workers: ")) << log;
  int csvs = 0;
  for (const fs::directory_entry& file : fs::directory_iterator(out / "here")) {
    if (file.path().extension() != ".csv") continue;
    ++csvs;
    EXPECT_EQ(lines(file.path().string()), lines((out / "workers" / file.path().filename()).string()))
        << file.path().filename();
  }
  EXPECT_EQ(csvs, 8) << "multimodal2d, multimodal20, multimodal50, multimodal100, bottles617, bottles, circle, "
                        "pi2viapoint";
  fs::remove_all(out);
}

// The simulated WAM's bottle task learns through ROS: its rollouts (each a Bullet simulation of the arm among free
// bottles) on the worker left alive give the learning curves and the final policies' paths of the run on this
// process's threads.
TEST(PsBenchmarkWorkers, TheWamBottleTaskLearnsOnTheWorkersAsHere) {
  std::string space = "/ps_workers";
  ros::param::get("~worker_namespace", space);
  const fs::path out = fs::temp_directory_path() / ("ps_benchmark_wam_workers_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string common = std::string(PS_BENCHMARK) + " --experiment wam_bottles --runs 1 --quick --seed 4 --out ";
  ASSERT_EQ(std::system((common + (out / "here").string() + " --jobs 2 > " + out.string() + "_here.log 2>&1").c_str()),
            0);
  const std::string log = out.string() + "_workers.log";
  ASSERT_EQ(std::system((common + (out / "workers").string() + " --worker-namespace " + space +
                         " --worker-timeout 30 > " + log + " 2>&1")
                            .c_str()),
            0)
      << "see " << log;
  EXPECT_TRUE(contains(lines(log), "wam_bottles on workers: 40 rollouts in 4 batches")) << log;
  for (const char* file : {"wam_bottles.csv", "wam_bottles_paths.csv"}) {
    const std::vector<std::string> here = lines((out / "here" / file).string());
    EXPECT_GT(here.size(), 2u) << file;
    EXPECT_EQ(here, lines((out / "workers" / file).string())) << file;
  }
  fs::remove_all(out);
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_ps_benchmark_workers");
  ros::NodeHandle node;
  return RUN_ALL_TESTS();
}
