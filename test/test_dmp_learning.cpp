// rollout::DmpLearner on a task of known optimum (a 2-DoF DMP that must pass a via-point halfway): PI2-CMA on the
// second layer of Gaussians, REPS with IDR and the standard DMP all learn it; a learning stopped half way resumes
// to the same epochs to the byte; one thread or two give the same files; robot faults are run again and never
// learned from; a directory of another configuration is refused; the second layer's weights are normalised Gaussians.
#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>

namespace br = bimanual_skills::rollout;
namespace bp = bimanual_skills::primitives;
namespace fs = std::filesystem;
using bimanual_skills::testing::readTextFile;

namespace {

constexpr int kDofs = 2, kKernels = 10;
constexpr double kStep = 0.01;
const Eigen::Vector2d kVia(0.2, 0.8);  // the demonstration passes (0.5, 0.25) halfway

bp::DrDmpParameters forcing(int matrices) {
  bp::DrDmpParameters p;
  p.dmp.kernels = kKernels;
  p.matrices = matrices;
  return p;
}

/// From (0, 0) to (1, 1) in 1 s: the first DoF by minimum jerk m(s), the second as m(s)² (two distinct DoF, so that
/// the coordination has two directions).
Eigen::MatrixXd demonstration() {
  Eigen::MatrixXd y(101, kDofs);
  for (int k = 0; k <= 100; ++k) {
    const double s = k / 100.0, m = s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
    y.row(k) << m, m * m;
  }
  return y;
}

/// Faults injected by seed: the first attempt at every rollout whose seed is divisible by `every` fails.
struct Faults {
  int every = 0;
  std::mutex mutex;
  std::set<std::uint32_t> failed;
};

class ViaPointTask final : public br::RolloutTask {
 public:
  explicit ViaPointTask(Faults* faults = nullptr) : faults_(faults) {}
  std::vector<std::string> termNames() const override { return {"via_error", "success"}; }
  Eigen::VectorXd initialParameters() const override { return {}; }
  br::RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override {
    br::RolloutResult out;
    if (faults_ != nullptr && faults_->every > 0 && seed % static_cast<std::uint32_t>(faults_->every) == 0) {
      const std::lock_guard<std::mutex> lock(faults_->mutex);
      if (faults_->failed.insert(seed).second) {
        out.ok = false;
        out.outcome = "RobotFailed";
        out.reason = "the gripper did not answer";
        out.terms = Eigen::Vector2d::Zero();
        return out;
      }
    }
    std::vector<Eigen::MatrixXd> coordination;
    Eigen::VectorXd weights;
    if (!br::decodeCoordinatedPolicy(parameters, kDofs, kKernels, coordination, weights)) {
      throw std::logic_error("the learner sent parameters that do not decode");
    }
    const bp::DrDmp dmp(forcing(static_cast<int>(coordination.size())), coordination, weights, Eigen::Vector2d::Zero(),
                        Eigen::Vector2d::Ones(), 1.0);
    bp::DrDmpState state = dmp.initialState();
    for (int k = 0; k < 50; ++k) (void)dmp.step(state, kStep);
    const double error = (state.dmp.y - kVia).norm();
    out.outcome = "Ok";
    out.reward = -error;
    out.terms = Eigen::Vector2d(error, error < 0.05 ? 1.0 : 0.0);
    out.wall_seconds = 0.0;
    return out;
  }

 private:
  Faults* faults_;
};

br::DmpTaskModel model() {
  br::DmpTaskModel m;
  m.dofs = kDofs;
  m.forcing = forcing;
  m.demonstration = demonstration();
  m.step = kStep;
  m.terms = {"via_error", "success"};
  m.success = "success";
  m.locks = {{"task.txt", "via 0.2 0.8\n"}};
  return m;
}

br::DmpLearningConfig config(const std::string& algorithm) {
  br::DmpLearningConfig c;
  c.algorithms = {algorithm};
  c.updates = 25;
  c.rollouts = 10;
  c.initial_stddev = 150.0;
  c.dual_kernels = algorithm == "PI2-CMA" ? 4 : 0;
  c.covariance_memory = algorithm == "PI2-CMA" ? 0.0 : 0.9;  // REPS without memory stalls early here
  c.diagonal_covariance = true;
  c.seed = 7;
  c.jobs = 1;
  return c;
}

std::string fresh(const std::string& name) {
  const std::string dir = (fs::temp_directory_path() / ("dmp_learning_test_" + name)).string();
  fs::remove_all(dir);
  return dir;
}

br::DmpLearningResult learn(const br::DmpLearningConfig& c, const std::string& dir, Faults* faults = nullptr,
                            br::DmpLearningObserver observer = {}) {
  auto threads =
      std::make_unique<br::ParallelEvaluator>([faults] { return std::make_unique<ViaPointTask>(faults); }, c.jobs);
  br::DmpLearner learner(model(), c, dir, std::move(threads), std::move(observer));
  return learner.learn();
}

}  // namespace

TEST(DmpLearning, EveryAlgorithmLearnsTheViaPoint) {
  for (const std::string algorithm : {"PI2-CMA", "IDR-DMP_CMU", "DR-DMP0(2)"}) {
    const br::DmpLearningResult r = learn(config(algorithm), fresh(algorithm.substr(0, 3)));
    ASSERT_EQ(r.runs.size(), 1u);
    const br::DmpRunResult& run = r.runs.front();
    const double before = -run.initial_policy.result.reward, after = -run.final_policy.result.reward;
    std::printf("%s: via-point error of the noise-free policy %.4f -> %.4f\n", algorithm.c_str(), before, after);
    EXPECT_NEAR(before, (Eigen::Vector2d(0.5, 0.25) - kVia).norm(), 0.01) << "it starts at the demonstration";
    EXPECT_LT(after, 0.5 * before) << algorithm;
    EXPECT_EQ(r.ran, 26 * 11);
    EXPECT_EQ(run.epochs.size(), 26u);
  }
}

TEST(DmpLearning, AStoppedLearningResumesToTheSameFilesAndThreadsDoNotMatter) {
  const br::DmpLearningConfig c = config("PI2-CMA");
  const std::string whole = fresh("whole"), stopped = fresh("stopped"), two = fresh("two");
  learn(c, whole);
  std::atomic<int> seen{0};
  br::DmpLearningObserver observer;
  observer.rollout = [&](const br::DmpRolloutRecord&, br::RolloutTask*) { ++seen; };
  observer.stop = [&] { return seen.load() >= 40; };
  EXPECT_THROW(learn(c, stopped, nullptr, observer), std::runtime_error);
  const br::DmpLearningResult resumed = learn(c, stopped);
  EXPECT_GE(resumed.resumed, 40);
  EXPECT_EQ(resumed.resumed + resumed.ran, 26 * 11);
  EXPECT_EQ(readTextFile(stopped + "/epochs.csv"), readTextFile(whole + "/epochs.csv"));
  br::DmpLearningConfig parallel = c;
  parallel.jobs = 2;
  learn(parallel, two);
  EXPECT_EQ(readTextFile(two + "/epochs.csv"), readTextFile(whole + "/epochs.csv"));
  // Another seed in a directory of this one: refused, nothing overwritten.
  br::DmpLearningConfig other = c;
  other.seed = 8;
  try {
    learn(other, whole);
    ADD_FAILURE() << "a learning of another seed reused the directory";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("another configuration or seed"), std::string::npos) << e.what();
  }
}

TEST(DmpLearning, RobotFaultsAreRunAgainAndNeverLearnedFrom) {
  const br::DmpLearningConfig c = config("PI2-CMA");
  const std::string clean = fresh("clean"), faulty = fresh("faulty");
  learn(c, clean);
  Faults faults;
  faults.every = 3;
  const br::DmpLearningResult r = learn(c, faulty, &faults);
  EXPECT_GT(r.robot_faults, 10);
  EXPECT_EQ(readTextFile(faulty + "/epochs.csv"), readTextFile(clean + "/epochs.csv"));
  EXPECT_EQ(readTextFile(faulty + "/rollouts.csv").find("RobotFailed"), std::string::npos);
  EXPECT_NE(readTextFile(faulty + "/robot_faults.csv").find("the gripper did not answer"), std::string::npos);
  // A robot that is down: the learning stops with the reason.
  br::DmpLearningConfig strict = c;
  strict.robot_retries = 0;
  Faults down;
  down.every = 1;
  try {
    learn(strict, fresh("down"), &down);
    ADD_FAILURE() << "a robot failing every rollout did not stop the learning";
  } catch (const br::RobotFaults& e) {
    EXPECT_NE(std::string(e.what()).find("the gripper did not answer"), std::string::npos) << e.what();
  }
}

TEST(DmpLearning, TheSecondLayerAndTheConfigurationAreChecked) {
  const Eigen::MatrixXd phi = br::dualLayer(25, 8);
  ASSERT_EQ(phi.rows(), 25);
  ASSERT_EQ(phi.cols(), 8);
  EXPECT_NEAR((phi.rowwise().sum().array() - 1.0).abs().maxCoeff(), 0.0, 1e-12);
  EXPECT_GT(phi(0, 0), phi(0, 1)) << "the first kernel is mostly the first Gaussian's";
  EXPECT_GT(phi(24, 7), phi(24, 6));
  EXPECT_THROW(br::dualLayer(25, 0), std::invalid_argument);
  EXPECT_THROW(br::dualLayer(25, 26), std::invalid_argument);
  br::DmpLearningConfig c = config("PI2-CMA");
  c.algorithms = {"SGD"};
  EXPECT_THROW(c.validate(kDofs), std::invalid_argument);
  c = config("PI2-CMA");
  c.rollouts = 1;
  EXPECT_THROW(c.validate(kDofs), std::invalid_argument);
  c = config("PI2-CMA");
  c.covariance_memory = 1.0;
  EXPECT_THROW(c.validate(kDofs), std::invalid_argument);
  br::DmpTaskModel bad = model();
  bad.success = "no_such_term";
  EXPECT_THROW(
      br::DmpLearner(bad, config("PI2-CMA"), fresh("bad"),
                     std::make_unique<br::ParallelEvaluator>([] { return std::make_unique<ViaPointTask>(); }, 1)),
      std::invalid_argument);
}
