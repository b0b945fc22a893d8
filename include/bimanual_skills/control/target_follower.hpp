/// \file
/// The tool follows a tracked object and grasps it (thesis Sec. 4.3.2, Fig. 4.10: the tracked target through CLIK
/// into the compliant computed-torque controller). Every update (≥ 100 Hz): the target's estimate is predicted to
/// now with its velocity; the tool's goal is the object's grasp point plus a pre-grasp offset, with an orientation
/// fixed at the start (pointing down, with the yaw the tool had: keep_yaw); a few CLIK steps (Sec. 3.1.5, the thesis'
/// joint-limit-aware scheme) from the last joint goal give the joints' goal q*; the joint reference moves towards it, v
/// = v_ff + (q* − q_r)/τ with v_ff the rate of change of q* (the target's motion through the arm), its velocity and
/// acceleration limited per joint and its positions kept inside the limits; and it is handed to the computed-torque
/// controller as a short trajectory segment (Waypoints). It holds, stopping at its acceleration limit, when the target
/// is not tracked, when its estimate is older than max_age, or when it jumps (an estimate farther than `jump` from
/// where the last one predicted it: it settles for `settle` before following again), and says why. Once it has followed
/// without a hold for track_time, the target moves slower than grasp_speed and the tool is within follow_tolerance of
/// its goal, the offset shrinks at approach_speed towards the grasp point, and grows back while the target moves faster
/// than twice grasp_speed (slow spells add up; the track goes on); the speed is the low-pass filtered one of the
/// measured estimates, and on the approach the grasp point their filtered position; at the grasp point, within
/// grasp_tolerance, it asks for the gripper to close (graspRequested) and waits for the answer (graspDone): held, it
/// stays there; refused, it backs off to the pre-grasp point and tries again. Construction allocates; everything else
/// is real-time safe.
#pragma once

#include "bimanual_skills/control/joint_trajectory.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/clik.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <limits>

namespace bimanual_skills::control {

/// The tracked object's estimate as the tracker gives it (world frame).
struct FollowTarget {
  double stamp = std::numeric_limits<double>::quiet_NaN();  ///< The estimate's time (its camera frame's stamp) [s].
  bool tracking = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< Its centre [m].
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< [m/s].
  /// The stamp of the last frame whose measurement the estimate took in (TrackedObject::last_accepted): an estimate
  /// with an older one is a prediction (the object not seen, e.g. hidden by the hand). NaN: every estimate is measured.
  double measured = std::numeric_limits<double>::quiet_NaN();
};

struct TargetFollowerConfig {
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();  ///< The arm's base in the world.
  /// The tool's orientation in the world while it follows (default: pointing down, z of the tool along −z).
  Eigen::Matrix3d tool_orientation = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  /// true: the tool keeps the yaw (its turn about the world's vertical) it has when following starts, with
  /// tool_orientation's tilt: a round object leaves the yaw free, and a yaw fixed in the world can ask the wrist for
  /// half a turn, reached either way round (the WAM's start tool is yawed π from the default: the arm took one way
  /// or the other on a rounding, the other one into joint 7's limit). false: tool_orientation as it is.
  bool keep_yaw = true;
  Eigen::Vector3d grasp_offset = Eigen::Vector3d::Zero();      ///< Object centre → grasp point (world axes) [m].
  Eigen::Vector3d pregrasp = Eigen::Vector3d(0.0, 0.0, 0.10);  ///< Grasp point → where the tool follows [m].
  double period = 0.008;                                       ///< [s] between updates (125 Hz).
  double time_constant = 0.1;          ///< τ of the reference's pull towards the joints' goal [s].
  Eigen::VectorXd velocity_limit;      ///< [rad/s] per joint; empty: half the model's limits.
  Eigen::VectorXd acceleration_limit;  ///< [rad/s²] per joint; empty: 4 rad/s² each.
  double limit_margin = 0.05;          ///< The reference keeps this far inside the position limits [rad].
  double max_age = 0.25;               ///< An estimate older than this holds [s].
  double jump = 0.05;                  ///< [m] between an estimate and the last one's prediction: a jump.
  double settle = 0.5;                 ///< [s] held after a jump before following the new place.
  double track_time = 2.0;             ///< [s] followed without a hold before approaching.
  double grasp_speed = 0.03;           ///< [m/s] the target must be slower than to approach.
  double follow_tolerance = 0.02;      ///< [m] the tool within this of the pre-grasp point to approach.
  double approach_speed = 0.05;        ///< [m/s] of the offset's change on the approach (and back).
  /// τ [s] of the low-pass filters on the measured estimates (predictions are left out): the approach is gated on the
  /// filtered velocity's norm, and on the approach and the grasp the grasp point is the filtered position, not
  /// extrapolated, so that an estimate's noise (a depth camera's jitter) neither switches the approach on and off nor
  /// moves the tool, and an object hidden by the hand leaves the grasp point where it was last seen.
  double speed_time_constant = 0.3;
  double position_time_constant = 0.1;
  double grasp_tolerance = 0.01;    ///< [m] the tool within this of the grasp point: close the gripper.
  int clik_iterations = 3;          ///< CLIK steps per update.
  kinematics::ClikParameters clik;  ///< The thesis' defaults (CTP with SVF and selective damping).

  /// \throws std::invalid_argument naming the entry out of range (sizes checked against `joints` when > 0).
  void validate(int joints) const;
};

enum class FollowPhase {
  Idle,           ///< Not started.
  Following,      ///< The tool follows the pre-grasp point.
  Holding,        ///< Stopped: see HoldReason.
  Approaching,    ///< The offset shrinks to the grasp point (or grows back when conditions fail).
  Closing,        ///< At the grasp point, the gripper asked to close; waiting for graspDone().
  HoldingObject,  ///< The gripper holds it: the tool stays where it closed.
};
const char* toString(FollowPhase phase) noexcept;

enum class HoldReason {
  None,
  NoTarget,  ///< Not tracked (never seen, lost, or a stopped camera).
  Stale,     ///< The estimate is older than max_age.
  Jumped,    ///< The estimate jumped; settling.
  Invalid,   ///< A non-finite estimate or measured state.
};
const char* toString(HoldReason reason) noexcept;

class TargetFollower {
 public:
  /// \throws std::invalid_argument for an invalid config or model.
  TargetFollower(const kinematics::ChainModel& model, const TargetFollowerConfig& config);

  /// Starts from the controller's desired state (q, q̇) at t: Following (or holding until a target comes); with
  /// `grasp` false it follows only, never approaching.
  void start(double t, const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
             bool grasp = true) noexcept;
  /// One update at time t with the latest estimate and the measured joint positions: moves the reference and
  /// writes waypoints(): the reference's motion five periods ahead at its last acceleration (at a constant velocity
  /// to a position limit that cuts it), from the state reference(), segmentVelocity(), segmentAcceleration(), which
  /// the controller starts it from (ArmController::setTrajectoryFrom); the next update replaces it. False (nothing
  /// written) when idle or for inputs of the wrong size.
  bool update(double t, const FollowTarget& target, const Eigen::Ref<const Eigen::VectorXd>& q_measured) noexcept;
  /// The gripper's answer to graspRequested(): true, it holds the object; false, it did not.
  void graspDone(bool held) noexcept;
  void stop() noexcept { phase_ = FollowPhase::Idle; }

  const Waypoints& waypoints() const noexcept { return waypoints_; }
  FollowPhase phase() const noexcept { return phase_; }
  HoldReason holdReason() const noexcept { return reason_; }
  /// Whether the gripper should close now (set on entering Closing, until graspDone()).
  bool graspRequested() const noexcept { return phase_ == FollowPhase::Closing && !grasp_answered_; }
  /// The tool's goal (world) of the last update, and the measured tool's distance to it [m].
  const Eigen::Vector3d& toolGoal() const noexcept { return goal_; }
  double toolError() const noexcept { return tool_error_; }
  /// The measured tool position (world) at the last update.
  const Eigen::Vector3d& toolPosition() const noexcept { return tool_; }
  /// The stamp of the estimate the last update used (NaN before any).
  double targetStamp() const noexcept { return used_stamp_; }
  /// The share of the pre-grasp offset the goal has (1 following, 0 at the grasp point).
  double offset() const noexcept { return offset_; }
  const Eigen::VectorXd& reference() const noexcept { return q_r_; }
  const Eigen::VectorXd& referenceVelocity() const noexcept { return v_r_; }
  /// The start velocity and acceleration of the segment in waypoints(): the reference's, or a constant velocity
  /// where a position limit cuts it.
  const Eigen::VectorXd& segmentVelocity() const noexcept { return v_segment_; }
  const Eigen::VectorXd& segmentAcceleration() const noexcept { return a_segment_; }
  const TargetFollowerConfig& config() const noexcept { return config_; }

 private:
  void hold(HoldReason reason) noexcept;
  /// The joints' goal for the tool at `position` (world) by CLIK from the last goal; false on a CLIK failure.
  bool solve(const Eigen::Vector3d& position) noexcept;

  const kinematics::ChainModel& model_;
  TargetFollowerConfig config_;
  kinematics::ClikData clik_;
  kinematics::ChainData fk_;
  Waypoints waypoints_;
  Eigen::VectorXd q_r_, v_r_, a_r_, v_segment_, a_segment_, q_goal_, q_goal_previous_, v_goal_, v_wanted_, lower_,
      upper_, v_max_, a_max_;
  Eigen::Matrix3d orientation_;  ///< The tool's while following since start(): tool_orientation, with keep_yaw turned.
  Eigen::Vector3d goal_ = Eigen::Vector3d::Zero(), tool_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero(), last_velocity_ = Eigen::Vector3d::Zero();
  FollowPhase phase_ = FollowPhase::Idle;
  HoldReason reason_ = HoldReason::None;
  double t_ = 0.0, followed_since_ = 0.0, jumped_at_ = -1e300, last_stamp_ = std::numeric_limits<double>::quiet_NaN();
  double used_stamp_ = std::numeric_limits<double>::quiet_NaN();
  /// The filtered measured estimate (speed_time_constant, position_time_constant) and the stamp it holds (NaN: none).
  Eigen::Vector3d filtered_position_ = Eigen::Vector3d::Zero(), filtered_velocity_ = Eigen::Vector3d::Zero();
  double filtered_stamp_ = std::numeric_limits<double>::quiet_NaN();
  double offset_ = 1.0;  ///< Share of the pre-grasp offset applied (1 following, 0 at the grasp point).
  double tool_error_ = 0.0;
  bool goal_valid_ = false, grasp_answered_ = false, grasp_ = true;
};

}  // namespace bimanual_skills::control
