#include "bimanual_skills/rollout/task_registry.hpp"

#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "io/yaml_io.hpp"

#include <cmath>
#include <random>
#include <stdexcept>

namespace bimanual_skills::rollout {

namespace {

class QuadraticTask : public RolloutTask {
 public:
  QuadraticTask(int dimension, double noise) : dimension_(dimension), noise_(noise) {}

  std::vector<std::string> termNames() const override { return {"squared_norm"}; }
  Eigen::VectorXd initialParameters() const override { return Eigen::VectorXd::Ones(dimension_); }

  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override {
    RolloutResult result;
    result.terms = Eigen::VectorXd::Zero(1);
    if (parameters.size() != dimension_ || !parameters.allFinite()) {
      result.ok = false;
      result.outcome = "InvalidPolicy";
      result.reason =
          "expected " + std::to_string(dimension_) + " finite parameters, got " + std::to_string(parameters.size());
      result.reward = -kFailureReward;
      return result;
    }
    std::seed_seq sequence{seed, 0x9a4du};
    std::mt19937 rng(sequence);
    std::normal_distribution<double> normal;
    result.terms[0] = parameters.squaredNorm();
    result.reward = -result.terms[0] / dimension_ + noise_ * normal(rng);
    result.outcome = "Ok";
    return result;
  }

 private:
  static constexpr double kFailureReward = 1e3;
  int dimension_;
  double noise_;
};

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
  return std::make_unique<QuadraticTask>(dimension, noise);
}

std::unique_ptr<RolloutTask> makeFold(const std::string& config) {
  if (config.empty()) throw std::invalid_argument("task 'fold' needs a fold learning file as its configuration");
  const FoldLearningConfig c = withSimulationRenderer(FoldLearningConfig::fromYamlFile(config));
  return std::make_unique<FoldRolloutTask>(c.task, c.reward);
}

}  // namespace

const std::vector<RolloutTaskInfo>& rolloutTasks() {
  static const std::vector<RolloutTaskInfo> tasks = {
      {"fold", "a fold learning file (config/fold_demo.yaml)",
       "the two simulated WAMs fold the cloth, scored by eq. 7.52 (a policy: FoldRolloutTask::encode)"},
      {"quadratic", "optional YAML with dimension (10) and noise (0)",
       "-|theta|^2/n plus seeded noise, no simulation: measures the dispatch's own cost"}};
  return tasks;
}

std::unique_ptr<RolloutTask> makeRolloutTask(const std::string& name, const std::string& config) {
  if (name == "fold") return makeFold(config);
  if (name == "quadratic") return makeQuadratic(config);
  std::string known;
  for (const RolloutTaskInfo& t : rolloutTasks()) known += (known.empty() ? "" : ", ") + t.name;
  throw std::invalid_argument("unknown rollout task '" + name + "' (known: " + known + ")");
}

}  // namespace bimanual_skills::rollout
