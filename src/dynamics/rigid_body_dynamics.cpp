#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"

#include <cmath>

namespace bimanual_skills::dynamics {
namespace {

const Eigen::Vector3d kZ = Eigen::Vector3d::UnitZ();

DynamicsStatus check(const ChainModel& model, const Eigen::Ref<const Eigen::VectorXd>& v) noexcept {
  if (v.size() != model.nq()) return DynamicsStatus::WrongSize;
  if (!v.allFinite()) return DynamicsStatus::NotFinite;
  return DynamicsStatus::Success;
}

/// Rotation and translation of every joint frame F_i in F_{i−1} at q (the forward kinematics of the chain,
/// in the internal frames whose z axis is the joint axis).
void jointFrames(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  const auto& steps = model.axisFrames();
  for (int i = 0; i < model.nq(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    const ChainModel::AxisFrame& step = steps[k];
    if (step.prismatic) {
      data.rotation[k] = step.rotation;
      data.translation[k] = step.translation + q[i] * step.rotation.col(2);
    } else {
      kinematics::ChainModel::turnAboutZ(step.rotation, q[i], data.rotation[k]);
      data.translation[k] = step.translation;
    }
  }
}

/// Newton–Euler passes on the frames of jointFrames(): τ for (q̇, q̈) with base acceleration −g (g = gravity, or
/// zero). Luh–Walker–Paul recursion, every vector in its own link frame.
void newtonEuler(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& qd,
                 const Eigen::Ref<const Eigen::VectorXd>& qdd, const Eigen::Vector3d& gravity, const Payload& payload,
                 Eigen::Ref<Eigen::VectorXd> tau) noexcept {
  const int n = model.nq();
  const auto& steps = model.axisFrames();
  Eigen::Vector3d w_prev = Eigen::Vector3d::Zero();
  Eigen::Vector3d dw_prev = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_prev = -gravity;
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const Eigen::Matrix3d& R = data.rotation[k];
    const Eigen::Vector3d& p = data.translation[k];
    const Eigen::Vector3d a_origin = a_prev + dw_prev.cross(p) + w_prev.cross(w_prev.cross(p));
    Eigen::Vector3d w = R.transpose() * w_prev;
    Eigen::Vector3d dw = R.transpose() * dw_prev;
    Eigen::Vector3d a = R.transpose() * a_origin;
    if (steps[k].prismatic) {
      a += qdd[i] * kZ + 2.0 * qd[i] * w.cross(kZ);
    } else {
      dw += qdd[i] * kZ + qd[i] * w.cross(kZ);
      w += qd[i] * kZ;
    }
    data.omega[k] = w;
    data.alpha[k] = dw;
    data.accel[k] = a;
    w_prev = w;
    dw_prev = dw;
    a_prev = a;
  }
  Eigen::Vector3d f_next = Eigen::Vector3d::Zero();
  Eigen::Vector3d n_next = Eigen::Vector3d::Zero();
  for (int i = n - 1; i >= 0; --i) {
    const auto k = static_cast<std::size_t>(i);
    const kinematics::BodyInertia& body = steps[k].body;
    const Eigen::Vector3d& w = data.omega[k];
    const Eigen::Vector3d& dw = data.alpha[k];
    const Eigen::Vector3d a_com = data.accel[k] + dw.cross(body.com) + w.cross(w.cross(body.com));
    Eigen::Vector3d F = body.mass * a_com;
    Eigen::Vector3d N = body.inertia * dw + w.cross(body.inertia * w) + body.com.cross(F);
    if (i == n - 1 && payload.mass > 0.0) {
      const Eigen::Vector3d c = model.tipInLastFrame() * payload.com;
      const Eigen::Vector3d F_payload = payload.mass * (data.accel[k] + dw.cross(c) + w.cross(w.cross(c)));
      F += F_payload;
      N += c.cross(F_payload);
    }
    Eigen::Vector3d f = F;
    Eigen::Vector3d m = N;
    if (i + 1 < n) {
      const Eigen::Matrix3d& R_next = data.rotation[k + 1];
      const Eigen::Vector3d f_child = R_next * f_next;
      f += f_child;
      m += R_next * n_next + data.translation[k + 1].cross(f_child);
    }
    tau[i] = (steps[k].prismatic ? f.z() : m.z()) + model.rotorInertia()[i] * qdd[i];
    f_next = f;
    n_next = m;
  }
}

/// |v|² 1 − v vᵀ: the rotational inertia of a unit point mass at v about the origin.
Eigen::Matrix3d pointInertia(const Eigen::Vector3d& v) noexcept {
  return v.squaredNorm() * Eigen::Matrix3d::Identity() - v * v.transpose();
}

/// Composite-rigid-body algorithm on the frames of jointFrames() (see massMatrix()).
void compositeRigidBody(const ChainModel& model, DynamicsData& data, const Payload& payload) noexcept {
  const int n = model.nq();
  const auto& steps = model.axisFrames();
  // Composite inertias, tip to base: I^c_i = I_i + (the child's composite carried into F_i).
  for (int i = n - 1; i >= 0; --i) {
    const auto k = static_cast<std::size_t>(i);
    double m = steps[k].body.mass;
    Eigen::Vector3d h = steps[k].first_moment;
    Eigen::Matrix3d I = steps[k].origin_inertia;
    if (i == n - 1 && payload.mass > 0.0) {
      const Eigen::Vector3d c = model.tipInLastFrame() * payload.com;
      m += payload.mass;
      h += payload.mass * c;
      I += payload.mass * pointInertia(c);
    }
    if (i + 1 < n) {
      // Child (m', h', I') in F_{i+1} = (R, t) in F_i: h = R h' + m' t, I = R I' Rᵀ + m' K(t) + 2 (R h')·t 1 −
      // (R h') tᵀ − t (R h')ᵀ, the parallel-axis theorem written with the first moment.
      const Eigen::Matrix3d& R = data.rotation[k + 1];
      const Eigen::Vector3d& t = data.translation[k + 1];
      const double mc = data.composite_mass[k + 1];
      const Eigen::Vector3d Rh = R * data.composite_moment[k + 1];
      m += mc;
      h += Rh + mc * t;
      const Eigen::Matrix3d RI = R * data.composite_inertia[k + 1];
      I.noalias() += RI * R.transpose();
      I.diagonal().array() += mc * t.squaredNorm() + 2.0 * Rh.dot(t);
      I.noalias() -= (mc * t + Rh) * t.transpose();
      I.noalias() -= t * Rh.transpose();
    }
    data.composite_mass[k] = m;
    data.composite_moment[k] = h;
    data.composite_inertia[k] = I;
  }
  // Columns: the spatial force (moment n about the origin, force f) of unit motion of joint i, carried inwards.
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const Eigen::Vector3d& h = data.composite_moment[k];
    Eigen::Vector3d f, moment;
    if (steps[k].prismatic) {
      f = data.composite_mass[k] * kZ;  // S = [0; z]: f = m z, n = h × z
      moment = h.cross(kZ);
    } else {
      f = kZ.cross(h);  // S = [z; 0]: n = I_o z, f = z × h
      moment = data.composite_inertia[k].col(2);
    }
    data.mass_matrix(i, i) = (steps[k].prismatic ? f.z() : moment.z()) + model.rotorInertia()[i];
    for (int j = i - 1; j >= 0; --j) {
      const auto c = static_cast<std::size_t>(j + 1);
      f = data.rotation[c] * f;
      moment = data.rotation[c] * moment + data.translation[c].cross(f);
      const double value = steps[static_cast<std::size_t>(j)].prismatic ? f.z() : moment.z();
      data.mass_matrix(i, j) = value;
      data.mass_matrix(j, i) = value;
    }
  }
}

}  // namespace

DynamicsData::DynamicsData(const ChainModel& model)
    : mass_matrix(Eigen::MatrixXd::Zero(model.nq(), model.nq())),
      bias(Eigen::VectorXd::Zero(model.nq())),
      rotation(static_cast<std::size_t>(model.nq()), Eigen::Matrix3d::Identity()),
      translation(static_cast<std::size_t>(model.nq()), Eigen::Vector3d::Zero()),
      omega(static_cast<std::size_t>(model.nq())),
      alpha(static_cast<std::size_t>(model.nq())),
      accel(static_cast<std::size_t>(model.nq())),
      composite_mass(static_cast<std::size_t>(model.nq()), 0.0),
      composite_moment(static_cast<std::size_t>(model.nq()), Eigen::Vector3d::Zero()),
      composite_inertia(static_cast<std::size_t>(model.nq()), Eigen::Matrix3d::Zero()),
      zeros(Eigen::VectorXd::Zero(model.nq())),
      llt(model.nq()) {}

DynamicsStatus inverseDynamics(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& qd,
                               const Eigen::Ref<const Eigen::VectorXd>& qdd, Eigen::Ref<Eigen::VectorXd> tau,
                               const Payload& payload) noexcept {
  for (const auto* v : {&q, &qd, &qdd}) {
    if (const DynamicsStatus status = check(model, *v); status != DynamicsStatus::Success) return status;
  }
  if (tau.size() != model.nq()) return DynamicsStatus::WrongSize;
  jointFrames(model, data, q);
  newtonEuler(model, data, qd, qdd, model.gravity(), payload, tau);
  return DynamicsStatus::Success;
}

DynamicsStatus massMatrix(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                          const Payload& payload) noexcept {
  if (const DynamicsStatus status = check(model, q); status != DynamicsStatus::Success) return status;
  jointFrames(model, data, q);
  compositeRigidBody(model, data, payload);
  return DynamicsStatus::Success;
}

DynamicsStatus coriolisTorques(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& qd, Eigen::Ref<Eigen::VectorXd> c,
                               const Payload& payload) noexcept {
  for (const auto* v : {&q, &qd}) {
    if (const DynamicsStatus status = check(model, *v); status != DynamicsStatus::Success) return status;
  }
  if (c.size() != model.nq()) return DynamicsStatus::WrongSize;
  jointFrames(model, data, q);
  newtonEuler(model, data, qd, data.zeros, Eigen::Vector3d::Zero(), payload, c);
  return DynamicsStatus::Success;
}

DynamicsStatus gravityTorques(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                              Eigen::Ref<Eigen::VectorXd> g, const Payload& payload) noexcept {
  if (const DynamicsStatus status = check(model, q); status != DynamicsStatus::Success) return status;
  if (g.size() != model.nq()) return DynamicsStatus::WrongSize;
  jointFrames(model, data, q);
  newtonEuler(model, data, data.zeros, data.zeros, model.gravity(), payload, g);
  return DynamicsStatus::Success;
}

DynamicsStatus forwardDynamics(const ChainModel& model, DynamicsData& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& qd,
                               const Eigen::Ref<const Eigen::VectorXd>& tau, Eigen::Ref<Eigen::VectorXd> qdd,
                               const Payload& payload) noexcept {
  for (const auto* v : {&q, &qd, &tau}) {
    if (const DynamicsStatus status = check(model, *v); status != DynamicsStatus::Success) return status;
  }
  if (qdd.size() != model.nq()) return DynamicsStatus::WrongSize;
  if (const DynamicsStatus status = massMatrix(model, data, q, payload); status != DynamicsStatus::Success) {
    return status;
  }
  newtonEuler(model, data, qd, data.zeros, model.gravity(), payload, data.bias);  // frames of massMatrix() stand
  data.llt.compute(data.mass_matrix);
  if (data.llt.info() != Eigen::Success) return DynamicsStatus::NotPositiveDefinite;
  qdd = tau - data.bias;
  data.llt.solveInPlace(qdd);
  return DynamicsStatus::Success;
}

}  // namespace bimanual_skills::dynamics
