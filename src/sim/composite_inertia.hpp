/// \file
/// Internal: the joint-space mass matrix by the composite-rigid-body algorithm (Featherstone, RBDA ch. 6), for the
/// simulator's per-step dynamics. Same model conventions as dynamics::massMatrix (which runs n Newton–Euler passes
/// and is the reference in the tests); about four times cheaper on the WAM. Candidate to move into dynamics/.
#pragma once

#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"

#include <vector>

namespace bimanual_skills::sim {

/// Scratch of compositeMassMatrix(), sized once from a model.
struct CompositeInertiaData {
  explicit CompositeInertiaData(const kinematics::ChainModel& model);
  std::vector<Eigen::Matrix3d> rotation;      ///< F_{i−1} → F_i at q.
  std::vector<Eigen::Vector3d> translation;   ///< Origin of F_i in F_{i−1}.
  std::vector<double> mass;                   ///< Composite mass of bodies i..n−1.
  std::vector<Eigen::Vector3d> first_moment;  ///< Composite m·c, in F_i.
  std::vector<Eigen::Matrix3d> inertia;       ///< Composite rotational inertia about the origin of F_i, in F_i.
};

/// M(q) (rotor inertias of the model on the diagonal, the payload at the tip) into `M` (n × n).
/// Real-time safe: no allocation, no exceptions. Sizes are the caller's responsibility.
void compositeMassMatrix(const kinematics::ChainModel& model, CompositeInertiaData& data,
                         const Eigen::Ref<const Eigen::VectorXd>& q, const dynamics::Payload& payload,
                         Eigen::Ref<Eigen::MatrixXd> M) noexcept;

}  // namespace bimanual_skills::sim
