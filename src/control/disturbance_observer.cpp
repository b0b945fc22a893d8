#include "bimanual_skills/control/disturbance_observer.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::control {

const char* toString(ObserverStatus status) noexcept {
  switch (status) {
    case ObserverStatus::Success:
      return "success";
    case ObserverStatus::WrongSize:
      return "an input has the wrong size";
    case ObserverStatus::NotFinite:
      return "an input contains NaN or Inf";
    case ObserverStatus::InvalidTimeStep:
      return "the time step is not finite and > 0";
    case ObserverStatus::Restarted:
      return "a gap longer than the observer integrates: restarted at this state";
  }
  return "unknown status";
}

ObserverGains ObserverGains::diagonal(int n, double k11, double k12, double k21, double k22, double sigma) {
  ObserverGains gains;
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  gains.K11 = k11 * I;
  gains.K12 = k12 * I;
  gains.K21 = k21 * I;
  gains.K22 = k22 * I;
  gains.Sigma = sigma * I;
  return gains;
}

DisturbanceObserver::DisturbanceObserver(const kinematics::ChainModel& model, const dynamics::FrictionModel& friction,
                                         const ObserverGains& gains)
    : model_(model),
      inertial_model_(model.withGravity(Eigen::Vector3d::Zero())),
      friction_(friction),
      period_(1.0 / gains.rate_hz),
      wrench_damping_(gains.wrench_damping),
      velocity_filter_(signal::designLowPassFir(gains.fir_taps, gains.fir_cutoff_hz, gains.rate_hz), model.nq()),
      dynamics_(model),
      friction_state_(friction),
      kinematics_(model),
      x1_(Eigen::VectorXd::Zero(model.nq())),
      x2_(Eigen::VectorXd::Zero(model.nq())),
      x2_previous_(Eigen::VectorXd::Zero(model.nq())),
      e1_(Eigen::VectorXd::Zero(model.nq())),
      e1_dt_(Eigen::VectorXd::Zero(model.nq())),
      accel_(Eigen::VectorXd::Zero(model.nq())),
      velocity_error_(Eigen::VectorXd::Zero(model.nq())),
      tau_model_(Eigen::VectorXd::Zero(model.nq())),
      friction_torque_(Eigen::VectorXd::Zero(model.nq())),
      external_torque_(Eigen::VectorXd::Zero(model.nq())),
      state_(Eigen::VectorXd::Zero(2 * model.nq())),
      learned_n_(Eigen::VectorXd::Zero(model.nq())),
      zeros_(Eigen::VectorXd::Zero(model.nq())),
      wrench_(Eigen::Matrix<double, 6, 1>::Zero()) {
  const int n = model.nq();
  for (const Eigen::MatrixXd* K : {&gains.K11, &gains.K12, &gains.K21, &gains.K22, &gains.Sigma}) {
    if (K->rows() != n || K->cols() != n || !K->allFinite()) {
      throw std::invalid_argument("DisturbanceObserver: K11, K12, K21, K22 and Sigma must be finite " +
                                  std::to_string(n) + " x " + std::to_string(n) + " matrices");
    }
  }
  if (!(gains.rate_hz > 0.0) || !(gains.wrench_damping >= 0.0)) {
    throw std::invalid_argument("DisturbanceObserver: rate_hz must be > 0 and wrench_damping >= 0");
  }
  if (friction_.size() != n) throw std::invalid_argument("DisturbanceObserver: friction model size mismatch");
  friction_.validate();
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(gains.Sigma + gains.K22);
  if (!lu.isInvertible()) throw std::invalid_argument("DisturbanceObserver: Sigma + K22 is singular");
  Sigma_ = gains.Sigma;
  G_ = lu.solve(gains.K21);
  P_ = gains.K11 + (Eigen::MatrixXd::Identity(n, n) - gains.K12) * G_;
  const Eigen::VectorXd symmetric =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (P_ + P_.transpose())).eigenvalues();
  if (symmetric.minCoeff() <= 0.0) {
    std::ostringstream message;
    message << "DisturbanceObserver: K11 + (I - K12)(Sigma + K22)^-1 K21 (thesis eq. 4.14) is not positive definite"
            << " (smallest eigenvalue of its symmetric part " << symmetric.minCoeff() << "): the estimate diverges";
    throw std::invalid_argument(message.str());
  }
  const double fastest = Eigen::EigenSolver<Eigen::MatrixXd>(P_).eigenvalues().cwiseAbs().maxCoeff();
  if (period_ * fastest >= 1.0) {
    std::ostringstream message;
    message << "DisturbanceObserver: the fastest observer pole (" << fastest << " 1/s) needs a rate above " << fastest
            << " Hz; rate_hz is " << gains.rate_hz;
    throw std::invalid_argument(message.str());
  }
  // x̂1's explicit Euler step converges while Δt |λ(P)| < 1; a gap of half that (or 20 periods) restarts the estimate.
  max_step_ = std::min(20.0 * period_, 0.5 / fastest);
}

void DisturbanceObserver::reset(const Eigen::Ref<const Eigen::VectorXd>& q,
                                const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept {
  if (q.size() != x1_.size() || qd.size() != x1_.size() || !q.allFinite() || !qd.allFinite()) return;
  x1_ = q;
  x2_ = qd;
  x2_previous_ = qd;
  velocity_clock_ = 0.0;
  velocity_filter_.reset();
  static_cast<void>(velocity_filter_.filter(qd));  // sizes and values checked above
  external_torque_.setZero();
  wrench_.setZero();
  started_ = true;
}

ObserverStatus DisturbanceObserver::update(const Eigen::Ref<const Eigen::VectorXd>& q,
                                           const Eigen::Ref<const Eigen::VectorXd>& qd,
                                           const Eigen::Ref<const Eigen::VectorXd>& u,
                                           const Eigen::Ref<const Eigen::VectorXd>& accel_sign) noexcept {
  return update(q, qd, u, accel_sign, period_);
}

ObserverStatus DisturbanceObserver::update(const Eigen::Ref<const Eigen::VectorXd>& q,
                                           const Eigen::Ref<const Eigen::VectorXd>& qd,
                                           const Eigen::Ref<const Eigen::VectorXd>& u,
                                           const Eigen::Ref<const Eigen::VectorXd>& accel_sign, double dt) noexcept {
  const auto n = x1_.size();
  for (const auto* v : {&q, &qd, &u, &accel_sign}) {
    if (v->size() != n) return ObserverStatus::WrongSize;
  }
  for (const auto* v : {&q, &qd, &u, &accel_sign}) {
    if (!v->allFinite()) return ObserverStatus::NotFinite;
  }
  if (!std::isfinite(dt) || !(dt > 0.0)) return ObserverStatus::InvalidTimeStep;
  if (!started_) reset(q, qd);
  if (dt > max_step_) {
    ++restarts_;
    reset(q, qd);
    return ObserverStatus::Restarted;
  }
  if (std::abs(dt - period_) > 0.2 * period_) ++irregular_steps_;
  // The FIR runs at the nominal rate on the measured velocity held over dt: one sample per elapsed nominal period
  // (rounded), at most a whole window.
  velocity_clock_ += dt;
  for (int pushed = 0; velocity_clock_ >= 0.5 * period_; ++pushed) {
    if (pushed == velocity_filter_.length()) {
      velocity_clock_ = 0.0;
      break;
    }
    static_cast<void>(velocity_filter_.filter(qd));  // sizes and values checked above
    velocity_clock_ -= period_;
  }
  const Eigen::VectorXd& v = velocity_filter_.output();
  e1_ = q - x1_;
  x2_previous_ = x2_;
  x2_.noalias() = G_ * e1_;
  x2_ += v;
  e1_dt_ = dt * e1_;
  x1_.noalias() += P_ * e1_dt_;
  x1_ += dt * v;
  // (4.15): d̂ = M(x̂1)(ẋ̂2 + Σ (v − x̂2)) + C(x̂1, x̂2) x̂2 + G(x̂1) + F_f − u_c, the first three in one RNEA pass.
  accel_ = (x2_ - x2_previous_) / dt;
  velocity_error_ = v - x2_;  // a plain vector: a product with an expression would allocate its temporary
  accel_.noalias() += Sigma_ * velocity_error_;
  bool learned = false;
  if (learned_.fits(static_cast<int>(n))) {
    state_.head(n) = x1_;
    state_.tail(n) = x2_;
    learned = learned_.predict(state_, learned_n_) &&
              dynamics::inverseDynamics(inertial_model_, dynamics_, x1_, zeros_, accel_, tau_model_, payload_) ==
                  dynamics::DynamicsStatus::Success;
    if (learned) tau_model_ += learned_n_;
  }
  if (!learned) {
    // Only an estimate that overflowed can fail here: the inputs were checked above.
    if (dynamics::inverseDynamics(model_, dynamics_, x1_, x2_, accel_, tau_model_, payload_) !=
            dynamics::DynamicsStatus::Success ||
        dynamics::frictionTorques(friction_, friction_state_, x1_, x2_, accel_sign, friction_torque_) !=
            dynamics::DynamicsStatus::Success) {
      return ObserverStatus::NotFinite;
    }
    tau_model_ += friction_torque_;
  }
  // d̂ = M q̈ + n − u_c: with M q̈ + n = u_c + τ_ext for a torque τ_ext the environment applies on the robot, this is
  // τ_ext (the thesis writes d = −u_e, u_e the robot's action on the environment).
  external_torque_ = tau_model_ - u;
  // Tool wrench: least-squares solution of Jᵀ F = τ̂_ext, F = (J Jᵀ + λ² I)⁻¹ J τ̂_ext.
  static_cast<void>(kinematics::computeJacobian(model_, kinematics_, q));  // q checked above
  const auto& J = kinematics_.jacobian;
  gram_.noalias() = J * J.transpose();
  gram_.diagonal().array() += wrench_damping_ * wrench_damping_;
  gram_llt_.compute(gram_);
  wrench_.noalias() = J * external_torque_;
  gram_llt_.solveInPlace(wrench_);
  return ObserverStatus::Success;
}

}  // namespace bimanual_skills::control
