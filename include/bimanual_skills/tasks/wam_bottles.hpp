/// \file
/// The bottle task of thesis Sec. 6.2 (Figs. 6.8–6.12) on the simulated WAM: the tool moves at a fixed height and
/// orientation (the one of the robot file's start posture: pointing down) from a start to a goal, two bottles (free
/// rigid bodies that tip, sim/obstacle.hpp) standing on the straight line between them. The policy is the planar task's
/// DMP (BottleTask::initialPolicy(): 10 kernels for each of x and y, 20 weights, fitted to the straight line) in the
/// line's units: x along the line (0 at the start, 1 at the goal), y to its left, both times the line's length. Its
/// path over `duration`, solved by CLIK (the thesis' scheme, CTP with SVF and selective damping) for the arm's joint
/// references, is tracked by the computed-torque controller with friction compensation (the robot path's ArmController,
/// in_process_control.hpp); the other arm holds its start.
///
/// The reward counts what the simulation did (thesis 6.17, 6.18): R = −2 N_down − 0.15 L − 4 I_cross, N_down the
/// bottles tilted past `tilt` when the rollout ends, L the length of the tool's measured path [m] (from the motion's
/// start to the rollout's end),
/// I_cross = 1 unless the tool passes the two bottles on opposite sides of the line (the side of the line where the
/// tool is when it first passes a bottle's place along it); (6.17) without the crossing term. Target
/// bimanual_skills_tasks. Offline: allocates and throws std::invalid_argument.
#pragma once

#include "bimanual_skills/tasks/cloth_fold.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::tasks {

struct WamBottleConfig {
  /// A simulation file whose free obstacles (those with a mass) are the two bottles (config/bottles_sim.yaml).
  std::string sim_config;
  std::string arm = "right";  ///< The arm that moves; the others hold their start.
  /// The line's ends [m, world]: the same height, which the tool keeps.
  Eigen::Vector3d start = Eigen::Vector3d(0.55, -0.65, 0.32);
  Eigen::Vector3d goal = Eigen::Vector3d(0.55, -0.05, 0.32);
  double duration = 4.0;     ///< Of the motion [s].
  double hold_before = 0.1;  ///< The arm holds its start before the motion [s].
  /// After `duration` the DMP converges on to the goal while a pushed bottle falls or stands up again [s].
  double settle = 0.5;
  bool crossing_term = true;         ///< (6.18); false: (6.17).
  double tilt = 0.7853981633974483;  ///< A bottle tilted beyond this is down [rad] (45°).
  double max_ik_error = 0.05;        ///< The planned tool farther than this from the DMP's path: IkFailed [m].
  double max_tracking_error = 0.3;   ///< Joint tracking error beyond which the rollout fails [rad].
  /// The controllers' velocity monitor [rad/s] on every joint; <= 0: the robot's velocity limits.
  double velocity_limit = 0.0;
  double failure_reward = -10.0;  ///< Of a rollout that failed (below any reward of one that ran: −8.x).
  double path_rate = 100.0;       ///< Samples per second of the recorded tool path.

  /// \throws std::invalid_argument naming the entry out of range.
  void validate() const;
  /// Reads a task file (config/bottles_wam.yaml): `sim_config` (relative to the file), `arm`, `start`, `goal`,
  /// `duration`, `hold_before`, `settle`, `crossing_term`, `tilt_deg`, `max_ik_error`, `max_tracking_error`,
  /// `velocity_limit`, `failure_reward`, `path_rate`. \throws std::invalid_argument naming the file and entry.
  static WamBottleConfig fromYamlFile(const std::string& path);
  /// Every entry as fromYamlFile() reads it (sim_config as it is: absolute for a file read anywhere).
  std::string toYaml() const;
};

struct WamBottleRollout {
  FoldOutcome outcome = FoldOutcome::Ok;
  std::string reason;
  double reward = 0.0;
  int down = 0;                     ///< Bottles knocked over (N_down).
  double length = 0.0;              ///< Of the tool's measured path [m].
  bool crossed = false;             ///< Passed the two bottles on opposite sides of the line.
  bool satisfactory = false;        ///< Crossed with no bottle down (the thesis' right-most solutions of Fig. 6.11).
  std::array<double, 2> sides{};    ///< The tool's offset to the left of the line where it passes each bottle [m].
  double max_ik_error = 0.0;        ///< Of the plan: the tool against the DMP's path [m].
  double max_tracking_error = 0.0;  ///< [rad]
  double max_height_error = 0.0;    ///< The measured tool's largest |z − z_line| over the motion [m].
  Eigen::Matrix3Xd tool_path;       ///< The measured tool (world), from the motion's start to the rollout's end.
  Eigen::Matrix3Xd planned_path;    ///< The DMP's path there (world).
  Eigen::VectorXd path_times;       ///< [s] from the motion's start.
  Eigen::MatrixXd joint_path;       ///< The moving arm's measured joints at the path's samples (joints × samples).
  /// Where the bottles were at the path's samples (2 per sample, bottle_path[2 i + k] bottle k's at sample i).
  std::vector<Eigen::Isometry3d> bottle_path;
  std::array<Eigen::Isometry3d, 2> bottles;  ///< Where the bottles ended.
  double simulated_seconds = 0.0, wall_seconds = 0.0;
};

/// The task. Construction reads the simulation, finds the bottles on the line, and solves the start posture by CLIK
/// from the robot file's start (so that the arm keeps its elbow and wrist: global IK's posture nearest the middle
/// of the joint ranges puts the wrist next to its singularity, q6 = 0, through which the S drives it); run() starts
/// every rollout from a new simulation (the rollout's seed its sensor noise), so that a rollout gives the same result
/// whatever ran before it. One object per thread.
class WamBottleTask {
 public:
  explicit WamBottleTask(const WamBottleConfig& config);
  ~WamBottleTask();
  WamBottleTask(const WamBottleTask&) = delete;
  WamBottleTask& operator=(const WamBottleTask&) = delete;

  const WamBottleConfig& config() const noexcept;
  /// The DMP's weights fitted to the straight line (x's 10 kernels, then y's).
  Eigen::VectorXd initialParameters() const;
  /// Kernels per DoF of the DMP (10).
  int kernels() const noexcept;
  /// The index of the moving arm, every arm's joint names and start posture (the moving arm's at the line's start).
  int arm() const noexcept;
  const std::vector<std::vector<std::string>>& jointNames() const noexcept;
  std::vector<Eigen::VectorXd> starts() const;
  /// The simulation the rollouts run in (the file's, its obstacles at their start).
  const sim::SimConfig& simConfig() const noexcept;
  /// Where bottle k stands on the line: along it (0 start, 1 goal) and to its left [line lengths].
  Eigen::Vector2d bottleOnLine(int k) const;
  double lineLength() const noexcept;
  /// The bottles' radius [m] (the first one's).
  double bottleRadius() const noexcept;
  /// A world point in the line's units (x along, y to the left, in line lengths) and back.
  Eigen::Vector2d toLine(const Eigen::Vector3d& world) const;
  Eigen::Vector3d fromLine(const Eigen::Vector2d& line) const;
  /// The rollout of the DMP with weights θ; a wrong size or a non-finite θ is an InvalidPolicy rollout.
  WamBottleRollout run(const Eigen::VectorXd& theta, std::uint32_t seed);
  /// The rollout of a tool path in the line's units (2 × samples at the simulation's step from the motion's start,
  /// starting at (0, 0); the arm holds its start for hold_before first), as run() runs its DMP's path: the human-guided
  /// runs' references. A path of fewer than two finite points or starting elsewhere is an InvalidPolicy rollout.
  WamBottleRollout runPath(const Eigen::Matrix2Xd& path, std::uint32_t seed);
  /// (6.17) or (6.18) of a measured tool path (out.tool_path, world) with `down` bottles knocked over: sets out's
  /// length, max_height_error, sides, down, crossed, satisfactory and reward, as run() does for its rollouts (a run
  /// recorded elsewhere, e.g. guided over ROS, is scored the same way).
  void score(WamBottleRollout& out, int down) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::tasks
