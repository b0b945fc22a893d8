#include "bimanual_skills/rollout/task_registry.hpp"

#include "bimanual_skills/rollout/bottle_learning.hpp"

#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/tasks/dr_tasks.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"
#include "bimanual_skills/tasks/wam_bottles.hpp"
#include "io/yaml_io.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <stdexcept>

namespace bimanual_skills::rollout {

namespace {

/// The result of a rollout whose parameters the task cannot run: failed, with a reward below any real one.
RolloutResult invalidPolicy(std::size_t terms, std::string reason) {
  RolloutResult result;
  result.terms = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(terms));
  result.ok = false;
  result.outcome = "InvalidPolicy";
  result.reason = std::move(reason);
  result.reward = -1e3;
  return result;
}

/// A task without simulation state: θ of a fixed size (and the rollout's seed) in, reward and terms out.
class PolicySearchTask : public RolloutTask {
 public:
  using Evaluate = std::function<double(const Eigen::VectorXd& theta, std::uint32_t seed, Eigen::VectorXd& terms)>;
  PolicySearchTask(std::vector<std::string> terms, Eigen::VectorXd initial, Evaluate evaluate)
      : terms_(std::move(terms)), initial_(std::move(initial)), evaluate_(std::move(evaluate)) {}

  std::vector<std::string> termNames() const override { return terms_; }
  Eigen::VectorXd initialParameters() const override { return initial_; }

  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override {
    if (parameters.size() != initial_.size() || !parameters.allFinite()) {
      return invalidPolicy(terms_.size(), "expected " + std::to_string(initial_.size()) + " finite parameters, got " +
                                              std::to_string(parameters.size()));
    }
    RolloutResult result;
    result.terms = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(terms_.size()));
    result.reward = evaluate_(parameters, seed, result.terms);
    result.outcome = "Ok";
    return result;
  }

 private:
  std::vector<std::string> terms_;
  Eigen::VectorXd initial_;
  Evaluate evaluate_;
};

std::unique_ptr<RolloutTask> makeBottles(const std::string& config) {
  tasks::BottleTask world;
  if (!config.empty()) {
    const std::string where = "bottles task '" + config + "'";
    const YAML::Node root = io::loadYamlFile(config, where);
    io::checkKeys(root, where, {"crossing_term"});
    if (root["crossing_term"]) world.crossing_term = io::readBool(root, "crossing_term", where);
  }
  const auto policy = std::make_shared<tasks::DmpRollout>(tasks::BottleTask::initialPolicy());
  const auto y = std::make_shared<Eigen::MatrixXd>(), ydd = std::make_shared<Eigen::MatrixXd>();
  return std::make_unique<PolicySearchTask>(
      std::vector<std::string>{"satisfactory"}, policy->parameters(),
      [world, policy, y, ydd](const Eigen::VectorXd& theta, std::uint32_t, Eigen::VectorXd& terms) {
        policy->rollout(theta, *y, *ydd);
        bool satisfactory = false;
        const double reward = world.reward(*y, &satisfactory);
        terms[0] = satisfactory ? 1.0 : 0.0;
        return reward;
      });
}

/// The bottle task on the simulated WAM: terms satisfactory, down, length, crossed, max_tracking_error; the
/// trajectory is the measured tool path (3 × samples, world).
class WamBottlesTask : public RolloutTask {
 public:
  explicit WamBottlesTask(const tasks::WamBottleConfig& config) : task_(config) {}
  std::vector<std::string> termNames() const override {
    return {"satisfactory", "bottles_down", "length", "crossed", "max_tracking_error"};
  }
  Eigen::VectorXd initialParameters() const override { return task_.initialParameters(); }
  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override {
    const tasks::WamBottleRollout r = task_.run(parameters, seed);
    RolloutResult result;
    result.reward = r.reward;
    result.terms = (Eigen::VectorXd(5) << (r.satisfactory ? 1.0 : 0.0), static_cast<double>(r.down), r.length,
                    (r.crossed ? 1.0 : 0.0), r.max_tracking_error)
                       .finished();
    result.ok = r.outcome == tasks::FoldOutcome::Ok;
    result.outcome = tasks::toString(r.outcome);
    result.reason = r.reason;
    result.wall_seconds = r.wall_seconds;
    result.trajectory = r.tool_path;
    return result;
  }

 private:
  tasks::WamBottleTask task_;
};

std::unique_ptr<RolloutTask> makeWamBottles(const std::string& config) {
  if (config.empty()) {
    throw std::invalid_argument("task 'wam_bottles' needs a configuration (config/bottles_wam.yaml)");
  }
  return std::make_unique<WamBottlesTask>(tasks::WamBottleConfig::fromYamlFile(config));
}

std::unique_ptr<RolloutTask> makeCircle(const std::string& config) {
  if (config.empty()) throw std::invalid_argument("task 'circle' needs a configuration (config/circle_task.yaml)");
  const std::string where = "circle task '" + config + "'";
  const YAML::Node root = io::loadYamlFile(config, where);
  io::checkKeys(root, where, {"urdf", "base", "tip", "seed"});
  const std::string urdf = io::resolvePath(config, io::readString(root, "urdf", where));
  const int seed = io::readInt(root, "seed", where);
  if (seed < 0) io::fail(where + ": 'seed' must be >= 0");
  const auto task = io::withContext(where, [&] {
    return std::make_shared<tasks::CircleTask>(
        kinematics::ChainModel::fromUrdfFile(urdf, io::readString(root, "base", where),
                                             io::readString(root, "tip", where)),
        static_cast<std::uint32_t>(seed));
  });
  return std::make_unique<PolicySearchTask>(
      std::vector<std::string>{"circle_radius"}, task->policy().parameters(),
      [task](const Eigen::VectorXd& theta, std::uint32_t, Eigen::VectorXd& terms) {
        terms[0] = task->radius();
        return task->reward(theta);
      });
}

std::unique_ptr<RolloutTask> makeViaPoint() {
  const auto task = std::make_shared<tasks::ViaPointTask>();
  // The step costs are the reward's terms (PI2 learns from them), then the via-point's error.
  std::vector<std::string> terms;
  for (int i = 0; i < task->policy().steps; ++i) terms.push_back("step_cost_" + std::to_string(i));
  terms.emplace_back("via_point_error");
  return std::make_unique<PolicySearchTask>(
      terms, task->policy().parameters(), [task](const Eigen::VectorXd& theta, std::uint32_t, Eigen::VectorXd& terms) {
        double via_error = 0.0;
        const Eigen::VectorXd costs = task->stepCosts(theta, &via_error);
        terms.head(costs.size()) = costs;
        terms[costs.size()] = via_error;
        return -costs.sum();
      });
}

std::unique_ptr<RolloutTask> makeMultimodal(const std::string& config) {
  int dimension = 2;
  if (!config.empty()) {
    const std::string where = "multimodal task '" + config + "'";
    const YAML::Node root = io::loadYamlFile(config, where);
    io::checkKeys(root, where, {"dimension"});
    if (root["dimension"]) dimension = io::readInt(root, "dimension", where);
    if (dimension < 2 || dimension % 2 != 0) io::fail(where + ": 'dimension' must be even and >= 2");
  }
  const tasks::MultimodalReward reward = tasks::MultimodalReward::inDimension(dimension);
  return std::make_unique<PolicySearchTask>(
      std::vector<std::string>{"nearest_optimum_distance"}, Eigen::VectorXd::Zero(dimension),
      [reward](const Eigen::VectorXd& theta, std::uint32_t, Eigen::VectorXd& terms) {
        terms[0] = (reward.optima.front() - theta).norm();
        for (const Eigen::VectorXd& p : reward.optima) terms[0] = std::min(terms[0], (p - theta).norm());
        return reward(theta);
      });
}

/// Table 7.3's planar via-point task with a DR-DMP: the policy is a coordinated policy vector
/// (encodeCoordinatedPolicy) over the DR-DMP fitted to the task's demonstrations; the exploration outside the latent
/// space is drawn from the rollout's seed.
class PlanarViaPointRollout : public RolloutTask {
 public:
  PlanarViaPointRollout(int dofs, std::uint32_t seed, int kernels, int matrices, double exploration)
      : task_(dofs, seed), exploration_(exploration) {
    primitives::DrDmpParameters parameters;
    parameters.dmp.kernels = kernels;
    parameters.matrices = matrices;
    dmp_ = std::make_unique<primitives::DrDmp>(
        primitives::DrDmp::fit(parameters, task_.demonstrations(), task_.dt(), dofs).dmp);
  }

  std::vector<std::string> termNames() const override { return {"via_point_1_error", "via_point_2_error"}; }
  Eigen::VectorXd initialParameters() const override {
    return encodeCoordinatedPolicy(dmp_->coordination(), dmp_->weights());
  }

  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override {
    std::vector<Eigen::MatrixXd> coordination;
    Eigen::VectorXd weights;
    if (!decodeCoordinatedPolicy(parameters, task_.dofs(), dmp_->basisSize(), coordination, weights) ||
        static_cast<int>(coordination.size()) != dmp_->matrices() || !parameters.allFinite()) {
      return invalidPolicy(2, "the parameters do not encode a finite coordinated policy of " +
                                  std::to_string(task_.dofs()) + " DoF, " + std::to_string(dmp_->kernels()) +
                                  " kernels and " + std::to_string(dmp_->matrices()) + " matrices");
    }
    RolloutResult result;
    result.terms = Eigen::VectorXd::Zero(2);
    std::seed_seq sequence{seed, 0x71a3u};
    std::mt19937 rng(sequence);
    tasks::rolloutDrDmp(dmp_->withCoordination(coordination, weights), task_.dt(), task_.steps(), exploration_, rng,
                        rollout_);
    for (int v = 0; v < 2; ++v) {
      const Eigen::VectorXd q = rollout_.positions.row(task_.viaSteps()[static_cast<std::size_t>(v)]).transpose();
      result.terms[v] = (tasks::planarTip(q) - task_.viaPoints()[static_cast<std::size_t>(v)]).norm();
    }
    result.reward = task_.reward(rollout_.positions, rollout_.accelerations);
    result.outcome = "Ok";
    return result;
  }

 private:
  tasks::PlanarViaPointTask task_;
  double exploration_;
  std::unique_ptr<primitives::DrDmp> dmp_;
  tasks::DrDmpRollout rollout_;
};

std::unique_ptr<RolloutTask> makePlanarViaPoint(const std::string& config) {
  int dofs = 10, seed = 1, kernels = 5, matrices = 1;
  double exploration = std::sqrt(0.1);
  if (!config.empty()) {
    const std::string where = "planar_viapoint task '" + config + "'";
    const YAML::Node root = io::loadYamlFile(config, where);
    io::checkKeys(root, where, {"dofs", "seed", "kernels", "matrices", "exploration"});
    if (root["dofs"]) dofs = io::readInt(root, "dofs", where);
    if (root["seed"]) seed = io::readInt(root, "seed", where);
    if (root["kernels"]) kernels = io::readInt(root, "kernels", where);
    if (root["matrices"]) matrices = io::readInt(root, "matrices", where);
    exploration = io::readDouble(root, "exploration", where, exploration);
    if (seed < 0 || kernels < 1 || matrices < 1 || exploration < 0.0) {
      io::fail(where + ": 'seed' and 'exploration' must be >= 0, 'kernels' and 'matrices' >= 1");
    }
  }
  return std::make_unique<PlanarViaPointRollout>(dofs, static_cast<std::uint32_t>(seed), kernels, matrices,
                                                 exploration);
}

std::unique_ptr<RolloutTask> makeQuadratic(const std::string& config) {
  int dimension = 10;
  double noise = 0.0;
  if (!config.empty()) {
    const std::string where = "quadratic task '" + config + "'";
    const YAML::Node root = io::loadYamlFile(config, where);
    io::checkKeys(root, where, {"dimension", "noise"});
    if (root["dimension"]) dimension = io::readInt(root, "dimension", where);
    noise = io::readDouble(root, "noise", where, noise);
    if (dimension < 1) io::fail(where + ": 'dimension' must be >= 1");
    if (noise < 0.0) io::fail(where + ": 'noise' must be >= 0");
  }
  return std::make_unique<PolicySearchTask>(
      std::vector<std::string>{"squared_norm"}, Eigen::VectorXd::Ones(dimension),
      [dimension, noise](const Eigen::VectorXd& theta, std::uint32_t seed, Eigen::VectorXd& terms) {
        std::seed_seq sequence{seed, 0x9a4du};
        std::mt19937 rng(sequence);
        terms[0] = theta.squaredNorm();
        return -terms[0] / dimension + noise * std::normal_distribution<double>()(rng);
      });
}

std::unique_ptr<RolloutTask> makeFold(const std::string& config) {
  if (config.empty()) throw std::invalid_argument("task 'fold' needs a fold learning file as its configuration");
  const FoldLearningConfig c = withSimulationRenderer(FoldLearningConfig::fromYamlFile(config));
  return std::make_unique<FoldRolloutTask>(c.task, c.reward);
}

std::unique_ptr<RolloutTask> makeBottlesLearning(const std::string& config) {
  if (config.empty()) {
    throw std::invalid_argument("task 'bottles_learning' needs a bottles learning file as its configuration");
  }
  return std::make_unique<BottleRolloutTask>(BottleLearningConfig::fromYamlFile(config).task);
}

std::unique_ptr<RolloutTask> makeScarf(const std::string& config) {
  if (config.empty()) throw std::invalid_argument("task 'scarf' needs a scarf learning file as its configuration");
  return std::make_unique<ScarfRolloutTask>(ScarfLearningConfig::fromYamlFile(config).task);
}

}  // namespace

const std::vector<RolloutTaskInfo>& rolloutTasks() {
  static const std::vector<RolloutTaskInfo> tasks = {
      {"fold", "a fold learning file (config/fold_demo.yaml)",
       "the two simulated WAMs fold the cloth, scored by the file's reward (a policy: encodeCoordinatedPolicy)"},
      {"scarf", "a scarf learning file (config/scarf_learning.yaml)",
       "the simulated WAM puts a scarf round a mannequin's neck, thesis Sec. 4.3.1 (a policy: "
       "encodeCoordinatedPolicy)"},
      {"quadratic", "optional YAML with dimension (10) and noise (0)",
       "-|theta|^2/n plus seeded noise, no simulation: measures the dispatch's own cost"},
      {"bottles", "optional YAML with crossing_term (true: reward 6.18; false: 6.17)",
       "the planar path between two bottles of thesis Figs. 6.8-6.12 (a DMP of 20 weights)"},
      {"bottles_learning", "a bottles learning file (config/bottles_learning.yaml)",
       "the bottle task on the simulated WAM as bottles_learner runs it, its crossing_term the file's (a policy: "
       "encodeCoordinatedPolicy of one matrix)"},
      {"wam_bottles", "the task file (config/bottles_wam.yaml)",
       "the bottle task on the simulated WAM, thesis Sec. 6.2: its tool between two free bottles (a DMP of 20 "
       "weights; terms satisfactory, bottles_down, length, crossed, max_tracking_error; trajectory: the tool path)"},
      {"circle", "YAML with urdf, base, tip and the demonstration's seed (config/circle_task.yaml)",
       "the WAM tool traces a circle, thesis Fig. 6.14 (a 7-DoF DMP)"},
      {"planar_viapoint", "optional YAML with dofs (10), seed (1), kernels (5), matrices (1), exploration (0.316)",
       "thesis Table 7.3: a planar arm through two via-points, a DR-DMP policy (encodeCoordinatedPolicy)"},
      {"viapoint", "none",
       "Stulp's 1-D DMP through a via-point (ps_benchmark pi2viapoint; terms: the step costs PI2 learns from, then "
       "the via-point's error; reward: minus the summed step costs)"},
      {"multimodal", "optional YAML with dimension (2, even)",
       "the reward with three optima of thesis eq. 6.16, in 2-D or d dimensions (ps_benchmark multimodal2d, "
       "multimodal_scale)"}};
  return tasks;
}

std::unique_ptr<RolloutTask> makeRolloutTask(const std::string& name, const std::string& config) {
  if (name == "fold") return makeFold(config);
  if (name == "scarf") return makeScarf(config);
  if (name == "quadratic") return makeQuadratic(config);
  if (name == "bottles") return makeBottles(config);
  if (name == "wam_bottles") return makeWamBottles(config);
  if (name == "bottles_learning") return makeBottlesLearning(config);
  if (name == "circle") return makeCircle(config);
  if (name == "viapoint") return makeViaPoint();
  if (name == "planar_viapoint") return makePlanarViaPoint(config);
  if (name == "multimodal") return makeMultimodal(config);
  std::string known;
  for (const RolloutTaskInfo& t : rolloutTasks()) known += (known.empty() ? "" : ", ") + t.name;
  throw std::invalid_argument("unknown rollout task '" + name + "' (known: " + known + ")");
}

}  // namespace bimanual_skills::rollout
