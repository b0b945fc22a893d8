/// \file
/// A joint trajectory through waypoints, interpolated by quintic polynomials so that positions, velocities and
/// accelerations are continuous (the reference of the computed-torque controller needs q̈_d). A new trajectory can
/// replace the running one at any instant without a jump: its first segment starts from the desired state the old
/// one had at that instant.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::control {

enum class TrajectoryStatus {
  Ok,
  WrongSize,      ///< Waypoint or state sizes do not match the joints, or more waypoints than the capacity.
  NotFinite,      ///< NaN/Inf in the waypoints or the state.
  NotIncreasing,  ///< Waypoint times are not strictly increasing and positive.
  OutOfLimits,    ///< A waypoint lies outside the position limits.
  InThePast,      ///< Every waypoint lies at or before the start (a start too far behind).
};

/// Name of a status ("Ok", ...), for logs outside the real-time path.
const char* toString(TrajectoryStatus status) noexcept;

/// Waypoints as a message carries them. Times are relative to the start (the instant the trajectory is
/// activated) and must be > 0 and increasing. Velocities and accelerations are optional (empty matrices): missing
/// velocities are the mean of the adjacent secant slopes where they have the same sign (0 otherwise and at the
/// last waypoint); missing accelerations are 0.
struct Waypoints {
  Eigen::VectorXd times;          ///< [s], k entries.
  Eigen::MatrixXd positions;      ///< n × k.
  Eigen::MatrixXd velocities;     ///< n × k or empty.
  Eigen::MatrixXd accelerations;  ///< n × k or empty.
};

/// Quintic-spline joint trajectory with a fixed capacity. Construction allocates; load() checks and copies
/// waypoints (no allocation when within capacity); start() and sample() are real-time safe.
class JointTrajectory {
 public:
  /// For `joints` joints and up to `capacity` waypoints, with position limits (±∞ allowed).
  /// \throws std::invalid_argument for non-positive sizes or limits of the wrong size or lower > upper.
  JointTrajectory(int joints, int capacity, const Eigen::VectorXd& lower, const Eigen::VectorXd& upper);

  /// Validates and stores waypoints; the trajectory is not active until start(). Anything but Ok leaves the
  /// trajectory unchanged. Real-time safe.
  TrajectoryStatus load(const Waypoints& waypoints) noexcept;
  /// The same for waypoints whose times count from a start `offset` seconds after the instant start() activates them
  /// (offset < 0: a start that lies behind, as control_msgs' header.stamp in the past): time t becomes t + offset,
  /// and the waypoints at or before 0 are past and dropped (InThePast when every one is). Times must be >= 0 and
  /// increase. Real-time safe.
  TrajectoryStatus load(const Waypoints& waypoints, double offset) noexcept;

  /// Activates the loaded waypoints at time `t0` from the desired state (q, q̇, q̈) at that instant (typically
  /// the previous trajectory's sample). Real-time safe.
  TrajectoryStatus start(double t0, const Eigen::Ref<const Eigen::VectorXd>& q,
                         const Eigen::Ref<const Eigen::VectorXd>& qd,
                         const Eigen::Ref<const Eigen::VectorXd>& qdd) noexcept;

  /// A trajectory that stays at q from t0 on (velocity and acceleration 0).
  void hold(double t0, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
  /// A stop: one quintic segment from the state (q, q̇, q̈) at t0 to rest at q + q̇ T/2 at t0 + T (T > 0), then
  /// there; no step in position, velocity or acceleration. Real-time safe.
  void stop(double t0, const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
            const Eigen::Ref<const Eigen::VectorXd>& qdd, double duration) noexcept;

  /// Desired state at time t (before the start: the start state; after the end: the last waypoint at rest).
  /// Real-time safe; the outputs must have `joints` entries.
  void sample(double t, Eigen::Ref<Eigen::VectorXd> q, Eigen::Ref<Eigen::VectorXd> qd,
              Eigen::Ref<Eigen::VectorXd> qdd) const noexcept;

  /// Whether t is past the last waypoint.
  bool finished(double t) const noexcept { return t >= t0_ + knot_times_[segments_]; }
  /// Time of the last waypoint (absolute).
  double endTime() const noexcept { return t0_ + knot_times_[segments_]; }
  int joints() const noexcept { return static_cast<int>(knot_q_.rows()); }
  int capacity() const noexcept { return static_cast<int>(knot_q_.cols()) - 1; }

 private:
  Eigen::VectorXd lower_, upper_;
  // Knot 0 is the start state; knots 1..k the waypoints. Loaded waypoints wait in pending_*.
  Eigen::VectorXd knot_times_;
  Eigen::MatrixXd knot_q_, knot_qd_, knot_qdd_;
  Eigen::VectorXd pending_times_;
  Eigen::MatrixXd pending_q_, pending_qd_, pending_qdd_;
  int pending_ = 0;
  int segments_ = 0;
  double t0_ = 0.0;
};

}  // namespace bimanual_skills::control
