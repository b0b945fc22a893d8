/// \file
/// The scarf-placing experiment (thesis Sec. 4.3.1) as a rollout task and a learning file: tasks::ScarfTask whose
/// parameters are a coordinated policy of its arm's joints (coordinated_parameters.hpp), its cost's terms and the
/// ground truth in every result, learned by DmpLearner (PI2-CMA on a second layer of Gaussians as the thesis ran it,
/// REPS and IDR-DMP beside it). Target bimanual_skills_rollout. Offline: allocates and throws std::invalid_argument.
#pragma once

#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/tasks/scarf_task.hpp"

#include <string>
#include <vector>

namespace bimanual_skills::rollout {

struct ScarfLearningConfig {
  tasks::ScarfTaskConfig task;
  DmpLearningConfig learning;

  /// Reads a learning file (config/scarf_learning.yaml): `sim`, `start`, `task: {...}`, `camera: {...}`,
  /// `learning: {...}`; relative paths are relative to the file. Entries absent keep their defaults.
  /// \throws std::invalid_argument naming the file and the entry at fault.
  static ScarfLearningConfig fromYamlFile(const std::string& path);
};

/// A scarf task that keeps its last rollout (in this process's simulation, or as a robot's interfaces gave it).
class RecordedScarfTask {
 public:
  virtual ~RecordedScarfTask() = default;
  virtual const tasks::ScarfRollout& lastRollout() const = 0;
};

class ScarfRolloutTask : public RolloutTask, public RecordedScarfTask {
 public:
  /// \throws std::invalid_argument as ScarfTask.
  explicit ScarfRolloutTask(const tasks::ScarfTaskConfig& config);

  /// cost, c_acceleration, c_cam, c_torque, acceleration, mean_abs_torque, peak_abs_torque, mean_tool_force,
  /// peak_tool_force, mean_force_error, max_force_error, max_tracking_error, d, hanging, right_pixels, left_pixels (the
  /// camera's), winding, wrapped, hanging_right, hanging_left, fallen, success (the scarf mesh's truth),
  /// simulated_seconds.
  std::vector<std::string> termNames() const override { return names(); }
  static std::vector<std::string> names();
  /// The demonstration: one coordination matrix Ω = I and its standard DMP's weights.
  Eigen::VectorXd initialParameters() const override;
  /// One rollout of the encoded policy, the reward −cost; its trajectory summary is the tool's path (3 × samples).
  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override;
  /// A rollout's result: ok, outcome, reason, reward −cost, its terms in names()'s order, the tool's path.
  static RolloutResult resultOf(const tasks::ScarfRollout& rollout);

  tasks::ScarfTask& task() noexcept { return task_; }
  const tasks::ScarfRollout& lastRollout() const override { return last_; }

 private:
  tasks::ScarfTask task_;
  tasks::ScarfRollout last_;
};

/// What DmpLearner needs of the scarf task: its DoF, DMP, demonstration, term names ("success" the truth), and the
/// files a run directory is locked to (the task's settings and the simulation's world digest).
DmpTaskModel scarfTaskModel(const tasks::ScarfTask& task);

}  // namespace bimanual_skills::rollout
