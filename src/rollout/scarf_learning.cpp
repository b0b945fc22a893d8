#include "bimanual_skills/rollout/scarf_learning.hpp"

#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "io/csv_records.hpp"
#include "io/digest.hpp"
#include "io/yaml_io.hpp"
#include "learning_section.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::rollout {

namespace {

/// The settings a run directory's rollouts were made with (DIR/task.txt).
std::string settingsText(const tasks::ScarfTaskConfig& c) {
  std::ostringstream text;
  const auto n = [](double v) { return io::exactNumber(v); };
  text << "arm " << c.arm << "\nkernels " << c.kernels << "\nduration " << n(c.duration) << "\nhold_before "
       << n(c.hold_before) << "\nhold_after " << n(c.hold_after) << "\nsettle " << n(c.settle) << "\nrelease "
       << (c.release ? 1 : 0) << "\nmax_tracking_error " << n(c.max_tracking_error) << "\nvelocity_limit "
       << n(c.velocity_limit) << "\nacceleration_weight " << n(c.acceleration_weight) << "\ntorque_weight "
       << n(c.torque_weight) << "\nfailure_cost " << n(c.failure_cost) << "\nd_ref " << n(c.camera.d_ref)
       << "\nhanging_level " << n(c.camera.hanging_level) << "\nalpha " << n(c.camera.alpha) << "\ndistance_weight "
       << n(c.camera.distance_weight) << "\nhanging_weight " << n(c.camera.hanging_weight) << "\nprinted "
       << (c.camera.printed ? 1 : 0) << "\nband " << c.camera.band << "\nwaypoints";
  for (const Eigen::Vector3d& w : c.demo_waypoints) text << ' ' << n(w.x()) << ' ' << n(w.y()) << ' ' << n(w.z());
  text << '\n';
  if (c.clear_posture.size() > 0) {  // a learning without the move reads as before it existed
    text << "clear_time " << n(c.clear_time) << "\nclear_posture";
    for (const double q : c.clear_posture) text << ' ' << n(q);
    text << '\n';
  }
  return text.str();
}

}  // namespace

ScarfLearningConfig ScarfLearningConfig::fromYamlFile(const std::string& path) {
  const std::string where = "scarf learning file '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  io::checkKeys(root, where, {"sim", "start", "task", "camera", "learning"});
  ScarfLearningConfig c;
  c.task.sim_config = io::resolvePath(path, io::readString(root, "sim", where));
  c.task.start = io::resolvePath(path, io::readString(root, "start", where));
  if (const YAML::Node task = root["task"]) {
    const std::string at = where + " task";
    io::checkKeys(task, at,
                  {"arm", "kernels", "duration", "hold_before", "hold_after", "settle", "release", "clear_posture",
                   "clear_time", "demo_waypoints", "max_tracking_error", "velocity_limit", "acceleration_weight",
                   "torque_weight", "failure_cost"});
    tasks::ScarfTaskConfig& t = c.task;
    if (task["arm"]) t.arm = io::readString(task, "arm", at);
    if (task["kernels"]) t.kernels = io::readInt(task, "kernels", at);
    t.duration = io::readDouble(task, "duration", at, t.duration);
    t.hold_before = io::readDouble(task, "hold_before", at, t.hold_before);
    t.hold_after = io::readDouble(task, "hold_after", at, t.hold_after);
    t.settle = io::readDouble(task, "settle", at, t.settle);
    if (task["release"]) t.release = io::readBool(task, "release", at);
    if (task["clear_posture"]) t.clear_posture = io::readVector(task, "clear_posture", at);
    t.clear_time = io::readDouble(task, "clear_time", at, t.clear_time);
    if (const YAML::Node points = task["demo_waypoints"]) {
      if (!points.IsSequence()) io::fail(at + ": 'demo_waypoints' must be a list of [x, y, z]");
      for (std::size_t k = 0; k < points.size(); ++k) {
        t.demo_waypoints.push_back(io::toVector(points[k], at, "demo_waypoints[" + std::to_string(k) + "]", 3));
      }
    }
    t.max_tracking_error = io::readDouble(task, "max_tracking_error", at, t.max_tracking_error);
    t.velocity_limit = io::readDouble(task, "velocity_limit", at, t.velocity_limit);
    t.acceleration_weight = io::readDouble(task, "acceleration_weight", at, t.acceleration_weight);
    t.torque_weight = io::readDouble(task, "torque_weight", at, t.torque_weight);
    t.failure_cost = io::readDouble(task, "failure_cost", at, t.failure_cost);
  }
  if (const YAML::Node camera = root["camera"]) {
    const std::string at = where + " camera";
    io::checkKeys(
        camera, at,
        {"from_camera", "d_ref", "hanging_level", "alpha", "distance_weight", "hanging_weight", "reading", "band"});
    tasks::ScarfCameraConfig& k = c.task.camera;
    if (camera["from_camera"]) c.task.from_camera = io::readBool(camera, "from_camera", at);
    k.d_ref = io::readDouble(camera, "d_ref", at, k.d_ref);
    k.hanging_level = io::readDouble(camera, "hanging_level", at, k.hanging_level);
    k.alpha = io::readDouble(camera, "alpha", at, k.alpha);
    k.distance_weight = io::readDouble(camera, "distance_weight", at, k.distance_weight);
    k.hanging_weight = io::readDouble(camera, "hanging_weight", at, k.hanging_weight);
    if (camera["reading"]) {
      const std::string reading = io::readString(camera, "reading", at);
      if (reading != "absolute" && reading != "printed") {
        io::fail(at + ": 'reading' must be absolute (|d - d_ref|, the default) or printed (max(., 1))");
      }
      k.printed = reading == "printed";
    }
    if (camera["band"]) k.band = io::readInt(camera, "band", at);
  }
  if (const YAML::Node learning = root["learning"]) {
    const std::string at = where + " learning";
    DmpLearningConfig& l = c.learning;
    readSharedLearning(learning, at, l, {"dual_kernels", "diagonal_covariance", "h"});
    if (learning["dual_kernels"]) l.dual_kernels = io::readInt(learning, "dual_kernels", at);
    if (learning["diagonal_covariance"]) l.diagonal_covariance = io::readBool(learning, "diagonal_covariance", at);
    l.h = io::readDouble(learning, "h", at, l.h);
  }
  io::withContext(where, [&] {
    c.task.validate();
    // The learning's variants against the holding arm's joints on the simulation file's robot (a robot file given
    // later is checked again by the learner).
    const sim::SimConfig sim = sim::SimConfig::fromYamlFile(c.task.sim_config);
    const auto arm =
        std::find_if(sim.arms.begin(), sim.arms.end(), [&](const sim::ArmConfig& a) { return a.name == c.task.arm; });
    if (arm == sim.arms.end()) io::fail("task arm '" + c.task.arm + "' is not an arm of '" + c.task.sim_config + "'");
    c.learning.validate(static_cast<int>(arm->start.size()));
  });
  return c;
}

ScarfRolloutTask::ScarfRolloutTask(const tasks::ScarfTaskConfig& config) : task_(config) {}

std::vector<std::string> ScarfRolloutTask::names() {
  return {"cost",
          "c_acceleration",
          "c_cam",
          "c_torque",
          "acceleration",
          "mean_abs_torque",
          "peak_abs_torque",
          "mean_tool_force",
          "peak_tool_force",
          "mean_force_error",
          "max_force_error",
          "max_tracking_error",
          "d",
          "hanging",
          "right_pixels",
          "left_pixels",
          "winding",
          "wrapped",
          "hanging_right",
          "hanging_left",
          "fallen",
          "success",
          "simulated_seconds"};
}

Eigen::VectorXd ScarfRolloutTask::initialParameters() const {
  const int d = task_.dofs();
  return encodeCoordinatedPolicy({Eigen::MatrixXd::Identity(d, d)}, task_.demonstrationWeights());
}

RolloutResult ScarfRolloutTask::run(const Eigen::VectorXd& parameters, std::uint32_t seed) {
  std::vector<Eigen::MatrixXd> coordination;
  Eigen::VectorXd weights;
  if (decodeCoordinatedPolicy(parameters, task_.dofs(), task_.config().kernels, coordination, weights)) {
    last_ = task_.run(coordination, weights, seed);
  } else {
    last_ = tasks::ScarfRollout();
    last_.outcome = tasks::FoldOutcome::InvalidPolicy;
    last_.reason = "the parameters do not encode a coordinated policy of " + std::to_string(task_.dofs()) +
                   " DoF and " + std::to_string(task_.config().kernels) + " weights per latent DoF";
    last_.cost = task_.config().failure_cost;
  }
  return resultOf(last_);
}

RolloutResult ScarfRolloutTask::resultOf(const tasks::ScarfRollout& r) {
  RolloutResult out;
  out.ok = r.outcome == tasks::FoldOutcome::Ok;
  out.outcome = tasks::toString(r.outcome);
  out.reason = r.reason;
  out.reward = -r.cost;
  out.wall_seconds = r.wall_seconds;
  out.terms.resize(static_cast<Eigen::Index>(names().size()));
  out.terms << r.cost, r.c_acceleration, r.c_cam, r.c_torque, r.acceleration, r.mean_abs_torque, r.peak_abs_torque,
      r.mean_tool_force, r.peak_tool_force, r.mean_force_error, r.max_force_error, r.max_tracking_error, r.camera.d,
      r.camera.hanging, r.camera.right_pixels, r.camera.left_pixels, r.truth.winding, r.truth.wrapped ? 1.0 : 0.0,
      r.truth.hanging_right, r.truth.hanging_left, r.truth.fallen ? 1.0 : 0.0, r.truth.success ? 1.0 : 0.0,
      r.simulated_seconds;
  out.trajectory = r.tool_path;
  return out;
}

DmpTaskModel scarfTaskModel(const tasks::ScarfTask& task) {
  DmpTaskModel model;
  model.dofs = task.dofs();
  model.forcing = [parameters = task.forcingParameters(1)](int matrices) {
    primitives::DrDmpParameters p = parameters;
    p.matrices = matrices;
    return p;
  };
  model.demonstration = task.demonstrationTrajectory();
  model.step = task.demonstrationStep();
  model.terms = ScarfRolloutTask::names();
  model.success = "success";
  model.locks = {{"task.txt", settingsText(task.config())},
                 {"world.txt", "sim_config " + sim::SimConfig::worldDigest(task.config().sim_config) + "\nstart " +
                                   io::fileDigest({task.config().start}) + "\n"}};
  return model;
}

}  // namespace bimanual_skills::rollout
