// The bottle task's learning (rollout/bottle_learning.hpp): a coordinated policy (Ω, W) runs the task's DMP with the
// weights Ω W, checked against the DR-DMP's own integration of f = Ω W g(x) (thesis 7.26) and against the task's
// fitted line; the learning file's defaults are the thesis' planar settings, bad files are refused by name; "REPS"
// and "DREPS" are DmpLearner algorithms, and DREPS learns on the simulated WAM, its rollouts recording the arm's
// joints and the bottles over the motion.
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/rollout/bottle_learning.hpp"
#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

namespace br = bimanual_skills::rollout;
namespace bp = bimanual_skills::primitives;
namespace bt = bimanual_skills::tasks;
namespace fs = std::filesystem;

namespace {

std::string configFile(const std::string& name) {
  return std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/" + name;
}

std::string writeFile(const std::string& name, const std::string& text) {
  const fs::path path = fs::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path.string();
}

}  // namespace

TEST(BottleLearning, TheTaskRunsTheWeightsOmegaW) {
  const br::BottleLearningConfig config = br::BottleLearningConfig::fromYamlFile(configFile("bottles_learning.yaml"));
  br::BottleRolloutTask task(config.task);
  const br::DmpTaskModel model = br::bottleTaskModel(task.task());
  const bp::DrDmpFit fit = bp::DrDmp::fit(model.forcing(1), {model.demonstration}, model.step, 2, 0.0);
  const Eigen::MatrixXd& omega = fit.dmp.coordination().front();
  EXPECT_TRUE((omega.transpose() * omega).isApprox(Eigen::Matrix2d::Identity(), 1e-9))
      << "PCA's Ω is orthonormal: the learners' isotropic exploration is isotropic in the task's weights";
  // The fit's policy runs the task's straight line as closely as the task's own fit (a least-squares fit of the
  // forcing over all kernels at once where Dmp::fit weighs each kernel alone).
  Eigen::VectorXd theta;
  ASSERT_TRUE(task.taskWeights(br::encodeCoordinatedPolicy(fit.dmp.coordination(), fit.dmp.weights()), theta));
  const bt::DmpRollout reference = bt::BottleTask::initialPolicy();
  Eigen::MatrixXd y, ydd;
  reference.rollout(theta, y, ydd);
  const double fitted = (y - model.demonstration).cwiseAbs().maxCoeff();
  reference.rollout(task.task().initialParameters(), y, ydd);
  const double own = (y - model.demonstration).cwiseAbs().maxCoeff();
  std::printf("the line's largest deviation [line lengths]: the learners' fit %.2e, the task's own %.2e\n", fitted,
              own);
  EXPECT_LT(fitted, 1.1 * own);
  EXPECT_LT(fitted, 0.01) << "under 6 mm of the 0.6 m line";
  // Any latent weights: the task's DMP with Ω W integrates as the DR-DMP with (Ω, W).
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 60.0);
  Eigen::VectorXd latent(fit.dmp.weights().size());
  for (Eigen::Index i = 0; i < latent.size(); ++i) latent[i] = fit.dmp.weights()[i] + normal(rng);
  ASSERT_TRUE(task.taskWeights(br::encodeCoordinatedPolicy(fit.dmp.coordination(), latent), theta));
  const bp::DrDmp coordinated(fit.dmp.parameters(), fit.dmp.coordination(), latent, fit.dmp.start(), fit.dmp.goal(),
                              fit.dmp.duration());
  reference.rollout(theta, y, ydd);
  bp::DrDmpState state = coordinated.initialState();
  for (int k = 1; k <= reference.steps; ++k) {
    ASSERT_EQ(coordinated.step(state, reference.dt), bp::DmpStatus::Success);
    ASSERT_LT((state.dmp.y - y.row(k).transpose()).norm(), 1e-9) << "step " << k;
  }
  // A policy of another shape is an InvalidPolicy rollout with its reason, never a crash.
  const br::RolloutResult bad = task.run(Eigen::VectorXd::Constant(5, 1.0), 1);
  EXPECT_FALSE(bad.ok);
  EXPECT_EQ(bad.outcome, "InvalidPolicy");
  EXPECT_NE(bad.reason.find("2 DoF"), std::string::npos) << bad.reason;
  EXPECT_EQ(bad.reward, config.task.failure_reward);
}

TEST(BottleLearning, ReadsTheThesisSettingsAndRefusesBadFiles) {
  const br::BottleLearningConfig c = br::BottleLearningConfig::fromYamlFile(configFile("bottles_learning.yaml"));
  EXPECT_EQ(c.learning.algorithms, (std::vector<std::string>{"REPS", "DREPS"}));
  EXPECT_EQ(c.learning.rollouts, 50);
  EXPECT_EQ(c.learning.reuse, 200);
  EXPECT_EQ(c.learning.initial_stddev, 60.0);
  EXPECT_TRUE(c.task.crossing_term);
  const std::string task = configFile("bottles_wam.yaml");
  const br::BottleLearningConfig c617 = br::BottleLearningConfig::fromYamlFile(
      writeFile("bottles_617.yaml", "task: " + task + "\ncrossing_term: false\n"));
  EXPECT_FALSE(c617.task.crossing_term);
  EXPECT_EQ(c617.learning.reuse, 200) << "the defaults without a learning section";
  const auto refused = [&](const std::string& text, const std::string& says) {
    try {
      br::BottleLearningConfig::fromYamlFile(writeFile("bottles_bad.yaml", text));
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused("task: " + task + "\nlearning: {algorithms: [\"DR-DMP_MCMU(2,1)\"]}\n", "one coordination matrix");
  refused("task: " + task + "\nlearning: {algorithms: [DREPSS]}\n", "unknown algorithm 'DREPSS'");
  refused("task: " + task + "\nlearning: {algorithms: DREPS}\n", "must be a list");
  refused("task: " + task + "\nlearning: {seed: -1}\n", "seed");
  refused("task: " + task + "\nlearning: {rollouts: 1}\n", "rollouts >= 2");
  refused("task: " + task + "\nbottles: 3\n", "bottles");
  refused("task: no_such_file.yaml\n", "no_such_file.yaml");
}

TEST(BottleLearning, DrepsLearnsOnTheSimulatedWam) {
  EXPECT_EQ(br::parseDrDmpVariant("DREPS", 2, 50.0).search, br::PolicySearch::Dreps);
  EXPECT_EQ(br::parseDrDmpVariant("REPS", 2, 50.0).search, br::PolicySearch::StandardReps);
  EXPECT_EQ(br::parseDrDmpVariant("REPS", 2, 50.0).latent_dims, 2);
  br::BottleLearningConfig config = br::BottleLearningConfig::fromYamlFile(configFile("bottles_learning.yaml"));
  config.learning.algorithms = {"DREPS"};
  config.learning.updates = 1;
  config.learning.rollouts = 8;
  config.learning.jobs = 2;
  const std::string dir = (fs::temp_directory_path() / "bottle_learning_dreps").string();
  fs::remove_all(dir);
  const bt::WamBottleConfig task_config = config.task;
  const auto evaluator = [&] {
    return std::make_unique<br::ParallelEvaluator>(
        [task_config] { return std::make_unique<br::BottleRolloutTask>(task_config); }, 2);
  };
  br::BottleRolloutTask task(config.task);
  int recorded = 0;
  br::DmpLearningObserver observer;
  observer.rollout = [&](const br::DmpRolloutRecord&, br::RolloutTask* ran) {
    const auto* bottles = dynamic_cast<br::BottleRolloutTask*>(ran);
    ASSERT_NE(bottles, nullptr);
    const bt::WamBottleRollout& r = bottles->lastRollout();
    if (r.outcome != bt::FoldOutcome::Ok) return;
    EXPECT_EQ(r.joint_path.cols(), r.tool_path.cols());
    EXPECT_EQ(r.joint_path.rows(), 7);
    EXPECT_EQ(r.bottle_path.size(), 2 * static_cast<std::size_t>(r.tool_path.cols()));
    ++recorded;
  };
  br::DmpLearner learner(br::bottleTaskModel(task.task()), config.learning, dir, evaluator(), observer);
  const br::DmpLearningResult result = learner.learn();
  ASSERT_EQ(result.runs.size(), 1u);
  EXPECT_EQ(result.ran, 18);
  EXPECT_GT(recorded, 10);
  const br::DmpRunResult& run = result.runs.front();
  EXPECT_EQ(run.initial_policy.result.terms[0], 2.0) << "the straight line knocks both bottles down";
  EXPECT_GT((run.final_policy.weights - run.initial_policy.weights).norm(), 1.0) << "DREPS moved the policy";
  // Again from the directory: every rollout taken from it, the same learning.
  br::DmpLearner again(br::bottleTaskModel(task.task()), config.learning, dir, evaluator());
  const br::DmpLearningResult resumed = again.learn();
  EXPECT_EQ(resumed.ran, 0);
  EXPECT_EQ(resumed.resumed, 18);
  EXPECT_EQ(resumed.runs.front().final_policy.weights, run.final_policy.weights);
  // The directory belongs to this task and reward: (6.17) is refused there.
  br::BottleLearningConfig other = config;
  other.task.crossing_term = false;
  br::BottleRolloutTask other_task(other.task);
  EXPECT_THROW(br::DmpLearner(br::bottleTaskModel(other_task.task()), other.learning, dir, evaluator()),
               std::invalid_argument);
  fs::remove_all(dir);
}
