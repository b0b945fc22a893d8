#include "bimanual_skills/sim/arm_plant.hpp"

#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace bimanual_skills::sim {
namespace {

constexpr int kMaxSweeps = 200;               ///< Projected Gauss–Seidel cap.
constexpr double kVelocityTolerance = 1e-12;  ///< [rad/s] largest velocity change of a converged sweep.
constexpr double kLimitMargin = 1e-9;         ///< [rad or m] a joint this close to a limit gets its row.

Eigen::VectorXd orZeros(const Eigen::VectorXd& v, int n) {
  return v.size() == 0 ? Eigen::VectorXd::Zero(n) : v;
}

}  // namespace

ArmPlant::ArmPlant(kinematics::ChainModel model, ArmPlantParameters parameters)
    : model_(model.withRotorInertia(Eigen::VectorXd::Zero(model.nq()))),
      parameters_(std::move(parameters)),
      data_(model_) {
  const int n = model_.nq();
  parameters_.validate(n, "plant of the chain " + model_.baseLink() + " -> " + model_.tipLink());
  rotor_ = orZeros(parameters_.rotor_inertia, n);
  resolution_ = orZeros(parameters_.encoder_resolution, n);
  noise_ = orZeros(parameters_.velocity_noise, n);

  std::vector<Eigen::VectorXd> rows;
  for (const Drive& drive : parameters_.drives) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
    g[drive.first] = 1.0;
    if (!drive.isDifferential()) {
      rows.push_back(g);
      laws_.push_back(drive.friction);
      channels_.push_back({drive.first, drive.first, 0.0});
      continue;
    }
    for (const double side : {1.0, -1.0}) {
      g[drive.second] = side * drive.ratio;
      rows.push_back(g);
      laws_.push_back(drive.friction);
      channels_.push_back({drive.first, drive.second, side * drive.ratio});
    }
  }
  const int c = static_cast<int>(rows.size());
  G_.resize(c, n);
  D_ = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < c; ++k) {
    G_.row(k) = rows[static_cast<std::size_t>(k)].transpose();
    D_.noalias() += laws_[static_cast<std::size_t>(k)].viscous * G_.row(k).transpose() * G_.row(k);
  }

  A_.setZero(n, n);
  mass_.setZero(n, n);
  inverse_.setZero(n, n);
  Y_.setZero(n, c + n);
  W_.setZero(c + n, c + n);
  lower_ = model_.lowerLimits();
  upper_ = model_.upperLimits();
  row_joint_.assign(static_cast<std::size_t>(n), 0);
  llt_ = Eigen::LLT<Eigen::MatrixXd>(n);
  for (Eigen::VectorXd* v : {&mass_times_qdd_, &bias_, &rhs_, &v_free_, &qd_next_, &friction_torque_, &zeros_}) {
    v->setZero(n);
  }
  for (Eigen::VectorXd* v : {&u_free_, &lambda_, &lo_, &hi_, &target_}) v->setZero(c + n);
  for (Eigen::VectorXd* v : {&u_previous_, &position_, &active_rhs_}) v->setZero(c);
  active_.setZero(c, c);
  lu_ = Eigen::PartialPivLU<Eigen::MatrixXd>(c);
  sigma_ = Eigen::VectorXd::Ones(c);
  stuck_.assign(static_cast<std::size_t>(c), 1);
}

ArmPlant::~ArmPlant() = default;
ArmPlant::ArmPlant(ArmPlant&&) noexcept = default;
ArmPlant& ArmPlant::operator=(ArmPlant&&) noexcept = default;

void ArmPlant::applyTorqueLimits(const Eigen::Ref<const Eigen::VectorXd>& command,
                                 Eigen::Ref<Eigen::VectorXd> applied) const noexcept {
  const Eigen::VectorXd& limit = model_.effortLimits();
  for (int i = 0; i < nq(); ++i) {
    applied[i] = parameters_.saturate_torque && std::isfinite(limit[i]) ? std::clamp(command[i], -limit[i], limit[i])
                                                                        : command[i];
  }
}

double ArmPlant::ripple(int k, double position, double direction) const noexcept {
  const FrictionLaw& law = laws_[static_cast<std::size_t>(k)];
  if (law.ripple == 0.0) return 1.0;
  const double phase = direction >= 0.0 ? law.ripple_phase_positive : law.ripple_phase_negative;
  return 1.0 + law.ripple * std::sin(law.ripple_frequency * position + phase);
}

double ArmPlant::slidingLevel(int k, double position, double velocity) const noexcept {
  const FrictionLaw& law = laws_[static_cast<std::size_t>(k)];
  const double ratio = velocity / law.stribeck_velocity;
  const double level =
      law.coulomb * (1.0 + law.hysteresis * sigma_[k]) + (law.static_friction - law.coulomb) * std::exp(-ratio * ratio);
  return ripple(k, position, signal::sign(velocity)) * level;
}

SimStatus ArmPlant::step(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
                         const Eigen::Ref<const Eigen::VectorXd>& tau, const Eigen::Ref<const Eigen::VectorXd>& tau_ext,
                         const dynamics::Payload& payload, double dt, Eigen::Ref<Eigen::VectorXd> qdd,
                         Eigen::Ref<Eigen::VectorXd> rigid_body_torque) noexcept {
  const int n = nq();
  if (q.size() != n || qd.size() != n || tau.size() != n || tau_ext.size() != n || qdd.size() != n ||
      rigid_body_torque.size() != n) {
    return SimStatus::InvalidArgument;
  }
  if (!q.allFinite() || !qd.allFinite() || !tau.allFinite() || !tau_ext.allFinite() || !std::isfinite(dt) ||
      !(dt > 0.0) || !std::isfinite(payload.mass) || !payload.com.allFinite()) {
    return SimStatus::InvalidArgument;
  }
  // M(q) and h = C q̇ + G with the payload; A = M + J_m + Δt D.
  if (dynamics::massMatrix(model_, data_, q, payload) != dynamics::DynamicsStatus::Success) {
    return SimStatus::InvalidArgument;
  }
  mass_ = data_.mass_matrix;
  if (dynamics::inverseDynamics(model_, data_, q, qd, zeros_, bias_, payload) != dynamics::DynamicsStatus::Success) {
    return SimStatus::InvalidArgument;
  }
  A_ = mass_;
  A_.diagonal() += rotor_;
  A_.noalias() += dt * D_;
  llt_.compute(A_);
  if (llt_.info() != Eigen::Success) return SimStatus::InvalidArgument;

  // Velocity without the Coulomb impulses: v_free = q̇ + A⁻¹ Δt (τ + τ_ext − h − D q̇).
  rhs_ = tau + tau_ext - bias_;
  rhs_.noalias() -= D_.lazyProduct(qd);
  rhs_ *= dt;
  llt_.solveInPlace(rhs_);
  v_free_ = qd + rhs_;

  // Joint limits that the free motion would cross this step become unilateral rows after the friction channels:
  // q_i + Δt q̇⁺_i ≥ lower_i (or ≤ upper_i), an inelastic stop at the limit with the full inertia A.
  const int c = channelCount();
  int rows = c;
  for (int i = 0; i < n; ++i) {
    const double next = q[i] + dt * v_free_[i];
    double target = 0.0, lo = 0.0, hi = 0.0;
    if (next < lower_[i] + kLimitMargin) {
      target = (lower_[i] - q[i]) / dt;
      hi = std::numeric_limits<double>::infinity();
    } else if (next > upper_[i] - kLimitMargin) {
      target = (upper_[i] - q[i]) / dt;
      lo = -std::numeric_limits<double>::infinity();
    } else {
      continue;
    }
    row_joint_[static_cast<std::size_t>(rows - c)] = i;
    target_[rows] = target;
    lo_[rows] = lo;
    hi_[rows] = hi;
    ++rows;
  }
  const int limits = rows - c;

  if (rows > 0) {
    // Y = A⁻¹ Gᵀ and the Delassus matrix W = G A⁻¹ Gᵀ, from A⁻¹ and the (one or two) joints of each row.
    inverse_.setIdentity();
    llt_.solveInPlace(inverse_);
    for (int k = 0; k < rows; ++k) {
      const Channel ch = rowChannel(k);
      Y_.col(k) = inverse_.col(ch.a);
      if (ch.kb != 0.0) Y_.col(k) += ch.kb * inverse_.col(ch.b);
    }
    for (int k = 0; k < rows; ++k) {
      const Channel ch = rowChannel(k);
      for (int j = 0; j < rows; ++j) W_(k, j) = Y_(ch.a, j) + (ch.kb != 0.0 ? ch.kb * Y_(ch.b, j) : 0.0);
      u_free_[k] = v_free_[ch.a] + (ch.kb != 0.0 ? ch.kb * v_free_[ch.b] : 0.0);
    }
    for (int k = 0; k < c; ++k) {
      const FrictionLaw& law = laws_[static_cast<std::size_t>(k)];
      position_[k] = channelValue(k, q);
      const double u = channelValue(k, qd);
      // Hysteresis direction: +1 while |u| grows, −1 while it shrinks (held when undecided).
      const double du = u - u_previous_[k];
      if (u != 0.0 && du != 0.0) sigma_[k] = signal::sign(u) * signal::sign(du);
      u_previous_[k] = u;
      const double level = stuck_[static_cast<std::size_t>(k)]
                               ? ripple(k, position_[k], signal::sign(u_free_[k])) * law.static_friction
                               : slidingLevel(k, position_[k], u);
      hi_[k] = dt * level;
      lo_[k] = -hi_[k];
      target_[k] = 0.0;
    }
    iterations_ = 0;
    bool consistent = false;
    if (limits == 0) {
      // Active-set guess from the last step: sticking channels get the λ that stops them (a linear solve), sliding
      // ones ∓bound against their motion. Accepted when consistent (|λ| within bounds where sticking, friction
      // opposing the end velocity where sliding): the usual case, and exact.
      bool any_sticking = false;
      for (int k = 0; k < c; ++k) {
        const bool sticking = stuck_[static_cast<std::size_t>(k)] != 0;
        any_sticking = any_sticking || sticking;
        active_.row(k).setZero();
        if (sticking) {
          active_.row(k) = W_.row(k).head(c);
          active_rhs_[k] = -u_free_[k];
        } else {
          const double u = channelValue(k, qd);
          const double direction = u != 0.0 ? signal::sign(u) : signal::sign(u_free_[k]);
          active_(k, k) = 1.0;
          active_rhs_[k] = -direction * hi_[k];
        }
      }
      if (any_sticking) {
        lu_.compute(active_);
        lambda_.head(c) = lu_.solve(active_rhs_);
      } else {
        lambda_.head(c) = active_rhs_;
      }
      consistent = lambda_.head(c).allFinite();
      for (int k = 0; k < c && consistent; ++k) {
        const double u = u_free_[k] + W_.row(k).head(c).dot(lambda_.head(c));
        consistent = stuck_[static_cast<std::size_t>(k)] ? std::abs(lambda_[k]) <= hi_[k] : u * lambda_[k] <= 0.0;
      }
    }
    if (!consistent) {
      // Projected Gauss–Seidel: λ_k ← clamp(λ_k − ((u_free + W λ)_k − target_k) / W_kk, lo_k, hi_k).
      for (int k = 0; k < rows; ++k) {
        lambda_[k] = k < c && std::isfinite(lambda_[k]) ? std::clamp(lambda_[k], lo_[k], hi_[k]) : 0.0;
      }
      for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
        double largest_change = 0.0;
        for (int k = 0; k < rows; ++k) {
          if (lo_[k] == 0.0 && hi_[k] == 0.0) {
            lambda_[k] = 0.0;
            continue;
          }
          const double u = u_free_[k] + W_.row(k).head(rows).dot(lambda_.head(rows));
          const double updated = std::clamp(lambda_[k] - (u - target_[k]) / W_(k, k), lo_[k], hi_[k]);
          largest_change = std::max(largest_change, std::abs(updated - lambda_[k]) * W_(k, k));
          lambda_[k] = updated;
        }
        ++iterations_;
        if (largest_change <= kVelocityTolerance) break;
      }
    }
    qd_next_ = v_free_;
    qd_next_.noalias() += Y_.leftCols(rows).lazyProduct(lambda_.head(rows));
    for (int k = 0; k < c; ++k) {
      stuck_[static_cast<std::size_t>(k)] = hi_[k] > 0.0 && std::abs(lambda_[k]) < hi_[k] * (1.0 - 1e-9);
    }
    // F_f = −(Gᵀ λ / Δt − D q̇⁺) over the friction channels; the limit rows' impulses are constraint forces.
    friction_torque_.setZero();
    for (int k = 0; k < c; ++k) {
      const Channel& ch = channels_[static_cast<std::size_t>(k)];
      friction_torque_[ch.a] -= lambda_[k] / dt;
      if (ch.kb != 0.0) friction_torque_[ch.b] -= ch.kb * lambda_[k] / dt;
    }
  } else {
    qd_next_ = v_free_;
    friction_torque_.setZero();
  }
  friction_torque_.noalias() += D_.lazyProduct(qd_next_);
  qdd = (qd_next_ - qd) / dt;
  if (payload.mass == 0.0) {
    rigid_body_torque = bias_;
    rigid_body_torque.noalias() += mass_.lazyProduct(qdd);
  } else if (dynamics::inverseDynamics(model_, data_, q, qd, qdd, rigid_body_torque) !=
             dynamics::DynamicsStatus::Success) {
    return SimStatus::InvalidArgument;
  }
  return SimStatus::Ok;
}

void ArmPlant::resetFriction(const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept {
  for (int k = 0; k < channelCount(); ++k) {
    const double u = qd.size() == nq() ? channelValue(k, qd) : 0.0;
    stuck_[static_cast<std::size_t>(k)] = u == 0.0;
    u_previous_[k] = u;
    sigma_[k] = 1.0;
    lambda_[k] = 0.0;
  }
  friction_torque_.setZero();
}

void ArmPlant::measure(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
                       std::mt19937& rng, Eigen::Ref<Eigen::VectorXd> q_measured,
                       Eigen::Ref<Eigen::VectorXd> qd_measured) noexcept {
  for (int i = 0; i < nq(); ++i) {
    q_measured[i] = resolution_[i] > 0.0 ? resolution_[i] * std::round(q[i] / resolution_[i]) : q[i];
    qd_measured[i] = noise_[i] > 0.0 ? qd[i] + noise_[i] * normal_(rng) : qd[i];
  }
}

}  // namespace bimanual_skills::sim
