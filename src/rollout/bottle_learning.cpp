#include "bimanual_skills/rollout/bottle_learning.hpp"

#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"
#include "io/yaml_io.hpp"
#include "learning_section.hpp"

#include <stdexcept>

namespace bimanual_skills::rollout {

BottleLearningConfig BottleLearningConfig::fromYamlFile(const std::string& path) {
  const std::string where = "bottle learning file '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  io::checkKeys(root, where, {"task", "crossing_term", "learning"});
  BottleLearningConfig c;
  c.task = tasks::WamBottleConfig::fromYamlFile(io::resolvePath(path, io::readString(root, "task", where)));
  if (root["crossing_term"]) c.task.crossing_term = io::readBool(root, "crossing_term", where);
  // The thesis' planar settings (ps_benchmark bottles): ε 0.5, 200 rollouts reused, Σ₀ = 60² I.
  c.learning.algorithms = {"REPS", "DREPS"};
  c.learning.rollouts = 50;
  c.learning.reuse = 200;
  c.learning.initial_stddev = 60.0;
  if (const YAML::Node learning = root["learning"]) readSharedLearning(learning, where + " learning", c.learning, {});
  io::withContext(where, [&] {
    c.task.validate();
    c.learning.validate(2);
    for (const std::string& a : c.learning.algorithms) {
      if (parseDrDmpVariant(a, 2, c.learning.eta).matrices != 1) {
        io::fail("algorithm '" + a + "': the bottle task's DMP has one coordination matrix");
      }
    }
  });
  return c;
}

BottleRolloutTask::BottleRolloutTask(const tasks::WamBottleConfig& config) : task_(config) {}

std::vector<std::string> BottleRolloutTask::names() {
  return {"bottles_down",     "length",           "crossed",      "satisfactory",
          "side_1",           "side_2",           "max_ik_error", "max_tracking_error",
          "max_height_error", "simulated_seconds"};
}

Eigen::VectorXd BottleRolloutTask::initialParameters() const {
  return encodeCoordinatedPolicy({Eigen::MatrixXd::Identity(2, 2)}, task_.initialParameters());
}

bool BottleRolloutTask::taskWeights(const Eigen::VectorXd& parameters, Eigen::VectorXd& theta) const {
  std::vector<Eigen::MatrixXd> coordination;
  Eigen::VectorXd weights;
  const int n = task_.kernels();
  if (!decodeCoordinatedPolicy(parameters, 2, n, coordination, weights) || coordination.size() != 1) return false;
  const Eigen::MatrixXd& omega = coordination.front();
  // W (r × n): latent DoF by latent DoF; the task's θ: the rows of Ω W, x's kernels then y's.
  const Eigen::MatrixXd w = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      weights.data(), omega.cols(), n);
  const Eigen::MatrixXd per_dof = omega * w;
  theta.resize(2 * n);
  for (int d = 0; d < 2; ++d) theta.segment(d * n, n) = per_dof.row(d).transpose();
  return theta.allFinite();
}

RolloutResult BottleRolloutTask::run(const Eigen::VectorXd& parameters, std::uint32_t seed) {
  Eigen::VectorXd theta;
  if (taskWeights(parameters, theta)) {
    last_ = task_.run(theta, seed);
  } else {
    last_ = tasks::WamBottleRollout();
    last_.outcome = tasks::FoldOutcome::InvalidPolicy;
    last_.reason = "the parameters do not encode a finite coordinated policy of 2 DoF, " +
                   std::to_string(task_.kernels()) + " weights per latent DoF and one matrix";
    last_.reward = task_.config().failure_reward;
  }
  return resultOf(last_);
}

RolloutResult BottleRolloutTask::resultOf(const tasks::WamBottleRollout& r) {
  RolloutResult out;
  out.ok = r.outcome == tasks::FoldOutcome::Ok;
  out.outcome = tasks::toString(r.outcome);
  out.reason = r.reason;
  out.reward = r.reward;
  out.wall_seconds = r.wall_seconds;
  out.terms.resize(static_cast<Eigen::Index>(names().size()));
  out.terms << r.down, r.length, r.crossed ? 1.0 : 0.0, r.satisfactory ? 1.0 : 0.0, r.sides[0], r.sides[1],
      r.max_ik_error, r.max_tracking_error, r.max_height_error, r.simulated_seconds;
  out.trajectory = r.tool_path;
  return out;
}

DmpTaskModel bottleTaskModel(const tasks::WamBottleTask& task) {
  DmpTaskModel model;
  model.dofs = 2;
  model.forcing = [kernels = task.kernels()](int matrices) {
    primitives::DrDmpParameters p;
    p.dmp.kernels = kernels;
    p.matrices = matrices;
    return p;
  };
  model.demonstration = tasks::BottleTask::demonstration();
  model.step = tasks::BottleTask::kDemonstrationStep;
  model.terms = BottleRolloutTask::names();
  model.success = "satisfactory";
  tasks::WamBottleConfig settings = task.config();
  settings.sim_config = "(world.txt)";  // where the file is does not matter, what it holds does
  model.locks = {{"task.yaml", settings.toYaml()},
                 {"world.txt", "sim_config " + sim::SimConfig::worldDigest(task.config().sim_config) + "\n"}};
  return model;
}

}  // namespace bimanual_skills::rollout
