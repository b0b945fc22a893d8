#include "bimanual_skills/control/joint_trajectory.hpp"

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::control {

const char* toString(TrajectoryStatus status) noexcept {
  switch (status) {
    case TrajectoryStatus::Ok:
      return "Ok";
    case TrajectoryStatus::WrongSize:
      return "WrongSize";
    case TrajectoryStatus::NotFinite:
      return "NotFinite";
    case TrajectoryStatus::NotIncreasing:
      return "NotIncreasing";
    case TrajectoryStatus::OutOfLimits:
      return "OutOfLimits";
    case TrajectoryStatus::InThePast:
      return "InThePast";
  }
  return "Unknown";
}

JointTrajectory::JointTrajectory(int joints, int capacity, const Eigen::VectorXd& lower, const Eigen::VectorXd& upper)
    : lower_(lower), upper_(upper) {
  if (joints <= 0 || capacity <= 0) throw std::invalid_argument("JointTrajectory: joints and capacity must be > 0");
  if (lower.size() != joints || upper.size() != joints || (lower.array() > upper.array()).any()) {
    throw std::invalid_argument("JointTrajectory: position limits must have one entry per joint, lower <= upper");
  }
  knot_times_ = Eigen::VectorXd::Zero(capacity + 1);
  knot_q_ = knot_qd_ = knot_qdd_ = Eigen::MatrixXd::Zero(joints, capacity + 1);
  pending_times_ = Eigen::VectorXd::Zero(capacity);
  pending_q_ = Eigen::MatrixXd::Zero(joints, capacity);
  pending_qd_ = pending_qdd_ = Eigen::MatrixXd::Constant(joints, capacity, std::nan(""));
}

TrajectoryStatus JointTrajectory::load(const Waypoints& w) noexcept {
  if (w.times.size() > 0 && !(w.times[0] > 0.0)) return TrajectoryStatus::NotIncreasing;
  return load(w, 0.0);
}

TrajectoryStatus JointTrajectory::load(const Waypoints& w, double offset) noexcept {
  const Eigen::Index n = knot_q_.rows(), k = w.times.size();
  if (k < 1 || k > capacity() || w.positions.rows() != n || w.positions.cols() != k) return TrajectoryStatus::WrongSize;
  const auto optional_ok = [&](const Eigen::MatrixXd& m) { return m.size() == 0 || (m.rows() == n && m.cols() == k); };
  if (!optional_ok(w.velocities) || !optional_ok(w.accelerations)) return TrajectoryStatus::WrongSize;
  if (!w.times.allFinite() || !w.positions.allFinite() || !w.velocities.allFinite() || !w.accelerations.allFinite() ||
      !std::isfinite(offset)) {
    return TrajectoryStatus::NotFinite;
  }
  Eigen::Index first = k;  // the first waypoint after the start
  for (Eigen::Index i = 0; i < k; ++i) {
    if (i == 0 ? w.times[i] < 0.0 : w.times[i] <= w.times[i - 1]) return TrajectoryStatus::NotIncreasing;
    if ((w.positions.col(i).array() < lower_.array()).any() || (w.positions.col(i).array() > upper_.array()).any()) {
      return TrajectoryStatus::OutOfLimits;
    }
    if (first == k && w.times[i] + offset > 0.0) first = i;
  }
  if (first == k) return TrajectoryStatus::InThePast;
  const Eigen::Index kept = k - first;
  pending_ = static_cast<int>(kept);
  pending_times_.head(kept) = w.times.tail(kept).array() + offset;
  pending_q_.leftCols(kept) = w.positions.rightCols(kept);
  // NaN marks a value to estimate in start().
  if (w.velocities.size() > 0) {
    pending_qd_.leftCols(kept) = w.velocities.rightCols(kept);
  } else {
    pending_qd_.leftCols(kept).setConstant(std::nan(""));
  }
  if (w.accelerations.size() > 0) {
    pending_qdd_.leftCols(kept) = w.accelerations.rightCols(kept);
  } else {
    pending_qdd_.leftCols(kept).setZero();
  }
  return TrajectoryStatus::Ok;
}

TrajectoryStatus JointTrajectory::start(double t0, const Eigen::Ref<const Eigen::VectorXd>& q,
                                        const Eigen::Ref<const Eigen::VectorXd>& qd,
                                        const Eigen::Ref<const Eigen::VectorXd>& qdd) noexcept {
  const Eigen::Index n = knot_q_.rows();
  if (q.size() != n || qd.size() != n || qdd.size() != n || pending_ == 0) return TrajectoryStatus::WrongSize;
  if (!std::isfinite(t0) || !q.allFinite() || !qd.allFinite() || !qdd.allFinite()) return TrajectoryStatus::NotFinite;
  const int k = pending_;
  t0_ = t0;
  segments_ = k;
  knot_times_[0] = 0.0;
  knot_q_.col(0) = q;
  knot_qd_.col(0) = qd;
  knot_qdd_.col(0) = qdd;
  knot_times_.segment(1, k) = pending_times_.head(k);
  knot_q_.middleCols(1, k) = pending_q_.leftCols(k);
  knot_qd_.middleCols(1, k) = pending_qd_.leftCols(k);
  knot_qdd_.middleCols(1, k) = pending_qdd_.leftCols(k);
  for (int i = 1; i <= k; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      if (!std::isnan(knot_qd_(j, i))) continue;
      if (i == k) {
        knot_qd_(j, i) = 0.0;
        continue;
      }
      const double before = (knot_q_(j, i) - knot_q_(j, i - 1)) / (knot_times_[i] - knot_times_[i - 1]);
      const double after = (knot_q_(j, i + 1) - knot_q_(j, i)) / (knot_times_[i + 1] - knot_times_[i]);
      knot_qd_(j, i) = before * after > 0.0 ? 0.5 * (before + after) : 0.0;
    }
  }
  return TrajectoryStatus::Ok;
}

void JointTrajectory::stop(double t0, const Eigen::Ref<const Eigen::VectorXd>& q,
                           const Eigen::Ref<const Eigen::VectorXd>& qd, const Eigen::Ref<const Eigen::VectorXd>& qdd,
                           double duration) noexcept {
  t0_ = t0;
  segments_ = 1;
  knot_times_[0] = 0.0;
  knot_times_[1] = duration;
  knot_q_.col(0) = q;
  knot_qd_.col(0) = qd;
  knot_qdd_.col(0) = qdd;
  knot_q_.col(1) = q + 0.5 * duration * qd;
  knot_qd_.col(1).setZero();
  knot_qdd_.col(1).setZero();
}

void JointTrajectory::hold(double t0, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  t0_ = t0;
  segments_ = 0;
  knot_times_[0] = 0.0;
  knot_q_.col(0) = q;
  knot_qd_.col(0).setZero();
  knot_qdd_.col(0).setZero();
}

void JointTrajectory::sample(double t, Eigen::Ref<Eigen::VectorXd> q, Eigen::Ref<Eigen::VectorXd> qd,
                             Eigen::Ref<Eigen::VectorXd> qdd) const noexcept {
  const double s = t - t0_;
  if (segments_ == 0 || s >= knot_times_[segments_]) {
    q = knot_q_.col(segments_);
    qd.setZero();
    qdd.setZero();
    return;
  }
  if (s <= 0.0) {
    q = knot_q_.col(0);
    qd = knot_qd_.col(0);
    qdd = knot_qdd_.col(0);
    return;
  }
  int i = 0;
  while (s >= knot_times_[i + 1]) ++i;
  const double T = knot_times_[i + 1] - knot_times_[i], x = s - knot_times_[i];
  const double T2 = T * T, T3 = T2 * T, T4 = T3 * T, T5 = T4 * T;
  for (Eigen::Index j = 0; j < q.size(); ++j) {
    const double p0 = knot_q_(j, i), v0 = knot_qd_(j, i), a0 = knot_qdd_(j, i);
    const double v1 = knot_qd_(j, i + 1), a1 = knot_qdd_(j, i + 1), h = knot_q_(j, i + 1) - p0;
    const double c3 = (20.0 * h - (8.0 * v1 + 12.0 * v0) * T - (3.0 * a0 - a1) * T2) / (2.0 * T3);
    const double c4 = (-30.0 * h + (14.0 * v1 + 16.0 * v0) * T + (3.0 * a0 - 2.0 * a1) * T2) / (2.0 * T4);
    const double c5 = (12.0 * h - 6.0 * (v1 + v0) * T - (a0 - a1) * T2) / (2.0 * T5);
    q[j] = p0 + x * (v0 + x * (0.5 * a0 + x * (c3 + x * (c4 + x * c5))));
    qd[j] = v0 + x * (a0 + x * (3.0 * c3 + x * (4.0 * c4 + x * 5.0 * c5)));
    qdd[j] = a0 + x * (6.0 * c3 + x * (12.0 * c4 + x * 20.0 * c5));
  }
}

}  // namespace bimanual_skills::control
