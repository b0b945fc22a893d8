/// \file
/// Learning to fold the cloth (thesis Sec. 7.2.3, Table 7.5): policy search with reward-oriented dimensionality
/// reduction over the 12-DoF coordinated DMP of both tools, each rollout executed on the simulated pair of WAMs
/// (tasks::ClothFoldTask) and scored on the rendered cloth by (7.52) or the goal-image reward (tasks::FoldReward).
///
/// Protocol of one run of one algorithm: the DR-DMP is fitted to the scripted demonstration (PCA coordination,
/// 7.26–7.27; r = 12 for IDR and the standard DMP); the latent weights start at the fit with an isotropic
/// covariance; each epoch e = 0 … updates draws `rollouts` latent weight vectors, evaluates them in parallel, and
/// (e < updates) updates the policy with REPS (reusing the previous epoch's rollouts) and, for the CMU variants, the
/// coordination matrices (Alg. 7.2, η for IDR). Each epoch also executes the mean policy without exploration (what
/// the learning would hand a user at that point; the updates do not use it).
///
/// The demonstration's DMPs are written as DIR/demonstration_left.yaml and demonstration_right.yaml (DMP files; a
/// learning file's `task: {demonstration: [left.yaml, right.yaml]}` starts from them instead of the scripted fold).
/// Nothing is lost: every finished rollout is appended at once to DIR/rollouts.csv (terms, outcome, reason) and
/// DIR/rollout_parameters.csv (its latent weights). The learning is deterministic for a seed, so a restarted run
/// regenerates the same rollouts and takes those already on disk instead of simulating them again (after checking
/// that their parameters are the same to the last bit). Results do not depend on the number of threads. Robot faults
/// stay out of the learning (FoldLearningConfig::robot_retries): a rollout is learned from only once the robot ran it.
/// Target bimanual_skills_rollout (rollout floor). Offline: allocates and throws std::invalid_argument.
#pragma once

#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

struct FoldLearningConfig {
  tasks::ClothFoldConfig task;
  /// Its renderer's camera and table follow the task's simulation file. The "fold" setting unless a file says
  /// otherwise.
  tasks::FoldRewardConfig reward = tasks::rewardSetting({}, "fold", "fold learning");
  std::vector<std::string> algorithms = {"IDR-DMP_CMU"};
  int runs = 1;
  int updates = 8;
  int rollouts = 12;            ///< Per epoch.
  int reuse = 12;               ///< Rollouts of the previous epochs reused by REPS.
  double epsilon = 0.5;         ///< REPS KL bound.
  double eta = 50.0;            ///< IDR: σ_1/σ_r beyond which the last latent DoF is dropped.
  double initial_stddev = 5.0;  ///< Of each latent kernel weight at the start.
  /// Of each latent goal weight at the start, as the goal displacement it makes [m] (tasks::FoldPolicy
  /// WeightsAndGoals; Ω is orthonormal, so each DoF's goal moves with this deviation too).
  double goal_stddev = 0.03;
  double covariance_memory = 0.0;  ///< λ of CoordinatedRepsParameters in [0, 1) (0: the thesis' REPS update).
  int repetitions = 0;             ///< Noise-free repetitions of the initial policy (varying only the sensors' noise).
  /// A rollout the robot failed (tasks::FoldOutcome::RobotFailed: a service, an action or the camera failed or did
  /// not answer) says nothing of its policy: it is run again with the same parameters and seed up to this many
  /// times, logged to DIR/robot_faults.csv and never written as a rollout; one that fails once more stops the
  /// learning with the reason.
  int robot_retries = 3;
  /// The learning also stops after this many robot failures in a row (a robot that is down).
  int robot_fault_limit = 5;
  std::uint32_t seed = 1;
  int jobs = 0;  ///< Rollouts evaluated in parallel (0: the hardware's threads).

  /// Reads a learning file (config/fold_demo.yaml); relative paths are relative to its directory. Entries absent
  /// keep their defaults. \throws std::invalid_argument naming the file and the entry at fault.
  static FoldLearningConfig fromYamlFile(const std::string& path);
  /// \throws std::invalid_argument for out-of-range values or unknown algorithms.
  void validate() const;
};

/// `config` with the reward's renderer (camera, table) set from the task's simulation file, its noise kept.
/// \throws std::invalid_argument for an unreadable simulation file.
FoldLearningConfig withSimulationRenderer(FoldLearningConfig config);

/// The exploration's starting standard deviation of each latent weight of `task`'s policy with Ω = I, in
/// encodeCoordinatedPolicy()'s order (DoF by DoF: the kernels' `config.initial_stddev`, then, with goals, the goal
/// weight's α_z β_z `config.goal_stddev`, the forcing that moves the goal by goal_stddev).
Eigen::VectorXd latentWeightStddev(const FoldLearningConfig& config, const tasks::ClothFoldTask& task);

/// One finished rollout, as written to DIR/rollouts.csv.
struct FoldRolloutRecord {
  std::string algorithm;
  int run = 0, epoch = 0, index = 0;
  RolloutKind kind = RolloutKind::Sample;
  std::uint32_t seed = 0;  ///< The simulation's sensor noise and the camera's.
  tasks::FoldRewardTerms terms;
  std::string reason;  ///< Why it failed; empty when Ok.
  double wall_seconds = 0.0;
  bool resumed = false;                       ///< Read from the run directory rather than simulated.
  std::vector<Eigen::MatrixXd> coordination;  ///< Ω_s of the policy it was drawn from.
  Eigen::VectorXd weights;                    ///< Its latent weights ω.
};

/// The rollouts of one epoch of one run.
struct FoldEpochStats {
  std::string algorithm;
  int run = 0, epoch = 0;
  int latent_dims = 0;  ///< r of the policy the epoch's rollouts were drawn from.
  int failures = 0;
  double mean_reward = 0.0, std_reward = 0.0;
  /// Means over the epoch's rollouts, failed ones included (with what their cloth showed).
  double r_acceleration = 0.0, r_color = 0.0, r_depth = 0.0, fill_ratio = 0.0, mean_gradient = 0.0, area_ratio = 0.0;
  double r_goal = 0.0, goal_mismatch = 0.0, r_fold = 0.0, fold_mismatch = 0.0;
  /// The fold's ground truth q (tasks/fold_quality.hpp): mean and sample standard deviation over the same rollouts.
  double fold_quality = 0.0, fold_quality_std = 0.0;
  /// The noise-free mean policy the epoch's rollouts were drawn around: its reward and q, and whether it failed.
  double policy_reward = 0.0, policy_fold_quality = 0.0;
  bool policy_failed = false;
};

struct FoldRunResult {
  std::string algorithm;
  int run = 0;
  std::vector<FoldEpochStats> epochs;
  FoldRolloutRecord initial_policy, final_policy;
  FoldRolloutRecord best;  ///< The best rollout of the run (any kind).
  learning::CoordinatedPolicy final;
  double seconds = 0.0;
};

struct FoldLearningResult {
  std::vector<FoldRunResult> runs;
  std::vector<FoldRolloutRecord> repetitions;
  int simulated = 0, resumed = 0;  ///< Rollouts simulated now and taken from disk.
  int robot_faults = 0;            ///< Attempts the robot failed (run again; not among the rollouts).
  double seconds = 0.0;
};

/// Hooks for a user interface (a ROS node, a console). Called from one thread at a time, in completion order.
struct FoldLearningObserver {
  /// A rollout finished. One that ran on a rollout worker has only its actual tool paths in `rollout` (no mesh, no
  /// images in `reward`); one on a robot (a RecordedFoldTask) what the robot sent (its camera's images in
  /// `rollout.camera_*`, not in `reward`); one read from disk has neither.
  std::function<void(const FoldRolloutRecord& record, const tasks::FoldRollout& rollout,
                     const tasks::FoldReward& reward)>
      rollout;
  std::function<void(const FoldEpochStats&)> epoch;
  /// The robot failed attempt `attempt` (1 = the first) of a rollout, for `reason`; `retry` whether it runs again.
  std::function<void(const FoldRolloutRecord& record, int attempt, const std::string& reason, bool retry)> robot_fault;
  /// Polled between rollouts: true stops the learning (learn() then throws std::runtime_error("stopped")); what
  /// finished is on disk.
  std::function<bool()> stop;
};

class FoldLearner {
 public:
  /// Builds the workers (one simulation, controllers and renderer per thread) and opens `out_dir` (created if
  /// missing), reading the rollouts already there. With an `evaluator` (e.g. a Dispatcher to rollout workers
  /// running the task "fold" of this configuration) the rollouts run there instead, with the same results, and
  /// config.jobs is not used. \throws std::invalid_argument for a bad configuration or an unwritable directory.
  FoldLearner(const FoldLearningConfig& config, const std::string& out_dir, FoldLearningObserver observer = {},
              std::unique_ptr<Evaluator> evaluator = nullptr);
  ~FoldLearner();
  FoldLearner(const FoldLearner&) = delete;
  FoldLearner& operator=(const FoldLearner&) = delete;

  /// Runs every algorithm and run of the configuration. \throws std::invalid_argument when the directory holds
  /// rollouts of another configuration or seed; RobotFaults when the robot failed a rollout robot_retries + 1 times
  /// or robot_fault_limit rollouts in a row (what finished is on disk: a run after the robot is fixed resumes).
  FoldLearningResult learn();

  /// Executes a recorded rollout again with paths and cloth meshes recorded at `cloth_rate` frames per second:
  /// the same result (same policy, same seed), for replays.
  tasks::FoldRollout replay(const FoldRolloutRecord& record, double cloth_rate);

  /// Renders and scores a rollout as the learning does (same seed, same images).
  tasks::FoldRewardTerms score(const tasks::FoldRollout& rollout, std::uint32_t seed, cv::Mat& bgr, cv::Mat& depth);

  /// The configuration in use: the renderer set from the simulation file, jobs resolved.
  const FoldLearningConfig& config() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::rollout
