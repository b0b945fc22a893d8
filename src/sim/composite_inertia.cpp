#include "composite_inertia.hpp"

#include <cmath>

namespace bimanual_skills::sim {
namespace {

/// S(r) = |r|² I − r rᵀ: the rotational inertia of a unit point mass at r about the origin.
Eigen::Matrix3d pointInertia(const Eigen::Vector3d& r) {
  return r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose();
}

}  // namespace

CompositeInertiaData::CompositeInertiaData(const kinematics::ChainModel& model)
    : rotation(static_cast<std::size_t>(model.nq()), Eigen::Matrix3d::Identity()),
      translation(static_cast<std::size_t>(model.nq()), Eigen::Vector3d::Zero()),
      mass(static_cast<std::size_t>(model.nq()), 0.0),
      first_moment(static_cast<std::size_t>(model.nq()), Eigen::Vector3d::Zero()),
      inertia(static_cast<std::size_t>(model.nq()), Eigen::Matrix3d::Zero()) {}

void compositeMassMatrix(const kinematics::ChainModel& model, CompositeInertiaData& data,
                         const Eigen::Ref<const Eigen::VectorXd>& q, const dynamics::Payload& payload,
                         Eigen::Ref<Eigen::MatrixXd> M) noexcept {
  const int n = model.nq();
  const auto& steps = model.axisFrames();
  // Joint frames at q (as dynamics::inverseDynamics: a rotation about z, or a translation along z, per joint).
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const kinematics::ChainModel::AxisFrame& step = steps[k];
    if (step.prismatic) {
      data.rotation[k] = step.rotation;
      data.translation[k] = step.translation + q[i] * step.rotation.col(2);
    } else {
      const double c = std::cos(q[i]), s = std::sin(q[i]);
      Eigen::Matrix3d& R = data.rotation[k];
      R.col(0) = c * step.rotation.col(0) + s * step.rotation.col(1);
      R.col(1) = c * step.rotation.col(1) - s * step.rotation.col(0);
      R.col(2) = step.rotation.col(2);
      data.translation[k] = step.translation;
    }
  }
  // Composite bodies, tip to base: (m, h = m c, Ī about the frame origin).
  for (int i = n - 1; i >= 0; --i) {
    const auto k = static_cast<std::size_t>(i);
    const kinematics::BodyInertia& body = steps[k].body;
    double m = body.mass;
    Eigen::Vector3d h = body.mass * body.com;
    Eigen::Matrix3d I = body.inertia + body.mass * pointInertia(body.com);
    if (i == n - 1 && payload.mass > 0.0) {
      const Eigen::Vector3d c = model.tipInLastFrame() * payload.com;
      m += payload.mass;
      h += payload.mass * c;
      I += payload.mass * pointInertia(c);
    }
    if (i + 1 < n) {
      const Eigen::Matrix3d& R = data.rotation[k + 1];
      const Eigen::Vector3d& p = data.translation[k + 1];
      const double mc = data.mass[k + 1];
      const Eigen::Vector3d hc = R * data.first_moment[k + 1];
      m += mc;
      h += hc + mc * p;
      I += R * data.inertia[k + 1] * R.transpose() + mc * pointInertia(p) +
           2.0 * p.dot(hc) * Eigen::Matrix3d::Identity() - p * hc.transpose() - hc * p.transpose();
    }
    data.mass[k] = m;
    data.first_moment[k] = h;
    data.inertia[k] = I;
  }
  // Column i: the spatial force of a unit acceleration of joint i on composite body i, carried to the base.
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    Eigen::Vector3d F, N;
    if (steps[k].prismatic) {
      F = data.mass[k] * z;
      N = data.first_moment[k].cross(z);
    } else {
      F = z.cross(data.first_moment[k]);
      N = data.inertia[k] * z;
    }
    M(i, i) = (steps[k].prismatic ? F.z() : N.z()) + model.rotorInertia()[i];
    for (int j = i - 1; j >= 0; --j) {
      const auto kk = static_cast<std::size_t>(j + 1);
      const Eigen::Vector3d F_parent = data.rotation[kk] * F;
      N = data.rotation[kk] * N + data.translation[kk].cross(F_parent);
      F = F_parent;
      M(j, i) = M(i, j) = steps[static_cast<std::size_t>(j)].prismatic ? F.z() : N.z();
    }
  }
}

}  // namespace bimanual_skills::sim
