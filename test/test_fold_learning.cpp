// Learning to fold: the reward of the demonstration, the coordinated policy against the plain one, variant names,
// learning files, and a small learning run that is the same on one or two threads and resumes from its directory.
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"

#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <thread>
#include <tuple>
#include <utility>

namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

const std::string kSource = BIMANUAL_SKILLS_SOURCE_DIR;

br::FoldLearningConfig smallConfig() {
  br::FoldLearningConfig c;
  c.task.sim_config = kSource + "/config/sim.yaml";
  // As the learning files, the controllers compensate the robot file's identified friction (their state must not
  // leak from one rollout into the next).
  c.task.duration = 3.0;
  c.task.settle = 0.7;
  c.algorithms = {"IDR-DMP_CMU"};
  c.updates = 1;
  c.rollouts = 3;
  c.reuse = 3;
  c.jobs = 2;
  c.seed = 5;
  return c;
}

/// Another policy than `theta`, far enough to move the cloth differently.
Eigen::VectorXd perturbed(const Eigen::VectorXd& theta) {
  Eigen::VectorXd other = theta;
  for (Eigen::Index i = 0; i < other.size(); ++i) other[i] += 8.0 * std::sin(1.7 * i);
  return other;
}

std::string freshDirectory(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/fold_learning_" + name;
  std::filesystem::remove_all(dir);
  return dir;
}

}  // namespace

TEST(FoldLearning, VariantNames) {
  const br::DrDmpVariant standard = br::parseDrDmpVariant("DR-DMP0(12)", 12, 50.0);
  EXPECT_EQ(standard.latent_dims, 12);
  EXPECT_EQ(standard.matrices, 1);
  EXPECT_EQ(standard.rule, bimanual_skills::learning::CoordinationRule::Fixed);
  EXPECT_TRUE(std::isinf(standard.eta));
  const br::DrDmpVariant idr = br::parseDrDmpVariant("IDR-DMP_MCMU(3)", 12, 50.0);
  EXPECT_EQ(idr.latent_dims, 12);
  EXPECT_EQ(idr.matrices, 3);
  EXPECT_EQ(idr.rule, bimanual_skills::learning::CoordinationRule::Cmu);
  EXPECT_EQ(idr.eta, 50.0);
  const br::DrDmpVariant mcmu = br::parseDrDmpVariant("DR-DMP_MCMU(2,4)", 12, 50.0);
  EXPECT_EQ(mcmu.matrices, 2);
  EXPECT_EQ(mcmu.latent_dims, 4);
  EXPECT_EQ(mcmu.search, br::PolicySearch::Reps);
  for (const auto& [name, search] :
       {std::pair{"PI2-CMA", br::PolicySearch::Pi2Cma}, std::pair{"CMA-ES", br::PolicySearch::CmaEs}}) {
    const br::DrDmpVariant peer = br::parseDrDmpVariant(name, 12, 50.0);
    EXPECT_EQ(peer.search, search);
    EXPECT_EQ(peer.latent_dims, 12);
    EXPECT_EQ(peer.rule, bimanual_skills::learning::CoordinationRule::Fixed);
  }
  EXPECT_THROW(br::parseDrDmpVariant("DR-DMP0(13)", 12, 50.0), std::invalid_argument);
  EXPECT_THROW(br::parseDrDmpVariant("PoWER", 12, 50.0), std::invalid_argument);
}

TEST(FoldLearning, PeersUpdateTowardsTheirBestRollouts) {
  // One update from three rollouts. CMA-ES recombines the best half (one rollout: weight 1), so its new mean is the
  // best rollout's weights; PI2-CMA's is a projected, probability-weighted average that lands nearer the best
  // rollout than the worst. Both adapt the exploration covariance.
  br::FoldLearningConfig config = smallConfig();
  config.algorithms = {"PI2-CMA", "CMA-ES"};
  std::map<std::string, std::vector<br::FoldRolloutRecord>> samples;
  br::FoldLearningObserver observer;
  observer.rollout = [&](const br::FoldRolloutRecord& r, const bt::FoldRollout&, const bt::FoldReward&) {
    if (r.kind == br::RolloutKind::Sample && r.epoch == 0) samples[r.algorithm].push_back(r);
  };
  const br::FoldLearningResult result = br::FoldLearner(config, freshDirectory("peers"), observer).learn();
  ASSERT_EQ(result.runs.size(), 2u);
  for (const br::FoldRunResult& run : result.runs) {
    const std::vector<br::FoldRolloutRecord>& batch = samples[run.algorithm];
    ASSERT_EQ(batch.size(), 3u) << run.algorithm;
    const auto by_reward = [](const br::FoldRolloutRecord& a, const br::FoldRolloutRecord& b) {
      return a.terms.reward < b.terms.reward;
    };
    const br::FoldRolloutRecord& best = *std::max_element(batch.begin(), batch.end(), by_reward);
    const br::FoldRolloutRecord& worst = *std::min_element(batch.begin(), batch.end(), by_reward);
    ASSERT_LT(worst.terms.reward, best.terms.reward) << run.algorithm;
    const double initial_variance = config.initial_stddev * config.initial_stddev;
    EXPECT_GT((run.final.covariance - initial_variance * Eigen::MatrixXd::Identity(240, 240)).norm(), 1e-6)
        << run.algorithm;
    if (run.algorithm == "CMA-ES") {
      EXPECT_LT((run.final.mean - best.weights).norm(), 1e-9);
    } else {
      EXPECT_LT((run.final.mean - best.weights).norm(), (run.final.mean - worst.weights).norm());
    }
  }
}

TEST(FoldLearning, TheFoldAndTheScarfReadTheSharedLearningKeysAlike) {
  const std::string dir = freshDirectory("shared_keys");
  std::filesystem::create_directories(dir);
  std::ifstream shipped(kSource + "/config/scarf_learning.yaml");
  std::string scarf((std::istreambuf_iterator<char>(shipped)), std::istreambuf_iterator<char>());
  scarf = scarf.substr(0, scarf.find("\nlearning:") + 1);
  for (const std::string name : {"scarf_sim.yaml", "scarf_start.yaml"}) {
    scarf.replace(scarf.find(name), name.size(), kSource + "/config/" + name);
  }
  const std::string fold = "sim: " + kSource + "/config/sim.yaml\n";
  const auto write = [&](const std::string& head, const std::string& learning) {
    std::ofstream(dir + "/file.yaml") << head << "learning: " << learning << "\n";
    return dir + "/file.yaml";
  };
  const std::string good =
      "{algorithms: [PI2-CMA], runs: 2, updates: 3, rollouts: 6, reuse: 6, epsilon: 0.4, eta: 60, initial_stddev: "
      "1.5, covariance_memory: 0.5, seed: 4294967295, jobs: 1, robot_retries: 2, robot_fault_limit: 4}";
  const br::FoldLearningConfig f = br::FoldLearningConfig::fromYamlFile(write(fold, good));
  const br::DmpLearningConfig s = br::ScarfLearningConfig::fromYamlFile(write(scarf, good)).learning;
  EXPECT_EQ(f.algorithms, s.algorithms);
  EXPECT_EQ(std::tie(f.runs, f.updates, f.rollouts, f.reuse, f.jobs, f.robot_retries, f.robot_fault_limit, f.seed),
            std::tie(s.runs, s.updates, s.rollouts, s.reuse, s.jobs, s.robot_retries, s.robot_fault_limit, s.seed));
  EXPECT_EQ(f.seed, 4294967295u);
  EXPECT_EQ(std::tie(f.epsilon, f.eta, f.initial_stddev, f.covariance_memory),
            std::tie(s.epsilon, s.eta, s.initial_stddev, s.covariance_memory));
  for (const auto& [learning, key] :
       std::vector<std::pair<std::string, std::string>>{{"{seed: -1}", "'seed'"},
                                                        {"{seed: 1.5}", "'seed'"},
                                                        {"{seed: 4294967296}", "'seed'"},
                                                        {"{algorithms: PI2-CMA}", "'algorithms'"},
                                                        {"{algorithms: [[a]]}", "'algorithms'"},
                                                        {"{runs: 2.5}", "'runs'"},
                                                        {"{rollout: 6}", "'rollout'"}}) {
    for (const bool is_scarf : {false, true}) {
      std::string message = "no error";
      try {
        if (is_scarf) {
          br::ScarfLearningConfig::fromYamlFile(write(scarf, learning));
        } else {
          br::FoldLearningConfig::fromYamlFile(write(fold, learning));
        }
      } catch (const std::invalid_argument& e) {
        message = e.what();
      }
      EXPECT_NE(message.find(key), std::string::npos) << (is_scarf ? "scarf " : "fold ") << learning << ": " << message;
    }
  }
  // Each learner's own keys stay its own.
  EXPECT_THROW(br::FoldLearningConfig::fromYamlFile(write(fold, "{dual_kernels: 2}")), std::invalid_argument);
  EXPECT_THROW(br::ScarfLearningConfig::fromYamlFile(write(scarf, "{goal_stddev: 0.1}")), std::invalid_argument);
}

TEST(FoldLearning, LearningFiles) {
  const br::FoldLearningConfig demo = br::FoldLearningConfig::fromYamlFile(kSource + "/config/fold_demo.yaml");
  EXPECT_TRUE(demo.task.friction_files.empty());  // the robot file's
  EXPECT_TRUE(demo.task.robot.empty());           // the simulation file's
  EXPECT_TRUE(std::filesystem::exists(demo.task.sim_config));
  const br::FoldLearningConfig table = br::FoldLearningConfig::fromYamlFile(kSource + "/config/fold_table75.yaml");
  EXPECT_EQ(table.algorithms.size(), 5u);
  EXPECT_EQ(table.runs, 10);
  EXPECT_EQ(table.updates, 15);
  EXPECT_EQ(table.rollouts, 12);
  // make demo learns as Table 7.5 does: the same faulty demonstration, policy, reward and search settings.
  for (const br::FoldLearningConfig* c : {&demo, &table}) {
    EXPECT_DOUBLE_EQ(c->covariance_memory, 0.8);
    EXPECT_EQ(c->reward.setting, "fold");
    EXPECT_DOUBLE_EQ(c->reward.image.fold_weight, 1.0);
    EXPECT_DOUBLE_EQ(c->reward.image.goal_weight, 0.0);
    EXPECT_EQ(c->task.policy, bt::FoldPolicy::WeightsAndGoals);
    EXPECT_DOUBLE_EQ(c->task.demo_reach, 0.85);
    EXPECT_DOUBLE_EQ(c->goal_stddev, 0.03);
    EXPECT_DOUBLE_EQ(c->eta, 500.0);
  }
  const br::FoldLearningConfig ablation = br::FoldLearningConfig::fromYamlFile(kSource + "/config/fold_ablation.yaml");
  EXPECT_EQ(ablation.algorithms, std::vector<std::string>{"IDR-DMP_CMU"});
  EXPECT_EQ(ablation.runs, table.runs);
  EXPECT_DOUBLE_EQ(ablation.initial_stddev, table.initial_stddev);
  // The reward's check where learning ends perturbs policies learned as in Table 7.5, its first algorithm run for run.
  const br::FoldLearningConfig check = br::FoldLearningConfig::fromYamlFile(kSource + "/config/fold_reward_check.yaml");
  EXPECT_EQ(check.algorithms,
            (std::vector<std::string>{table.algorithms[0], table.algorithms[3], table.algorithms[4]}));
  EXPECT_EQ(check.seed, table.seed);
  EXPECT_EQ(check.runs, 5);
  EXPECT_EQ(check.updates, table.updates);
  EXPECT_EQ(check.rollouts, table.rollouts);
  EXPECT_EQ(check.reuse, table.reuse);
  EXPECT_EQ(check.repetitions, 0);
  EXPECT_DOUBLE_EQ(check.covariance_memory, table.covariance_memory);
  EXPECT_DOUBLE_EQ(check.initial_stddev, table.initial_stddev);
  EXPECT_DOUBLE_EQ(check.goal_stddev, table.goal_stddev);
  EXPECT_DOUBLE_EQ(check.epsilon, table.epsilon);
  EXPECT_EQ(check.reward.setting, table.reward.setting);
  EXPECT_DOUBLE_EQ(check.task.demo_reach, table.task.demo_reach);
  EXPECT_EQ(check.task.policy, table.task.policy);

  const std::string dir = freshDirectory("files");
  std::filesystem::create_directories(dir);
  const auto write = [&](const std::string& text) {
    std::ofstream(dir + "/bad.yaml") << text;
    return dir + "/bad.yaml";
  };
  const auto message = [&](const std::string& text) {
    try {
      br::FoldLearningConfig::fromYamlFile(write(text));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nlearning: {algorithms: [PoWER]}\n").find("PoWER"),
            std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nlearning: {rollouts: 1}\n").find("rollouts"),
            std::string::npos);
  EXPECT_NE(
      message("sim: " + kSource + "/config/sim.yaml\nlearning: {covariance_memory: 1.0}\n").find("covariance_memory"),
      std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nlearnin: {}\n").find("learnin"), std::string::npos);
  EXPECT_NE(message("sim: [1, 2\n").find("YAML"), std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nreward: {setting: best}\n").find("best"), std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nreward: {goal_excess_height: 0}\n").find("goal_excess"),
            std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\ntask: {policy: both}\n").find("both"), std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nlearning: {goal_stddev: 0}\n").find("goal_stddev"),
            std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\ntask: {demo_lag: 0.95}\n").find("demo_lag"),
            std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\ntask: {velocity_limit: 0}\n").find("velocity_limit"),
            std::string::npos);
  EXPECT_EQ(
      br::FoldLearningConfig::fromYamlFile(write("sim: " + kSource + "/config/sim.yaml\ntask: {velocity_limit: 1.5}\n"))
          .task.velocity_limit,
      Eigen::VectorXd::Constant(1, 1.5));
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\ntask: {image_delay: -1}\n").find("image_delay"),
            std::string::npos);
  EXPECT_EQ(br::FoldLearningConfig::fromYamlFile(kSource + "/config/fold_hardware_check.yaml").task.image_delay, 4.0);
  // A setting gives its weights; an entry beside it overrides one of them.
  const br::FoldLearningConfig goal = br::FoldLearningConfig::fromYamlFile(
      write("sim: " + kSource + "/config/sim.yaml\nreward: {setting: goal, acceleration_weight: 0.003}\n"));
  EXPECT_EQ(goal.reward.setting, "goal");
  EXPECT_DOUBLE_EQ(goal.reward.image.goal_weight, 1.0);
  EXPECT_DOUBLE_EQ(goal.reward.image.colour_weight, 0.0);
  EXPECT_DOUBLE_EQ(goal.reward.acceleration_weight, 0.003);
  const br::FoldLearningConfig heap = br::FoldLearningConfig::fromYamlFile(
      write("sim: " + kSource + "/config/sim.yaml\nreward: {setting: fold, fold_heap_weight: 2.5}\n"));
  EXPECT_DOUBLE_EQ(heap.reward.image.fold_heap_weight, 2.5);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\nreward: {fold_heap_weight: -1}\n").find("fold_heap_weight"),
            std::string::npos);
  // The robot's noise: a named setting, and entries beside it that make it custom; refused out of range or unnamed.
  EXPECT_FALSE(demo.task.noise.any());
  const br::FoldLearningConfig robot =
      br::FoldLearningConfig::fromYamlFile(write("sim: " + kSource + "/config/sim.yaml\ntask: {noise: robot}\n"));
  EXPECT_EQ(robot.task.noise.setting, "robot");
  EXPECT_DOUBLE_EQ(robot.task.noise.cloth_position, 0.01);
  const br::FoldLearningConfig custom = br::FoldLearningConfig::fromYamlFile(
      write("sim: " + kSource + "/config/sim.yaml\ntask: {noise: robot, release_noise: 0.02}\n"));
  EXPECT_EQ(custom.task.noise.setting, "custom");
  EXPECT_DOUBLE_EQ(custom.task.noise.release_time, 0.02);
  EXPECT_DOUBLE_EQ(custom.task.noise.cloth_yaw, robot.task.noise.cloth_yaw);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\ntask: {noise: loud}\n").find("loud"), std::string::npos);
  EXPECT_NE(message("sim: " + kSource + "/config/sim.yaml\ntask: {cloth_yaw_noise: 3}\n").find("yaw"),
            std::string::npos);
}

TEST(FoldLearning, CoordinatedPolicyDrivesTheSameMotion) {
  bt::ClothFoldConfig c = smallConfig().task;
  bt::ClothFoldTask task(c);
  const Eigen::VectorXd theta = task.demonstrationParameters();
  const bt::FoldRollout plain = task.run(theta);
  ASSERT_EQ(plain.outcome, bt::FoldOutcome::Ok) << plain.reason;
  // The same forcing terms (and goals) through a random orthonormal Ω and ω = Ωᵀ θ (per kernel), blended from two
  // equal matrices: the commanded tool paths (kinematic: DMP and CLIK only) agree to rounding.
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd a(12, 12);
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = normal(rng);
  const Eigen::MatrixXd omega = Eigen::HouseholderQR<Eigen::MatrixXd>(a).householderQ();
  const int k = task.policyBasisSize();  // the kernels' weights and the goal's
  const Eigen::MatrixXd full = Eigen::Map<const Eigen::MatrixXd>(theta.data(), k, 12).transpose();
  const Eigen::MatrixXd latent = omega.transpose() * full;  // r × (kernels + 1)
  Eigen::VectorXd w(12 * k);
  for (int j = 0; j < 12; ++j) w.segment(j * k, k) = latent.row(j).transpose();
  const bt::FoldRollout coordinated = task.run({omega, omega}, w);
  ASSERT_EQ(coordinated.outcome, bt::FoldOutcome::Ok) << coordinated.reason;
  for (int arm = 0; arm < 2; ++arm) {
    ASSERT_EQ(plain.commanded_path[arm].cols(), coordinated.commanded_path[arm].cols());
    EXPECT_LT((plain.commanded_path[arm] - coordinated.commanded_path[arm]).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_EQ(plain.joint_path[arm].cols(), plain.path_times.size());
  }
  // Policies that do not fit: a reason, no crash.
  for (const auto& [matrices, weights] : std::vector<std::pair<std::vector<Eigen::MatrixXd>, Eigen::VectorXd>>{
           {{Eigen::MatrixXd::Identity(11, 11)}, Eigen::VectorXd::Zero(11 * k)},
           {{Eigen::MatrixXd::Identity(12, 3)}, Eigen::VectorXd::Zero(4 * k)},
           {{Eigen::MatrixXd::Identity(12, 3)}, Eigen::VectorXd::Constant(3 * k, NAN)},
           {{}, Eigen::VectorXd::Zero(3 * k)}}) {
    const bt::FoldRollout r = task.run(matrices, weights);
    EXPECT_EQ(r.outcome, bt::FoldOutcome::InvalidPolicy);
    EXPECT_FALSE(r.reason.empty());
  }
}

TEST(FoldLearning, DemonstrationReward) {
  const br::FoldLearningConfig config = smallConfig();
  bt::ClothFoldTask task(config.task);
  bt::FoldRewardConfig reward_config = bt::rewardSetting(config.reward, "thesis", "test");
  reward_config.renderer = bt::rendererFor(task.simConfig());
  bt::FoldReward reward(reward_config, 0.5 * 0.6, task.idealFoldVertices(), task.clothTriangles());
  const bt::FoldRollout r = task.run(task.demonstrationParameters());
  ASSERT_EQ(r.outcome, bt::FoldOutcome::Ok) << r.reason;
  std::mt19937 rng(1);
  const bt::FoldRewardTerms t = reward.evaluate(r, rng);
  std::printf(
      "demonstration: R = %.4f: R_acc %.4f, R_color %.4f (rho %.3f), R_depth %.4f (g %.4f), area %.3f, "
      "aspect %.2f\n",
      t.reward, t.r_acceleration, t.r_color, t.fill_ratio, t.r_depth, t.mean_gradient, t.area_ratio, t.aspect);
  EXPECT_EQ(t.vision, bimanual_skills::vision::VisionStatus::Ok);
  EXPECT_NEAR(t.reward, -t.r_acceleration - t.r_color - t.r_depth - t.r_goal, 1e-12);
  EXPECT_EQ(t.r_goal, 0.0);  // the thesis' setting
  // Folded in half: about half the flat area visible, a nearly rectangular outline.
  EXPECT_GT(t.area_ratio, 0.4);
  EXPECT_LT(t.area_ratio, 0.6);
  EXPECT_GT(t.fill_ratio, 0.9);
  EXPECT_GT(t.reward, config.reward.failure_reward);
  bt::FoldRollout failed = r;
  failed.outcome = bt::FoldOutcome::ControllerFailed;
  EXPECT_EQ(reward.evaluate(failed, rng).reward, config.reward.failure_reward);

  // The goal term: ~0 for the ideal fold itself (only the sensor noise), about ¾ for the flat cloth (half its area
  // outside the goal, e = 1, the other half one layer where two belong, e = ½), the demonstration between.
  bt::FoldReward goal(bt::rewardSetting(reward_config, "goal", "test"), 0.5 * 0.6, task.idealFoldVertices(),
                      task.clothTriangles());
  bt::FoldRollout ideal = r, flat = r;
  ideal.cloth_vertices = task.idealFoldVertices();
  flat.cloth_vertices = r.cloth_rest_vertices;
  const bt::FoldRewardTerms at_goal = goal.evaluate(ideal, rng), at_start = goal.evaluate(flat, rng),
                            demo = goal.evaluate(r, rng);
  std::printf("goal mismatch: ideal %.3f (IoU %.3f), flat %.3f (IoU %.3f), demonstration %.3f (IoU %.3f)\n",
              at_goal.goal_mismatch, at_goal.goal_iou, at_start.goal_mismatch, at_start.goal_iou, demo.goal_mismatch,
              demo.goal_iou);
  EXPECT_GT(at_goal.goal_iou, 0.97);
  EXPECT_LT(at_goal.goal_mismatch, 0.15);
  EXPECT_NEAR(at_start.goal_iou, 0.5, 0.03);
  EXPECT_GT(at_start.goal_mismatch, 0.7);
  EXPECT_GT(demo.goal_mismatch, at_goal.goal_mismatch);
  EXPECT_LT(demo.goal_mismatch, at_start.goal_mismatch);
  EXPECT_EQ(demo.r_color, 0.0);
  EXPECT_NEAR(demo.reward, -demo.r_acceleration - demo.goal_mismatch, 1e-12);

  // The fold term (the learning's default) against the flat cloth the camera saw: ~0 for the ideal fold, 1 for the
  // cloth left flat, the demonstration between; its terms are what the record holds.
  EXPECT_EQ(config.reward.setting, "fold");
  bt::FoldReward fold(bt::rewardSetting(reward_config, "fold", "test"), 0.5 * 0.6, task.idealFoldVertices(),
                      task.clothTriangles());
  const bt::FoldRewardTerms fold_ideal = fold.evaluate(ideal, rng), fold_flat = fold.evaluate(flat, rng),
                            fold_demo = fold.evaluate(r, rng);
  std::printf("fold mismatch: ideal %.3f, flat %.3f, demonstration %.3f (q %.3f)\n", fold_ideal.fold_mismatch,
              fold_flat.fold_mismatch, fold_demo.fold_mismatch, r.fold.q);
  EXPECT_LT(fold_ideal.fold_mismatch, 0.1);
  EXPECT_NEAR(fold_flat.fold_mismatch, 1.0, 0.05);
  EXPECT_GT(fold_demo.fold_mismatch, fold_ideal.fold_mismatch);
  EXPECT_LT(fold_demo.fold_mismatch, fold_flat.fold_mismatch);
  EXPECT_NEAR(fold_demo.reward, -fold_demo.r_acceleration - fold_demo.r_fold, 1e-12);
  EXPECT_EQ(fold_demo.r_fold, fold_demo.fold_mismatch);
  EXPECT_NEAR(fold_demo.r_acceleration, 0.001 * r.acceleration_cost, 1e-12);
}

TEST(FoldLearning, SameOnAnyThreadsAndResumes) {
  br::FoldLearningConfig config = smallConfig();
  config.jobs = 1;
  const std::string serial_dir = freshDirectory("serial"), parallel_dir = freshDirectory("parallel");
  int seen = 0;
  br::FoldLearningObserver observer;
  observer.rollout = [&](const br::FoldRolloutRecord&, const bt::FoldRollout&, const bt::FoldReward&) { ++seen; };
  const br::FoldLearningResult serial = br::FoldLearner(config, serial_dir, observer).learn();
  ASSERT_EQ(serial.runs.size(), 1u);
  EXPECT_EQ(seen, 8);  // 2 epochs × 3 samples + 2 mean-policy rollouts
  EXPECT_EQ(serial.simulated, 8);
  config.jobs = 2;
  const br::FoldLearningResult parallel = br::FoldLearner(config, parallel_dir).learn();
  for (std::size_t e = 0; e < serial.runs[0].epochs.size(); ++e) {
    EXPECT_EQ(serial.runs[0].epochs[e].mean_reward, parallel.runs[0].epochs[e].mean_reward) << "epoch " << e;
  }
  EXPECT_EQ(serial.runs[0].final_policy.terms.reward, parallel.runs[0].final_policy.terms.reward);
  EXPECT_EQ(bimanual_skills::testing::readTextFile(serial_dir + "/epochs.csv"),
            bimanual_skills::testing::readTextFile(parallel_dir + "/epochs.csv"));

  // Interrupted after three rollouts: the rest is simulated on restart, the result is the same.
  const std::string resumed_dir = freshDirectory("resumed");
  int finished = 0;
  br::FoldLearningObserver stopper;
  stopper.rollout = [&](const br::FoldRolloutRecord&, const bt::FoldRollout&, const bt::FoldReward&) { ++finished; };
  stopper.stop = [&] { return finished >= 3; };
  EXPECT_THROW(br::FoldLearner(config, resumed_dir, stopper).learn(), std::runtime_error);
  const br::FoldLearningResult resumed = br::FoldLearner(config, resumed_dir).learn();
  EXPECT_GE(resumed.resumed, 3);
  EXPECT_EQ(resumed.resumed + resumed.simulated, 8);
  EXPECT_EQ(resumed.runs[0].final_policy.terms.reward, serial.runs[0].final_policy.terms.reward);
  EXPECT_EQ(bimanual_skills::testing::readTextFile(resumed_dir + "/epochs.csv"),
            bimanual_skills::testing::readTextFile(serial_dir + "/epochs.csv"));
  // The first and the final coordination matrices, one row per DMP DoF and matrix, the same after the resume.
  for (const char* name : {"/coordination.csv", "/initial_coordination.csv"}) {
    const std::string serial_text = bimanual_skills::testing::readTextFile(serial_dir + name);
    EXPECT_EQ(std::count(serial_text.begin(), serial_text.end(), '\n'),
              1 + static_cast<long>(serial.runs[0].final.coordination.size()) * bt::ClothFoldTask::kDofs)
        << name;
    EXPECT_EQ(bimanual_skills::testing::readTextFile(resumed_dir + name), serial_text) << name;
  }

  // Another reward in the same directory is refused at once (its first epoch's rollouts would otherwise be reused
  // with the rewards of the first), and so is another seed.
  br::FoldLearningConfig other_reward = config;
  other_reward.reward = bt::rewardSetting(config.reward, "goal", "test");
  try {
    br::FoldLearner(other_reward, resumed_dir);
    ADD_FAILURE() << "a directory scored with another reward was reused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("another reward"), std::string::npos) << e.what();
  }
  // So is another world: the simulation file with a heavier cloth (its robot file named by an absolute path).
  {
    std::string text = bimanual_skills::testing::readTextFile(config.task.sim_config);
    const std::string config_dir = kSource + "/config/";
    const std::string robot = "robot: robots/wam.yaml";
    const std::string::size_type at = text.find(robot);
    ASSERT_NE(at, std::string::npos) << robot;
    text.replace(at, robot.size(), "robot: " + config_dir + "robots/wam.yaml");
    const std::string::size_type mass = text.find("mass: 0.22");
    ASSERT_NE(mass, std::string::npos);
    text.replace(mass, 10, "mass: 0.44");
    const std::string other_world = ::testing::TempDir() + "/fold_learning_other_world.yaml";
    std::ofstream(other_world) << text;
    br::FoldLearningConfig moved = config;
    moved.task.sim_config = other_world;
    try {
      br::FoldLearner(moved, resumed_dir);
      ADD_FAILURE() << "a directory of rollouts in another world was reused";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("another world"), std::string::npos) << e.what();
    }
  }
  config.seed = 6;
  EXPECT_THROW(br::FoldLearner(config, resumed_dir).learn(), std::invalid_argument);

  // rollouts.csv of other columns (an older version's) is refused with that reason, not misread.
  const std::string old_dir = freshDirectory("old_columns");
  std::filesystem::create_directories(old_dir);
  std::ofstream(old_dir + "/rollouts.csv") << "algorithm,run,epoch,kind,index,seed,outcome,reward\n";
  try {
    br::FoldLearner(config, old_dir);
    ADD_FAILURE() << "a rollouts.csv of other columns was read";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("other columns"), std::string::npos) << e.what();
  }
}

// A run killed with SIGKILL resumes. The kill comes when three rollouts are on disk, and the files then get a partial
// last line each, as a kill in the middle of a write leaves them: the partial lines are cut off, the whole records
// read back, the rest simulated, and the result is that of a run never interrupted.
TEST(FoldLearning, ResumesAfterSigkillMidWrite) {
  br::FoldLearningConfig config = smallConfig();
  config.jobs = 1;
  const br::FoldLearningResult whole = br::FoldLearner(config, freshDirectory("whole")).learn();
  const std::string dir = freshDirectory("killed");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    try {
      br::FoldLearner(config, dir).learn();
    } catch (...) {
    }
    std::_Exit(0);
  }
  const auto records = [&dir] {
    std::ifstream in(dir + "/rollout_parameters.csv");
    int lines = 0;
    for (std::string line; std::getline(in, line);) ++lines;
    return lines - 1;
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (records() < 3 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run ended before it was killed";
  for (const char* file : {"/rollouts.csv", "/rollout_parameters.csv"}) {
    std::ofstream(dir + file, std::ios::app) << "\"IDR-DMP_CMU\",0,1,sample,2,";  // no newline: cut mid-write
  }
  const br::FoldLearningResult resumed = br::FoldLearner(config, dir).learn();
  EXPECT_GE(resumed.resumed, 3);
  EXPECT_EQ(resumed.resumed + resumed.simulated, 8);
  EXPECT_EQ(resumed.runs[0].final_policy.terms.reward, whole.runs[0].final_policy.terms.reward);
  const auto rows = bimanual_skills::testing::readCsv(dir + "/rollouts.csv");
  EXPECT_EQ(rows.size(), 8u);  // every rollout once, every line whole
}

TEST(FoldLearning, FailedRolloutsGetTheFailureRewardAndTheLearningGoesOn) {
  br::FoldLearningConfig config = smallConfig();
  config.initial_stddev = 400.0;  // wild exploration: most rollouts leave the IK or tracking bounds
  const std::string dir = freshDirectory("failures");
  const br::FoldLearningResult result = br::FoldLearner(config, dir).learn();
  ASSERT_EQ(result.runs.size(), 1u);
  ASSERT_EQ(result.runs[0].epochs.size(), 2u);
  int failures = 0;
  for (const br::FoldEpochStats& s : result.runs[0].epochs) failures += s.failures;
  EXPECT_GT(failures, 0);
  int failed_rows = 0;
  for (const bimanual_skills::testing::CsvRow& row : bimanual_skills::testing::readCsv(dir + "/rollouts.csv")) {
    if (row.at("outcome") == "Ok") continue;
    ++failed_rows;
    EXPECT_EQ(bimanual_skills::testing::csvNumber(row, "reward"), config.reward.failure_reward);
    EXPECT_GT(row.at("reason").size(), 2u) << "a failed rollout is written with its reason";
  }
  EXPECT_EQ(failed_rows, failures + (result.runs[0].initial_policy.terms.outcome != bt::FoldOutcome::Ok) +
                             (result.runs[0].final_policy.terms.outcome != bt::FoldOutcome::Ok));
  // Every mean counts the failed rollouts: the epoch's q is the mean over all its samples, failed ones with the q
  // of the cloth they left, and its reward the mean with their failure rewards.
  for (const br::FoldEpochStats& s : result.runs[0].epochs) {
    double q = 0.0, reward = 0.0;
    int samples = 0;
    for (const bimanual_skills::testing::CsvRow& row : bimanual_skills::testing::readCsv(dir + "/rollouts.csv")) {
      if (row.at("kind") != "sample" || std::stoi(row.at("epoch")) != s.epoch) continue;
      q += bimanual_skills::testing::csvNumber(row, "fold_quality");
      reward += bimanual_skills::testing::csvNumber(row, "reward");
      ++samples;
    }
    ASSERT_EQ(samples, config.rollouts);
    EXPECT_NEAR(s.fold_quality, q / samples, 1e-12) << "epoch " << s.epoch;
    EXPECT_NEAR(s.mean_reward, reward / samples, 1e-12) << "epoch " << s.epoch;
  }
}

TEST(FoldLearning, DemonstrationDmpFilesGiveTheSameRollout) {
  bt::ClothFoldConfig c = smallConfig().task;
  const bt::ClothFoldTask scripted(c);
  const std::string dir = freshDirectory("demonstration");
  std::filesystem::create_directories(dir);
  scripted.saveDemonstration(dir + "/demo_");
  c.demonstration_files = {dir + "/demo_left.yaml", dir + "/demo_right.yaml"};
  bt::ClothFoldTask loaded(c);
  EXPECT_EQ(loaded.demonstrationParameters(), scripted.demonstrationParameters());
  const bt::FoldRollout r = loaded.run(loaded.demonstrationParameters());
  ASSERT_EQ(r.outcome, bt::FoldOutcome::Ok) << r.reason;
  bt::ClothFoldTask again(smallConfig().task);
  const bt::FoldRollout expected = again.run(again.demonstrationParameters());
  for (int arm = 0; arm < 2; ++arm) EXPECT_EQ(r.commanded_path[arm], expected.commanded_path[arm]);
  // The integrated demonstration follows the scripted one closely (the DMP's fit error).
  EXPECT_LT((loaded.demonstrationTrajectory() - scripted.demonstrationTrajectory()).cwiseAbs().maxCoeff(), 0.01);
  c.demonstration_files = {dir + "/demo_left.yaml"};
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
  c.demonstration_files = {dir + "/demo_left.yaml", dir + "/missing.yaml"};
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
}

TEST(FoldLearning, ARolloutDoesNotDependOnTheRolloutsBeforeIt) {
  // Parallel rollouts are spread over the workers by timing: a rollout must give the same result whatever its
  // worker ran before (a fresh task, or one that ran another policy first).
  const bt::ClothFoldConfig c = smallConfig().task;
  bt::ClothFoldTask fresh(c), used(c);
  const Eigen::VectorXd theta = fresh.demonstrationParameters();
  const Eigen::VectorXd other = perturbed(theta);
  ASSERT_EQ(used.run({Eigen::MatrixXd::Identity(12, 12)}, other, 7).outcome, bt::FoldOutcome::Ok);
  const bt::FoldRollout a = fresh.run({Eigen::MatrixXd::Identity(12, 12)}, theta, 11);
  const bt::FoldRollout b = used.run({Eigen::MatrixXd::Identity(12, 12)}, theta, 11);
  ASSERT_EQ(a.outcome, bt::FoldOutcome::Ok);
  EXPECT_EQ(a.acceleration_cost, b.acceleration_cost);
  EXPECT_EQ(a.cloth_vertices, b.cloth_vertices);
  for (int arm = 0; arm < 2; ++arm) EXPECT_EQ(a.joint_path[arm], b.joint_path[arm]);
}

TEST(FoldLearning, ARolloutsResultCarriesItsToolPaths) {
  // The trajectory summary a rollout worker sends back: both arms' actual tool paths, exactly.
  const br::FoldLearningConfig config = br::withSimulationRenderer(smallConfig());
  br::FoldRolloutTask task(config.task, config.reward);
  const br::RolloutResult result = task.run(task.initialParameters(), 5);
  ASSERT_TRUE(result.ok) << result.reason;
  const std::vector<Eigen::Matrix3Xd>& actual = task.lastRollout().actual_path;
  ASSERT_EQ(actual.size(), 2u);
  ASSERT_GT(actual[0].cols(), 10);
  EXPECT_EQ(result.trajectory.rows(), 6);
  EXPECT_EQ(br::FoldRolloutTask::toolPaths(result), actual);
  br::RolloutResult none;
  EXPECT_TRUE(br::FoldRolloutTask::toolPaths(none).empty());
  none.trajectory.resize(4, 3);
  EXPECT_TRUE(br::FoldRolloutTask::toolPaths(none).empty()) << "4 rows are no 3-D paths";
}

TEST(FoldLearning, ConcurrentRolloutsEqualSerialOnes) {
  // Two tasks stepping their simulations at the same time on two threads give the results each gives alone.
  const bt::ClothFoldConfig c = smallConfig().task;
  bt::ClothFoldTask first(c), second(c);
  const Eigen::VectorXd theta = first.demonstrationParameters();
  const Eigen::VectorXd other = perturbed(theta);
  const std::vector<Eigen::MatrixXd> identity = {Eigen::MatrixXd::Identity(12, 12)};
  const bt::FoldRollout alone_a = first.run(identity, theta, 11);
  const bt::FoldRollout alone_b = second.run(identity, other, 12);
  bt::FoldRollout together_a, together_b;
  std::thread thread([&] { together_b = second.run(identity, other, 12); });
  together_a = first.run(identity, theta, 11);
  thread.join();
  EXPECT_EQ(alone_a.cloth_vertices, together_a.cloth_vertices);
  EXPECT_EQ(alone_b.cloth_vertices, together_b.cloth_vertices);
  for (int arm = 0; arm < 2; ++arm) {
    EXPECT_EQ(alone_a.joint_path[arm], together_a.joint_path[arm]);
    EXPECT_EQ(alone_b.joint_path[arm], together_b.joint_path[arm]);
  }
}

namespace {

/// Rollouts on one thread here, except the attempts (1 = the first request it gets) that `fails` picks: those the
/// "robot" fails as FoldOnRobotTask does when an interface does not answer, without running them.
class FaultyRobot : public br::Evaluator {
 public:
  FaultyRobot(const br::FoldLearningConfig& config, std::function<bool(int)> fails)
      : threads_([c = br::withSimulationRenderer(
                      config)] { return std::make_unique<br::FoldRolloutTask>(c.task, c.reward); },
                 1),
        failure_reward_(config.reward.failure_reward),
        fails_(std::move(fails)) {}

  std::vector<br::RolloutResult> evaluate(const std::vector<br::RolloutRequest>& batch, const Done& done,
                                          const std::function<bool()>& stop) override {
    std::vector<br::RolloutResult> results(batch.size());
    for (std::size_t i = 0; i < batch.size(); ++i) {
      if (stop && stop()) throw std::runtime_error("stopped");
      if (fails_(++attempts_)) {
        bt::FoldRewardTerms terms;
        terms.outcome = bt::FoldOutcome::RobotFailed;
        terms.reward = failure_reward_;
        results[i] = br::FoldRolloutTask::resultOf(terms, "closing left's gripper (/grasp): no answer in time", {});
        if (done) done(i, results[i], nullptr);
        continue;
      }
      results[i] = threads_.evaluate({batch[i]}, [&](std::size_t, const br::RolloutResult& r, br::RolloutTask* t) {
        if (done) done(i, r, t);
      })[0];
    }
    return results;
  }

 private:
  br::ParallelEvaluator threads_;
  double failure_reward_;
  std::function<bool(int)> fails_;
  int attempts_ = 0;
};

}  // namespace

// A rollout the robot fails is run again with the same parameters and seed, logged, and never learned from: the
// learning is the one a robot without faults gives. Too many faults stop it with the reason, and a run after the
// robot is fixed resumes from what finished.
TEST(FoldLearning, RobotFaultsAreRunAgainNotLearnedFrom) {
  br::FoldLearningConfig config = smallConfig();
  config.jobs = 1;
  const std::string clean_dir = freshDirectory("robot_clean");
  const br::FoldLearningResult clean =
      br::FoldLearner(config, clean_dir, {}, std::make_unique<FaultyRobot>(config, [](int) { return false; })).learn();
  EXPECT_EQ(clean.robot_faults, 0);

  // The first epoch's batch is the policy and three samples (attempts 1–4): samples 0 and 1 fail at their first
  // attempts (2, 3), and sample 1 at its second (6, after sample 0's second at 5).
  const std::string dir = freshDirectory("robot_faults");
  std::vector<std::pair<int, bool>> seen;  // attempt, retried
  br::FoldLearningObserver observer;
  observer.robot_fault = [&](const br::FoldRolloutRecord&, int attempt, const std::string& reason, bool retry) {
    EXPECT_NE(reason.find("no answer in time"), std::string::npos) << reason;
    seen.emplace_back(attempt, retry);
  };
  const br::FoldLearningResult faulty =
      br::FoldLearner(config, dir, observer,
                      std::make_unique<FaultyRobot>(config, [](int n) { return n == 2 || n == 3 || n == 6; }))
          .learn();
  EXPECT_EQ(faulty.robot_faults, 3);
  EXPECT_EQ(faulty.simulated, clean.simulated);
  EXPECT_EQ(seen, (std::vector<std::pair<int, bool>>{{1, true}, {1, true}, {2, true}}));
  EXPECT_EQ(bimanual_skills::testing::readTextFile(dir + "/epochs.csv"),
            bimanual_skills::testing::readTextFile(clean_dir + "/epochs.csv"));
  EXPECT_EQ(faulty.runs[0].final_policy.terms.reward, clean.runs[0].final_policy.terms.reward);
  for (const auto& row : bimanual_skills::testing::readCsv(dir + "/rollouts.csv")) {
    EXPECT_NE(row.at("outcome"), "RobotFailed") << "a robot's fault was written as a rollout";
  }
  const auto faults = bimanual_skills::testing::readCsv(dir + "/robot_faults.csv");
  ASSERT_EQ(faults.size(), 3u);
  EXPECT_EQ(faults[2].at("attempt"), "2");
  EXPECT_EQ(faults[2].at("index"), faults[1].at("index"));

  // A robot that fails everything from attempt 4 on: with k = 1 the rollout's second fault stops the learning.
  config.robot_retries = 1;
  config.robot_fault_limit = 100;
  const std::string down_dir = freshDirectory("robot_down");
  try {
    br::FoldLearner(config, down_dir, {}, std::make_unique<FaultyRobot>(config, [](int n) { return n >= 4; })).learn();
    ADD_FAILURE() << "the learning went on with a robot that fails every rollout";
  } catch (const br::RobotFaults& e) {
    EXPECT_NE(std::string(e.what()).find("2 times (robot_retries 1)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no answer in time"), std::string::npos) << e.what();
  }
  // With k = 3 and m = 3, three faults in a row stop it.
  config.robot_retries = 3;
  config.robot_fault_limit = 3;
  try {
    br::FoldLearner(config, down_dir, {}, std::make_unique<FaultyRobot>(config, [](int) { return true; })).learn();
    ADD_FAILURE() << "the learning went on with a robot that is down";
  } catch (const br::RobotFaults& e) {
    EXPECT_NE(std::string(e.what()).find("3 times in a row (robot_fault_limit 3)"), std::string::npos) << e.what();
  }
  // The robot fixed: the run resumes with the three rollouts that finished, and ends as the clean one.
  const br::FoldLearningResult fixed =
      br::FoldLearner(config, down_dir, {}, std::make_unique<FaultyRobot>(config, [](int) { return false; })).learn();
  EXPECT_EQ(fixed.resumed, 3);
  EXPECT_EQ(fixed.runs[0].final_policy.terms.reward, clean.runs[0].final_policy.terms.reward);
  EXPECT_EQ(bimanual_skills::testing::readCsv(down_dir + "/robot_faults.csv").size(), 5u);  // 2 + 3, appended
}
