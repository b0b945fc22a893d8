/// \file
/// Internal building blocks of the CLIK solver (src/kinematics/clik*.cpp): the inverse operators applied to a
/// matrix, the selective-damping sum and one step function per joint-limit scheme. Not installed.
#pragma once

#include "bimanual_skills/kinematics/clik.hpp"

namespace bimanual_skills::kinematics::clik_detail {

inline bool isSelectiveDamping(InverseOperator op) noexcept {
  return op == InverseOperator::SelectiveDamping || op == InverseOperator::SvfSelectiveDamping;
}

/// Scales v so that max_i |v_i| ≤ bound (Buss & Kim's ClampMaxAbs).
void clampMaxAbs(Eigen::Ref<Eigen::VectorXd> v, double bound) noexcept;

/// Fills data.gains.head(r) with the operator gains of the singular values of `svd`.
void computeGains(const ClikParameters& p, InverseOperator op, const ThinSvd& svd, double E, ClikData& data) noexcept;

/// out = Σ_i g_i v_i (u_iᵀ e) with the gains in data.gains.
void applyGains(const ThinSvd& svd, const ClikData& data, const Eigen::Ref<const Eigen::VectorXd>& e,
                Eigen::Ref<Eigen::VectorXd> out) noexcept;

/// Selective damping sum (Buss & Kim; thesis eqs. 3.35–3.38) for an inverse written as Σ_s τ_s a_s b_sᵀ:
/// w_s = τ_s a_s (b_sᵀ e), M_s = τ_s Σ_j |a_{js}| ‖J^j‖, γ_s = min(1, 1/M_s) γ_max, each w_s clamped to γ_s.
/// `w` is the scratch of one component.
void selectiveDampingSum(const Eigen::Ref<const Eigen::VectorXd>& tau, const Eigen::Ref<const Eigen::MatrixXd>& A,
                         const Eigen::Ref<const Eigen::MatrixXd>& B, const Eigen::Ref<const Eigen::VectorXd>& norms,
                         const Eigen::Ref<const Eigen::VectorXd>& e, double gamma_max, Eigen::Ref<Eigen::VectorXd> w,
                         Eigen::Ref<Eigen::VectorXd> out) noexcept;

/// out = A* e for the operator `op`, decomposing A with `svd` (sized for A). False if A is not finite or a
/// factorisation fails.
bool applyInverse(const ClikParameters& p, InverseOperator op, ThinSvd& svd, const Eigen::Ref<const Eigen::MatrixXd>& A,
                  const Eigen::Ref<const Eigen::VectorXd>& e, double E, ClikData& data,
                  Eigen::Ref<Eigen::VectorXd> out) noexcept;

/// The step Δq of each limit scheme into data.dq, from the weighted task error and Jacobian left by evaluate(), with
/// activation buffer `beta` and E = ½ eᵀe. False on a numerical failure.
bool stepWithoutLimits(const ClikParameters& p, double E, ClikData& data) noexcept;
bool stepJointWeighting(const ChainModel& model, const ClikParameters& p, double E, ClikData& data,
                        const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
bool stepGradientProjection(const ChainModel& model, const ClikParameters& p, double E, ClikData& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
bool stepJointClamping(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                       const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
bool stepTaskAugmentation(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                          const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
bool stepTaskPriority(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                      const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
bool stepContinuousTaskPriority(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                                const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;

}  // namespace bimanual_skills::kinematics::clik_detail
