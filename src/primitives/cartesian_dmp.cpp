#include "bimanual_skills/primitives/cartesian_dmp.hpp"

#include "bimanual_skills/signal/fir_filter.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {
namespace {

constexpr double kUnitTolerance = 1e-6;  ///< |‖q‖ − 1| accepted as a unit quaternion

bool isUnit(const Eigen::Quaterniond& q) noexcept {
  return std::abs(q.norm() - 1.0) <= kUnitTolerance;  // false for NaN/Inf as well
}

void requireUnit(const Eigen::Quaterniond& q, const std::string& what) {
  if (!isUnit(q)) {
    throw std::invalid_argument(what + " must be a finite unit quaternion (norm " + std::to_string(q.norm()) + ")");
  }
}

bool sized3Finite(const Eigen::VectorXd& v) noexcept {
  return v.size() == 3 && v.allFinite();
}

bool validDmpState(const DmpState& s) noexcept {
  return sized3Finite(s.y) && sized3Finite(s.yd) && sized3Finite(s.ydd) && sized3Finite(s.goal) && std::isfinite(s.x) &&
         std::isfinite(s.t);
}

/// Coordinates of the goal orientation for the orientation Dmp: 2 log(g ∗ q̄_s) or vec(q_s⁻¹ ∗ g).
Eigen::Vector3d orientationGoal(OrientationEncoding encoding, const Eigen::Quaterniond& start,
                                const Eigen::Quaterniond& goal) noexcept {
  return encoding == OrientationEncoding::UnitQuaternion
             ? Eigen::Vector3d(2.0 * quaternionLog(goal * start.conjugate()))
             : relativeQuaternionVector(start, goal);
}

/// Checks what the members' constructors would report less precisely; returns the encoding.
OrientationEncoding checkedInputs(OrientationEncoding encoding, const Eigen::MatrixXd& position_weights,
                                  const Eigen::MatrixXd& orientation_weights, const Pose& start, const Pose& goal) {
  if (position_weights.rows() != 3 || orientation_weights.rows() != 3) {
    throw std::invalid_argument("CartesianDmp: position and orientation weights must have 3 rows (x, y, z), not " +
                                std::to_string(position_weights.rows()) + " and " +
                                std::to_string(orientation_weights.rows()));
  }
  requireUnit(start.orientation, "CartesianDmp: the start orientation");
  requireUnit(goal.orientation, "CartesianDmp: the goal orientation");
  return encoding;
}

}  // namespace

Eigen::Vector3d relativeQuaternionVector(const Eigen::Quaterniond& start, const Eigen::Quaterniond& q) noexcept {
  const Eigen::Quaterniond relative = nearestSign(start.conjugate() * q, Eigen::Quaterniond::Identity());
  return relative.vec();
}

Eigen::Vector3d quaternionLog(const Eigen::Quaterniond& q) noexcept {
  const double n = q.vec().norm();
  // atan2(n, w)/n → 1/w as n → 0; at q = −1 (a rotation of 2π, the identity) the axis is undefined: 0.
  if (n < 1e-12) return q.w() > 0.0 ? Eigen::Vector3d(q.vec() / q.w()) : Eigen::Vector3d::Zero();
  return std::atan2(n, q.w()) / n * q.vec();
}

Eigen::Quaterniond quaternionExp(const Eigen::Vector3d& r) noexcept {
  const double n = r.norm();
  if (n < 1e-12) return Eigen::Quaterniond(1.0, r.x(), r.y(), r.z()).normalized();
  const Eigen::Vector3d v = std::sin(n) / n * r;
  return Eigen::Quaterniond(std::cos(n), v.x(), v.y(), v.z());
}

Eigen::Quaterniond nearestSign(const Eigen::Quaterniond& q, const Eigen::Quaterniond& reference) noexcept {
  return q.coeffs().dot(reference.coeffs()) >= 0.0 ? q : Eigen::Quaterniond(-q.coeffs());
}

CartesianDmp::CartesianDmp(const DmpParameters& parameters, OrientationEncoding encoding,
                           const Eigen::MatrixXd& position_weights, const Eigen::MatrixXd& orientation_weights,
                           const Pose& start, const Pose& goal, double duration)
    : encoding_(checkedInputs(encoding, position_weights, orientation_weights, start, goal)),
      position_(parameters, position_weights, start.position, goal.position, duration),
      orientation_(parameters, orientation_weights, Eigen::Vector3d::Zero(),
                   orientationGoal(encoding, start.orientation, goal.orientation), duration),
      start_(start),
      goal_(goal) {}

CartesianDmp CartesianDmp::fit(const DmpParameters& parameters, OrientationEncoding encoding,
                               const std::vector<Pose>& demonstration, double dt, double smoothing_hz) {
  const auto samples = static_cast<Eigen::Index>(demonstration.size());
  if (samples < 10 || !(dt > 0.0)) throw std::invalid_argument("CartesianDmp::fit: need >= 10 poses and dt > 0");
  Eigen::MatrixXd positions(samples, 3);
  std::vector<Eigen::Quaterniond> q(demonstration.size());
  for (Eigen::Index k = 0; k < samples; ++k) {
    const Pose& pose = demonstration[static_cast<std::size_t>(k)];
    requireUnit(pose.orientation, "CartesianDmp::fit: pose " + std::to_string(k) + "'s orientation");
    positions.row(k) = pose.position.transpose();
    // Sign continuity: q and −q are the same orientation, the log map of consecutive samples needs the near one.
    q[k] = k == 0 ? pose.orientation.normalized() : nearestSign(pose.orientation.normalized(), q[k - 1]);
  }
  const Dmp position = Dmp::fit(parameters, positions, dt, smoothing_hz);
  const Pose start{positions.row(0).transpose(), q.front()};
  const Pose goal{positions.row(samples - 1).transpose(), q.back()};
  const double tau = position.duration();

  if (encoding == OrientationEncoding::QuaternionVector) {
    Eigen::MatrixXd v(samples, 3);
    for (Eigen::Index k = 0; k < samples; ++k) v.row(k) = relativeQuaternionVector(start.orientation, q[k]).transpose();
    const Dmp vector = Dmp::fit(parameters, v, dt, smoothing_hz);
    return CartesianDmp(parameters, encoding, position.weights(), vector.weights(), start, goal, tau);
  }

  // Unit quaternion: ω_{k+½} = 2 log(q_{k+1} ∗ q̄_k) / dt, smoothed, integrated back to orientations q̃_k.
  Eigen::MatrixXd half(samples - 1, 3);
  for (Eigen::Index k = 0; k + 1 < samples; ++k) {
    half.row(k) = (2.0 / dt * quaternionLog(q[k + 1] * q[k].conjugate())).transpose();
  }
  half = signal::zeroPhaseLowPass(half, dt, smoothing_hz);
  const CartesianDmp shape(parameters, encoding, position.weights(), Eigen::MatrixXd::Zero(3, parameters.kernels),
                           start, goal, tau);
  const Eigen::Vector3d amplitude = shape.orientation().goal();  // D_o = 2 log(g ∗ q̄_0)
  Eigen::MatrixXd forcing(samples, 3);
  Eigen::Quaterniond smoothed = start.orientation;
  for (Eigen::Index k = 0; k < samples; ++k) {
    Eigen::Vector3d omega = Eigen::Vector3d::Zero(), omega_dot = Eigen::Vector3d::Zero();
    if (k > 0 && k + 1 < samples) {
      omega = 0.5 * (half.row(k - 1) + half.row(k)).transpose();
      omega_dot = (half.row(k) - half.row(k - 1)).transpose() / dt;
    }
    const Eigen::Vector3d error = 2.0 * quaternionLog(goal.orientation * smoothed.conjugate());
    Eigen::Vector3d f = forcingTarget(parameters, tau, error, omega, omega_dot);  // Ude et al. (2014)
    if (parameters.goal_scaled_forcing) {
      for (int i = 0; i < 3; ++i) f[i] /= std::abs(amplitude[i]) > 1e-9 ? amplitude[i] : 1.0;
    }
    forcing.row(k) = f.transpose();
    if (k + 1 < samples) smoothed = (quaternionExp(0.5 * dt * half.row(k).transpose()) * smoothed).normalized();
  }
  return CartesianDmp(parameters, encoding, position.weights(), shape.orientation().fitWeights(forcing, dt), start,
                      goal, tau);
}

CartesianDmp CartesianDmp::withDuration(double duration) const {
  return CartesianDmp(parameters(), encoding_, positionWeights(), orientationWeights(), start_, goal_, duration);
}

CartesianDmp CartesianDmp::withGoal(const Pose& goal) const {
  return CartesianDmp(parameters(), encoding_, positionWeights(), orientationWeights(), start_, goal, duration());
}

CartesianDmpState CartesianDmp::initialState() const {
  CartesianDmpState state;
  state.position = position_.initialState();
  state.orientation = start_.orientation;
  state.goal_orientation = goal_.orientation;
  if (encoding_ == OrientationEncoding::QuaternionVector) state.orientation_vector = orientation_.initialState();
  return state;
}

DmpStatus CartesianDmp::step(CartesianDmpState& state, double dt) const noexcept {
  return stepWith(state, dt, nullptr);
}

DmpStatus CartesianDmp::step(CartesianDmpState& state, double dt,
                             const Eigen::Ref<const Eigen::VectorXd>& forcing) const noexcept {
  if (forcing.size() != 6 || !forcing.allFinite()) return DmpStatus::InvalidInput;
  return stepWith(state, dt, &forcing);
}

DmpStatus CartesianDmp::stepWith(CartesianDmpState& state, double dt,
                                 const Eigen::Ref<const Eigen::VectorXd>* forcing) const noexcept {
  const bool vector_encoding = encoding_ == OrientationEncoding::QuaternionVector;
  if (!(dt > 0.0) || !std::isfinite(dt) || !parameters().stableStep(dt, duration()) || !validDmpState(state.position) ||
      !isUnit(state.orientation) || !isUnit(state.goal_orientation) || !state.angular_velocity.allFinite() ||
      !state.angular_acceleration.allFinite() || (vector_encoding && !validDmpState(state.orientation_vector))) {
    return DmpStatus::InvalidInput;
  }
  const DmpParameters& p = parameters();
  const double tau = duration();
  const Eigen::Quaterniond& q_s = start_.orientation;
  const Eigen::Quaterniond previous = state.orientation;
  bool clamped = false;
  if (vector_encoding) {
    // The DMP of v = vec(q_s⁻¹ ∗ q), on the position's phase, then q = q_s ∗ (√(1 − ‖v‖²), v).
    DmpState& v_state = state.orientation_vector;
    v_state.goal = relativeQuaternionVector(q_s, state.goal_orientation);
    v_state.x = state.position.x;
    v_state.t = state.position.t;
    // Cannot fail: validated above.
    if (forcing != nullptr) {
      static_cast<void>(orientation_.step(v_state, dt, forcing->tail<3>()));
    } else {
      static_cast<void>(orientation_.step(v_state, dt));
    }
    Eigen::Vector3d v = v_state.y;
    const double n = v.norm();
    clamped = n > 1.0;
    if (clamped) v /= n;
    const double w = clamped ? 0.0 : std::sqrt(1.0 - n * n);
    state.orientation = (q_s * Eigen::Quaterniond(w, v.x(), v.y(), v.z())).normalized();
    // ω from the orientation change (the shorter of ±, since the reconstruction may flip the sign).
    const Eigen::Vector3d omega =
        2.0 / dt * quaternionLog(nearestSign(state.orientation * previous.conjugate(), Eigen::Quaterniond::Identity()));
    state.angular_acceleration = (omega - state.angular_velocity) / dt;
    state.angular_velocity = omega;
  } else {
    // Ude et al. (2014): τ² ω̇ = α_z (β_z 2 log(g ∗ q̄) − τ ω) + f(x), q ← exp(dt ω / 2) ∗ q.
    Eigen::Vector3d f;
    if (forcing != nullptr) {
      f = forcing->tail<3>();
    } else {
      double g_storage[kDmpMaxKernels];
      Eigen::Map<Eigen::VectorXd> g(g_storage, p.kernels);
      orientation_.basis(state.position.x, g);
      f.noalias() = orientation_.weights() * g;
      if (p.goal_scaled_forcing) f = f.cwiseProduct(2.0 * quaternionLog(state.goal_orientation * q_s.conjugate()));
    }
    const Eigen::Vector3d error = 2.0 * quaternionLog(state.goal_orientation * state.orientation.conjugate());
    state.angular_acceleration = transformationAcceleration(p, tau, error, state.angular_velocity, f);
    state.angular_velocity += dt * state.angular_acceleration;
    state.orientation = (quaternionExp(0.5 * dt * state.angular_velocity) * state.orientation).normalized();
  }
  // Advances the shared phase; validated above.
  if (forcing != nullptr) {
    static_cast<void>(position_.step(state.position, dt, forcing->head<3>()));
  } else {
    static_cast<void>(position_.step(state.position, dt));
  }
  return clamped ? DmpStatus::VectorClamped : DmpStatus::Success;
}

}  // namespace bimanual_skills::primitives
