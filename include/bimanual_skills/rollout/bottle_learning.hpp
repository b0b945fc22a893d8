/// \file
/// The bottle task on the simulated WAM (thesis Sec. 6.2, tasks/wam_bottles.hpp) as a rollout task and a learning
/// file for DmpLearner: the task's 2-DoF DMP of the line's x and y (10 kernels each) as a coordinated policy
/// (coordinated_parameters.hpp, one coordination matrix), learned by REPS and DREPS as the thesis compared them (and
/// any other DmpLearner algorithm of one matrix), with the reward (6.18) or (6.17) and what the simulation did in
/// every result. Target bimanual_skills_rollout. Offline: allocates and throws std::invalid_argument.
#pragma once

#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/tasks/wam_bottles.hpp"

#include <string>
#include <vector>

namespace bimanual_skills::rollout {

struct BottleLearningConfig {
  tasks::WamBottleConfig task;
  DmpLearningConfig learning;

  /// Reads a learning file (config/bottles_learning.yaml): `task` (a task file, tasks::WamBottleConfig's, relative to
  /// this file), `crossing_term` (instead of the task file's: true for 6.18, false for 6.17), `learning: {...}` (the
  /// keys every learner shares). Algorithms of more than one coordination matrix are refused (the task's DMP has
  /// one). \throws std::invalid_argument naming the file and the entry at fault.
  static BottleLearningConfig fromYamlFile(const std::string& path);
};

class BottleRolloutTask : public RolloutTask {
 public:
  /// \throws std::invalid_argument as tasks::WamBottleTask.
  explicit BottleRolloutTask(const tasks::WamBottleConfig& config);

  /// bottles_down, length, crossed, satisfactory, side_1, side_2 (the tool's offset to the left of the line at each
  /// bottle [m]), max_ik_error, max_tracking_error, max_height_error, simulated_seconds.
  std::vector<std::string> termNames() const override { return names(); }
  static std::vector<std::string> names();
  /// The straight line: one coordination matrix Ω = I and the task's fitted DMP weights.
  Eigen::VectorXd initialParameters() const override;
  /// The task's weights of an encoded policy: the rows of Ω W (x's kernels, then y's); false when `parameters`
  /// encode no policy of 2 DoF, 10 weights per latent DoF and one matrix.
  bool taskWeights(const Eigen::VectorXd& parameters, Eigen::VectorXd& theta) const;
  /// One rollout of the encoded policy (an InvalidPolicy rollout when it encodes none); the trajectory summary is the
  /// tool's measured path (3 × samples, world).
  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override;
  static RolloutResult resultOf(const tasks::WamBottleRollout& rollout);

  tasks::WamBottleTask& task() noexcept { return task_; }
  const tasks::WamBottleRollout& lastRollout() const noexcept { return last_; }

 private:
  tasks::WamBottleTask task_;
  tasks::WamBottleRollout last_;
};

/// What DmpLearner needs of the bottle task: 2 DoF, the DMP's kernels, the straight line's demonstration
/// (tasks::BottleTask::demonstration()), the term names ("satisfactory" the success) and the files a run directory is
/// locked to (the task's settings and the simulation's world digest).
DmpTaskModel bottleTaskModel(const tasks::WamBottleTask& task);

}  // namespace bimanual_skills::rollout
