#include "bimanual_skills/dynamics/friction_model.hpp"

#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>

namespace bimanual_skills::dynamics {
using signal::sign;

const char* toString(FrictionModelType type) noexcept {
  switch (type) {
    case FrictionModelType::Viscous:
      return "viscous";
    case FrictionModelType::Initial:
      return "initial";
    case FrictionModelType::Basic:
      return "basic";
    case FrictionModelType::Advanced:
      return "advanced";
  }
  return "unknown";
}

bool parseFrictionModelType(const std::string& name, FrictionModelType& type) noexcept {
  for (FrictionModelType t : {FrictionModelType::Viscous, FrictionModelType::Initial, FrictionModelType::Basic,
                              FrictionModelType::Advanced}) {
    if (name == toString(t)) {
      type = t;
      return true;
    }
  }
  return false;
}

int linearParameterCount(FrictionModelType type) noexcept {
  switch (type) {
    case FrictionModelType::Viscous:
      return 1;
    case FrictionModelType::Initial:
    case FrictionModelType::Basic:
      return 2;
    case FrictionModelType::Advanced:
      return 13;
  }
  return 0;
}

void JointFriction::validate() const {
  if (b.size() != linearParameterCount(type)) {
    throw std::invalid_argument(std::string("friction model '") + toString(type) + "' needs " +
                                std::to_string(linearParameterCount(type)) + " coefficients b, got " +
                                std::to_string(b.size()));
  }
  if (!b.allFinite() || !std::isfinite(s) || !std::isfinite(z) || !std::isfinite(h)) {
    throw std::invalid_argument(std::string("friction model '") + toString(type) + "': parameters must be finite");
  }
}

void frictionRegressor(const JointFriction& joint, double q, double qd, double accel_sign,
                       Eigen::Ref<Eigen::VectorXd> phi) noexcept {
  switch (joint.type) {
    case FrictionModelType::Viscous:
      phi[0] = qd;
      return;
    case FrictionModelType::Initial:  // (2.13)
      phi[0] = std::atan(joint.s * qd);
      phi[1] = qd;
      return;
    case FrictionModelType::Basic:  // (2.14)
      phi[0] = std::atan(joint.s * qd + joint.z * accel_sign);
      phi[1] = qd;
      return;
    case FrictionModelType::Advanced: {  // (4.16)
      phi[0] = q;
      phi[1] = qd;
      phi[2] = std::atan(joint.s * qd + joint.z * accel_sign);
      const double positive = 0.5 * (1.0 + sign(qd));
      const double negative = 0.5 * (1.0 - sign(qd));
      // sin(k h q) for k = 1, 3, ..., 9 from one sin/cos pair by the angle-addition recurrence
      // sin((k + 2) x) = sin(k x) cos(2 x) + cos(k x) sin(2 x): one libm call instead of five.
      const double x = joint.h * q;
      double sin_k = std::sin(x);
      double cos_k = std::cos(x);
      const double sin_2 = 2.0 * sin_k * cos_k;
      const double cos_2 = 1.0 - 2.0 * sin_k * sin_k;
      for (int j = 1; j <= 5; ++j) {
        const double k = 2.0 * j - 1.0;
        const double f = 4.0 * sin_k / (M_PI * k);
        phi[2 + j] = positive * f;
        phi[7 + j] = negative * f;
        const double sin_next = sin_k * cos_2 + cos_k * sin_2;
        cos_k = cos_k * cos_2 - sin_k * sin_2;
        sin_k = sin_next;
      }
      return;
    }
  }
}

double frictionTorque(const JointFriction& joint, double q, double qd, double accel_sign) noexcept {
  double phi_storage[13];
  Eigen::Map<Eigen::VectorXd> phi(phi_storage, linearParameterCount(joint.type));
  frictionRegressor(joint, q, qd, accel_sign, phi);
  return joint.b.dot(phi);
}

void FrictionModel::validate() const {
  for (std::size_t i = 0; i < joints.size(); ++i) {
    try {
      joints[i].validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("joint " + std::to_string(i + 1) + ": " + e.what());
    }
  }
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const CoupledPair& pair = pairs[k];
    const std::string where = "coupled pair " + std::to_string(k + 1) + ": ";
    if (pair.first < 0 || pair.second < 0 || pair.first >= size() || pair.second >= size() ||
        pair.first == pair.second) {
      throw std::invalid_argument(where + "joint indices must be two different joints of the chain");
    }
    if (!(pair.epsilon >= 0.0) || !std::isfinite(pair.epsilon)) {
      throw std::invalid_argument(where + "epsilon must be a finite number >= 0");
    }
    pair.reduced_first.validate();
    pair.reduced_second.validate();
  }
}

FrictionState::FrictionState(const FrictionModel& model) : reduced(static_cast<std::size_t>(model.size()), 0) {}

void updatePairModes(const FrictionModel& model, FrictionState& state,
                     const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept {
  // Sec. 4.2.2: A while |q̇_i| ≥ |q̇_j| + ε, B while |q̇_j| ≥ |q̇_i| + ε, unchanged in between.
  for (const CoupledPair& pair : model.pairs) {
    const double a = std::abs(qd[pair.first]);
    const double b = std::abs(qd[pair.second]);
    for (const auto& [i, vi, vj] : {std::tuple{pair.first, a, b}, std::tuple{pair.second, b, a}}) {
      if (vi >= vj + pair.epsilon) {
        state.reduced[static_cast<std::size_t>(i)] = 0;
      } else if (vj >= vi + pair.epsilon) {
        state.reduced[static_cast<std::size_t>(i)] = 1;
      }
    }
  }
}

const JointFriction& activeJointModel(const FrictionModel& model, const FrictionState& state, int joint) noexcept {
  if (state.reduced[static_cast<std::size_t>(joint)]) {
    for (const CoupledPair& pair : model.pairs) {
      if (pair.first == joint) return pair.reduced_first;
      if (pair.second == joint) return pair.reduced_second;
    }
  }
  return model.joints[static_cast<std::size_t>(joint)];
}

DynamicsStatus frictionTorques(const FrictionModel& model, FrictionState& state,
                               const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
                               const Eigen::Ref<const Eigen::VectorXd>& accel_sign,
                               Eigen::Ref<Eigen::VectorXd> tau) noexcept {
  const int n = model.size();
  if (q.size() != n || qd.size() != n || accel_sign.size() != n || tau.size() != n ||
      state.reduced.size() != static_cast<std::size_t>(n)) {
    return DynamicsStatus::WrongSize;
  }
  if (!q.allFinite() || !qd.allFinite() || !accel_sign.allFinite()) return DynamicsStatus::NotFinite;
  updatePairModes(model, state, qd);
  for (int i = 0; i < n; ++i) tau[i] = frictionTorque(activeJointModel(model, state, i), q[i], qd[i], accel_sign[i]);
  return DynamicsStatus::Success;
}

}  // namespace bimanual_skills::dynamics
