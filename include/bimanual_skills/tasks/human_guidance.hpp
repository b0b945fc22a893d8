/// \file
/// Human-guided learning of the bottle task (thesis Sec. 6.2, Figs. 6.9 and 6.13; Appendix B.4) on the simulated WAM.
/// In the thesis a Kinect tracked a person while the robot moved along the straight line; the person raised a hand
/// and the robot followed the hand (10 Hz camera points) between the bottles, leaving the first bottle on the left,
/// until the hand was raised again and the robot went back to the nearest point of the line and on to the goal.
/// Twenty guided runs were time-aligned by gradient descent and combined by a reward-weighted average.
///
/// Here the person is scripted and seeded (ScriptedPerson: where along the line the hand takes and releases the
/// robot, the S's amplitude, the person's pace and its unevenness, a tremor and the camera's noise, each drawn from
/// the ranges of PersonConfig); guidedReference() is the robot's reference in the line's units (x along the line, y
/// to its left, in line lengths), and WamBottleTask::runPath() runs it on the arm. learnFromGuidance() runs a set of
/// guided runs, aligns their three parts (before the take, guided, after the release) with
/// learning::alignCurves(), averages them weighted by their rewards and fits the task's DMP (10 kernels per DoF) to
/// the average: the policy a user gets, run on the arm. Offline: allocates and throws std::invalid_argument.
/// Target bimanual_skills_tasks.
#pragma once

#include "bimanual_skills/learning/time_alignment.hpp"
#include "bimanual_skills/tasks/wam_bottles.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace bimanual_skills::tasks {

/// The ranges a scripted person's guidance is drawn from (uniform), in line lengths and seconds.
struct PersonConfig {
  double take_min = 0.08, take_max = 0.18;           ///< Along the line where the hand goes up.
  double release_min = 0.82, release_max = 0.92;     ///< Along the line where the hand lets go.
  double amplitude_min = 0.12, amplitude_max = 0.2;  ///< Of the S, y = −A sin(2π (x − take)/(release − take)).
  double guided_min = 2.4, guided_max = 3.2;         ///< The person's time from take to release [s].
  double pace_unevenness = 0.3;   ///< |b| at most of the person's pace σ + b sin(2πσ)/(2π) (b < 1: monotone).
  double tremor = 0.003;          ///< Amplitude of the hand's tremor [m].
  double tremor_frequency = 6.0;  ///< [Hz]
  double camera_rate = 10.0;      ///< Hand points per second.
  double camera_noise = 0.005;    ///< Standard deviation of each point's error per axis [m].
  /// \throws std::invalid_argument naming the entry out of range.
  void validate() const;
};

/// A hand point the camera saw, in the line's units, at a time from the take [s].
struct HandPoint {
  double time = 0.0;
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
};

/// One person's guidance, drawn from a seed.
class ScriptedPerson {
 public:
  /// \throws std::invalid_argument for a bad config or a line length that is not positive.
  ScriptedPerson(const PersonConfig& config, double line_length, std::uint32_t seed);

  double take() const noexcept { return take_; }
  double release() const noexcept { return release_; }
  double amplitude() const noexcept { return amplitude_; }
  double guidedSeconds() const noexcept { return guided_; }
  /// The hand's intended point (no tremor, no camera) t seconds after the take; before 0 the take point, after
  /// guidedSeconds() the release point.
  Eigen::Vector2d intended(double t) const noexcept;
  /// What the camera gives while the hand guides: a point every 1/camera_rate from the take to the release, with the
  /// tremor and the camera's noise.
  const std::vector<HandPoint>& cameraPoints() const noexcept { return points_; }

 private:
  PersonConfig config_;
  double length_ = 0.0, take_ = 0.0, release_ = 0.0, amplitude_ = 0.0, guided_ = 0.0, pace_ = 0.0;
  double tremor_phase_x_ = 0.0, tremor_phase_y_ = 0.0;
  std::vector<HandPoint> points_;
};

/// How the robot's reference moves.
struct GuidanceConfig {
  double line_speed = 0.25;   ///< Along the line outside the guidance [line lengths/s] (the DMP's 1/duration).
  double lag = 0.15;          ///< Time constant of the critically damped follower of the hand or the line [s].
  double max_speed = 0.6;     ///< [line lengths/s]
  double max_seconds = 20.0;  ///< A reference that has not reached the goal by then is an error.
  /// \throws std::invalid_argument naming the entry out of range.
  void validate() const;
};

/// The robot's side of the guidance, one step at a time (offline in guidedReference(), online where a camera sees a
/// hand): a target moves along the line at line_speed; while the hand is raised (the gesture) the target is the
/// hand's latest point; once it is lowered the target goes back to the line at the reference's x and on along it to
/// the goal (one guidance per run: a hand raised again is not followed). The reference follows its target as a
/// critically damped second-order system of time constant `lag`, its speed capped at max_speed. Real-time safe.
class GuidanceFollower {
 public:
  enum class Phase { Line, Guided, Back, Arrived };

  /// \throws std::invalid_argument for a bad config.
  explicit GuidanceFollower(const GuidanceConfig& config);
  /// Back to the line's start at rest.
  void reset() noexcept;
  /// Advances by dt [s] (> 0): `raised` whether the hand is up, `hand` its latest point (line units; read only
  /// while following it). Arrived: at rest on the goal (the reference is the goal from then on), guided or not.
  Phase step(double dt, bool raised, const Eigen::Vector2d& hand) noexcept;

  Phase phase() const noexcept { return phase_; }
  const Eigen::Vector2d& position() const noexcept { return x_; }  ///< The reference [line lengths].
  const Eigen::Vector2d& velocity() const noexcept { return v_; }  ///< [line lengths/s]
  const Eigen::Vector2d& target() const noexcept { return target_; }

 private:
  GuidanceConfig config_;
  Phase phase_ = Phase::Line;
  Eigen::Vector2d x_ = Eigen::Vector2d::Zero(), v_ = Eigen::Vector2d::Zero(), target_ = Eigen::Vector2d::Zero();
  double line_x_ = 0.0;
};

/// The robot's reference at the simulation's step from the motion's start, starting at (0, 0) and ending at rest at
/// the goal (1, 0); `take` and `release` the samples where the hand took and let go.
struct GuidedReference {
  Eigen::Matrix2Xd path;
  int take = 0, release = 0;
};

/// The reference of a GuidanceFollower guided by the person: the hand goes up when the follower's line target reaches
/// the person's take and stays up for its guided seconds, the camera's latest point (held between points; the camera
/// registered to the line) the hand. \throws std::invalid_argument for bad configs, a step that is not positive, or
/// a reference that does not reach the goal within max_seconds.
GuidedReference guidedReference(const ScriptedPerson& person, const GuidanceConfig& config, double step);

struct GuidedLearningConfig {
  PersonConfig person;
  GuidanceConfig guidance;
  int runs = 20;                             ///< Guided runs per set (the thesis: 20).
  double h = 10.0;                           ///< Of the reward-weighted average (learning::rewardWeights).
  learning::TimeAlignmentOptions alignment;  ///< samples: of each of the three parts.
  /// \throws std::invalid_argument naming the entry out of range.
  void validate() const;
};

/// One guided run: the reference, the rollout on the arm and the measured tool in the line's units, split into its
/// three parts at the take and the release (each part's first sample the previous part's last).
struct GuidedRun {
  std::uint32_t seed = 0;
  ScriptedPerson person;
  GuidedReference reference;
  WamBottleRollout rollout;
  std::array<Eigen::MatrixXd, 3> parts;  ///< Rows: samples (the rollout's path rate), columns: x, y [line lengths].
  std::array<double, 3> seconds{};       ///< Each part's duration.
};

/// A measured tool path (world, with its times [s] from the motion's start) split at the take and the release [s]
/// and the motion's end into its three parts in the line's units (each part's first sample the previous part's last;
/// `seconds` gets each part's duration). \throws std::invalid_argument when a part has fewer than two samples or the
/// sizes differ.
std::array<Eigen::MatrixXd, 3> splitGuidedPath(const WamBottleTask& task, const Eigen::Matrix3Xd& tool,
                                               const Eigen::VectorXd& times, double take, double release, double end,
                                               std::array<double, 3>& seconds);

/// What guided runs teach: their parts aligned, the reward-weighted average and the DMP fitted to it.
struct GuidedAverage {
  std::array<learning::TimeAlignment, 3> alignment;  ///< Of each part over the runs.
  Eigen::VectorXd weights;                           ///< Of the runs, in their order.
  Eigen::MatrixXd average;        ///< The reward-weighted average path (rows: the three parts' samples, x, y).
  Eigen::VectorXd average_times;  ///< [s] of its rows (each part its weighted mean duration).
  Eigen::VectorXd theta;          ///< The task's DMP fitted to the average: the learned policy.
};

/// Aligns each part over the runs (learning::alignCurves), averages them with learning::rewardWeights(rewards, h) in
/// their weighted mean durations, and fits the task's DMP (`kernels` per DoF over BottleTask::demonstration()'s 101
/// samples) to the average. \throws std::invalid_argument for fewer than two runs, sizes that differ or a bad config.
GuidedAverage averageGuidedRuns(const std::vector<std::array<Eigen::MatrixXd, 3>>& parts,
                                const std::vector<std::array<double, 3>>& seconds, const std::vector<double>& rewards,
                                const GuidedLearningConfig& config, int kernels);

struct GuidedLearning : GuidedAverage {
  std::vector<GuidedRun> runs;
  WamBottleRollout policy;                 ///< theta run on the arm (seed 0, as the REPS study's final policies).
  int ok_runs = 0, satisfactory_runs = 0;  ///< Of the guided runs.
};

/// A set of config.runs guided runs (person seeds seed, seed + 1, …; rollout seeds the same), aligned and averaged,
/// the DMP fitted and run. Guided runs that failed on the arm are reported and left out of the average (an error if
/// fewer than two ran). \throws std::invalid_argument for a bad config.
GuidedLearning learnFromGuidance(WamBottleTask& task, const GuidedLearningConfig& config, std::uint32_t seed);

}  // namespace bimanual_skills::tasks
