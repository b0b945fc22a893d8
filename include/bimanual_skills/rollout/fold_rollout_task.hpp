/// \file
/// The cloth fold (tasks::ClothFoldTask scored by tasks::FoldReward) as a RolloutTask: one parameter vector holds a
/// whole coordinated policy, so that any evaluator (threads here, rollout workers elsewhere) can run it unchanged.
/// Target bimanual_skills_rollout.
#pragma once

#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"

#include <vector>

namespace bimanual_skills::rollout {

/// A task that runs the fold elsewhere (a robot through its interfaces) and keeps what its last rollout received:
/// the robot's joint and tool paths, its camera's images and, where the robot has one, the cloth's ground truth.
class RecordedFoldTask {
 public:
  virtual ~RecordedFoldTask() = default;
  /// The last rollout as received (tasks::FoldRollout's joint_path, actual_path, path_times, camera_*, cloth_*).
  virtual const tasks::FoldRollout& lastRecording() const = 0;
};

/// Its parameters: a coordinated policy of the fold's 12 DoF (encodeCoordinatedPolicy()).
class FoldRolloutTask : public RolloutTask {
 public:
  /// \throws std::invalid_argument as ClothFoldTask and FoldReward.
  FoldRolloutTask(const tasks::ClothFoldConfig& task, const tasks::FoldRewardConfig& reward);

  /// r_acceleration, r_color, r_depth, fill_ratio, mean_gradient, area_ratio, aspect, fold_quality, fold_distance,
  /// fold_displacement, r_goal, goal_iou, goal_mismatch, r_fold, fold_mismatch, fold_edge, fold_single,
  /// fold_length, fold_heap (tasks::FoldRewardTerms).
  std::vector<std::string> termNames() const override;
  static std::vector<std::string> names();
  static constexpr std::size_t kTerms = 19;
  /// The demonstration: one coordination matrix Ω = I, the demonstration's weights.
  Eigen::VectorXd initialParameters() const override;
  /// The terms of a result of run() (e.g. one that ran on a rollout worker); the vision status is not part of it.
  /// \throws std::invalid_argument for a result with other terms or an unknown outcome.
  static tasks::FoldRewardTerms termsOf(const RolloutResult& result);
  /// A result as run() gives it: the rollout's terms (their outcome and reward), its reason, and the tool paths
  /// (world, per arm) as its trajectory summary when every arm has the same number of samples.
  static RolloutResult resultOf(const tasks::FoldRewardTerms& terms, const std::string& reason,
                                const std::vector<Eigen::Matrix3Xd>& paths);
  /// The tool paths (world, per arm) of a result of run(): its trajectory summary, the arms' 3 rows each; none when
  /// it holds no such summary.
  static std::vector<Eigen::Matrix3Xd> toolPaths(const RolloutResult& result);
  /// One rollout of the encoded policy with the simulation's and the camera's noise seeded by `seed`; its trajectory
  /// summary holds the arms' actual tool paths, 3 rows per arm.
  RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override;
  /// Keeps a rollout that ran outside run() (tasks::ClothFoldTask's stepped rollouts) as the last one and scores it
  /// with the camera noise of `seed`, as run() does.
  RolloutResult record(tasks::FoldRollout rollout, std::uint32_t seed);

  tasks::ClothFoldTask& task() noexcept { return task_; }
  tasks::FoldReward& reward() noexcept { return reward_; }
  /// The last rollout, its terms (its images are reward().bgr() and depth()).
  const tasks::FoldRollout& lastRollout() const noexcept { return last_; }
  const tasks::FoldRewardTerms& lastTerms() const noexcept { return last_terms_; }
  /// Renders and scores `rollout` with the camera noise of `seed`, as run() does.
  tasks::FoldRewardTerms score(const tasks::FoldRollout& rollout, std::uint32_t seed);
  /// The camera's picture of rollout `seed`'s start (ClothFoldTask::clothStartVertices: the flat cloth where that
  /// rollout lays it) with camera noise of its own stream of `seed`: startBgr() and startDepth() until the next call.
  /// Same seed, same images.
  vision::VisionStatus renderStart(std::uint32_t seed);
  /// Colour (bgr8) and depth (32FC1, metres) of the last renderStart().
  const cv::Mat& startBgr() const noexcept { return start_renderer_.bgr(); }
  const cv::Mat& startDepth() const noexcept { return start_renderer_.depth(); }

 private:
  tasks::ClothFoldTask task_;
  tasks::FoldReward reward_;
  vision::ClothRenderer start_renderer_;
  tasks::FoldRollout last_;
  tasks::FoldRewardTerms last_terms_;
};

}  // namespace bimanual_skills::rollout
