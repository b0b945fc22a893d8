// Joint-limit schemes of the CLIK solver (thesis Sec. 3.1.3–3.1.4), one step function each.
#include "clik_internal.hpp"

#include <cmath>

namespace bimanual_skills::kinematics::clik_detail {
namespace {

/// ∂H_i/∂q_i of one joint's limit criterion H_i = (q_max − q_min)² / (4 (q_max − q_i)(q_i − q_min)) (thesis eqs. 3.16,
/// 3.19): (q_max − q_min)² (2 q_i − q_max − q_min) / (4 f²), f = (q_max − q_i)(q_i − q_min), with |f| kept above
/// 1e-12. It points away from the range centre, also beyond the limits (decaying with the distance there).
double limitCriterionGradient(double lo, double hi, double q) noexcept {
  double f = (hi - q) * (q - lo);
  if (std::abs(f) < 1e-12) f = 1e-12;
  return (hi - lo) * (hi - lo) * (2.0 * q - hi - lo) / (4.0 * f * f);
}

/// Gradient of the joint-centring function of thesis eq. 3.19, which grows towards the range centre:
/// ∂H/∂q_i = −(2/n) ∂H_i/∂q_i = (q_max − q_min)² (q_max + q_min − 2 q_i) / (2n f_i²). Taken literally
/// beyond the limits too (it still points to the centre there); only f = 0 is kept away from. Clamping q inside the
/// range instead makes steps of hundreds of radians near the limits (measured: GP then solved 19 % of Table 3.5
/// problems instead of 100 %).
void centringGradient(const ChainModel& model, const Eigen::Ref<const Eigen::VectorXd>& q,
                      Eigen::Ref<Eigen::VectorXd> out) noexcept {
  const int n = model.nq();
  for (int i = 0; i < n; ++i) {
    const double lo = model.lowerLimits()[i];
    const double hi = model.upperLimits()[i];
    out[i] = std::isfinite(lo) && std::isfinite(hi) && hi > lo ? -2.0 / n * limitCriterionGradient(lo, hi, q[i]) : 0.0;
  }
}

/// Chan & Dubey's joint weights (3.16): w_i = 1 + |∂H_i/∂q_i| while |∂H_i/∂q_i| grows (moving towards a limit),
/// else 1; writes W^{-1/2} into data.scale.
void jointWeights(const ChainModel& model, const Eigen::Ref<const Eigen::VectorXd>& q, ClikData& data) noexcept {
  for (int i = 0; i < model.nq(); ++i) {
    const double lo = model.lowerLimits()[i];
    const double hi = model.upperLimits()[i];
    if (!std::isfinite(lo) || !std::isfinite(hi)) {
      data.scale[i] = 1.0;
      continue;
    }
    // Beyond a limit the criterion is undefined: no weighting there (JW does not enforce limits, Table 3.5).
    const double gradient = q[i] > lo && q[i] < hi ? std::abs(limitCriterionGradient(lo, hi, q[i])) : 0.0;
    const double weight = gradient >= data.previous_gradient[i] ? 1.0 + gradient : 1.0;
    data.previous_gradient[i] = gradient;
    data.scale[i] = 1.0 / std::sqrt(weight);
  }
}

/// Activation h_β of every joint into data.activation (the centres are in data.centre).
void activations(const ChainModel& model, double beta, const Eigen::Ref<const Eigen::VectorXd>& q,
                 ClikData& data) noexcept {
  for (int i = 0; i < model.nq(); ++i) {
    data.activation[i] = limitActivation(q[i], model.lowerLimits()[i], model.upperLimits()[i], beta);
  }
}

ThinSvd& fullSvd(ClikData& data) noexcept {
  return data.svd_by_columns.back();
}

}  // namespace

bool stepWithoutLimits(const ClikParameters& p, double E, ClikData& data) noexcept {
  // Δq = J* e (Table 3.4).
  return applyInverse(p, p.inverse, fullSvd(data), data.jacobian, data.task, E, data, data.dq);
}

bool stepJointWeighting(const ChainModel& model, const ClikParameters& p, double E, ClikData& data,
                        const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  // (3.16): Δq = W^{-1/2} (J W^{-1/2})* e.
  jointWeights(model, q, data);
  data.columns = data.jacobian * data.scale.asDiagonal();
  if (!applyInverse(p, p.inverse, fullSvd(data), data.columns, data.task, E, data, data.task_step)) return false;
  data.dq = data.scale.cwiseProduct(data.task_step);
  return true;
}

bool stepGradientProjection(const ChainModel& model, const ClikParameters& p, double E, ClikData& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  // (3.17): Δq = J* e + μ (I − J† J) ∇H, the projection onto ker J with the ordinary pseudoinverse of the same
  // decomposition.
  ThinSvd& svd = fullSvd(data);
  if (!applyInverse(p, p.inverse, svd, data.jacobian, data.task, E, data, data.task_step)) return false;
  // The transpose and the damped operators do not decompose J: the projection needs its SVD.
  const bool decomposed = p.inverse != InverseOperator::Transpose && p.inverse != InverseOperator::Damping &&
                          p.inverse != InverseOperator::ErrorDamping &&
                          p.inverse != InverseOperator::ImprovedErrorDamping;
  if (!decomposed && !svd.compute(data.jacobian)) return false;
  centringGradient(model, q, data.centring_gradient);
  data.task_image.noalias() = data.jacobian * data.centring_gradient;
  computeGains(p, InverseOperator::Pseudoinverse, svd, E, data);
  applyGains(svd, data, data.task_image, data.null_space_part);
  data.dq = data.task_step + p.gp_gain * (data.centring_gradient - data.null_space_part);
  return true;
}

bool stepJointClamping(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                       const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  // (3.20): Δq = A (J A)* e, A = I − H_β.
  activations(model, beta, q, data);
  data.scale = Eigen::VectorXd::Ones(model.nq()) - data.activation;
  data.columns = data.jacobian * data.scale.asDiagonal();
  if (!applyInverse(p, p.inverse, fullSvd(data), data.columns, data.task, E, data, data.task_step)) return false;
  data.dq = data.scale.cwiseProduct(data.task_step);
  return true;
}

bool stepTaskAugmentation(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                          const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  // J extended with the rows h_i e_iᵀ, e with the push-to-centre errors −λ_JL h_i (q_i − q_c,i).
  activations(model, beta, q, data);
  const int n = model.nq();
  const int m = static_cast<int>(data.task.size());
  data.augmented.topRows(m) = data.jacobian;
  data.augmented.bottomRows(n) = data.activation.asDiagonal();
  data.augmented_task.head(m) = data.task;
  data.augmented_task.tail(n) = -p.lambda_jl * data.activation.cwiseProduct(q - data.centre);
  return applyInverse(p, p.inverse, data.svd_augmented, data.augmented, data.augmented_task, E, data, data.dq);
}

bool stepTaskPriority(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                      const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  // (3.18) with J1 = H_β, e1 = −λ_JL (q − q_c), ordinary pseudoinverses: J1^† = diag(1/h_i) on active joints.
  activations(model, beta, q, data);
  for (int i = 0; i < model.nq(); ++i) {
    const double h = data.activation[i];
    data.limit_step[i] = h > 0.0 ? -p.lambda_jl * (q[i] - data.centre[i]) / h : 0.0;
    data.scale[i] = h > 0.0 ? 0.0 : 1.0;  // P1 = I − J1^† J1
  }
  data.columns = data.jacobian * data.scale.asDiagonal();
  data.task_residual.noalias() = data.task - data.jacobian * data.limit_step;
  if (!applyInverse(p, p.inverse, fullSvd(data), data.columns, data.task_residual, E, data, data.task_step)) {
    return false;
  }
  data.dq = data.limit_step + data.scale.cwiseProduct(data.task_step);
  return true;
}

bool stepContinuousTaskPriority(const ChainModel& model, const ClikParameters& p, double beta, double E, ClikData& data,
                                const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  activations(model, beta, q, data);
  data.limit_step = -p.lambda_jl * data.activation.cwiseProduct(q - data.centre);  // Δq1 = H (−λ (q − q_c))
  data.scale = Eigen::VectorXd::Ones(model.nq()) - data.activation;                // task activation I − H
  const InverseOperator inner = p.inverse == InverseOperator::SelectiveDamping ? InverseOperator::Pseudoinverse
                                : p.inverse == InverseOperator::SvfSelectiveDamping
                                    ? InverseOperator::SingularValueFilter
                                    : p.inverse;
  continuousPseudoinverse(p, data, data.jacobian, data.scale, inner, E, data.inverse);
  if (!data.inverse.allFinite()) return false;
  if (!isSelectiveDamping(p.inverse)) {
    // (3.28): Δq = Δq1 + J^{(I−H)⊕} (e − J Δq1).
    data.task_residual.noalias() = data.task - data.jacobian * data.limit_step;
    data.dq.noalias() = data.limit_step + data.inverse * data.task_residual;
    return true;
  }
  // (3.39): Δq̂ = (I − J^⊕ J) Δq1 + Σ_s clamp(w_s), the w_s from the SVD of J^⊕ (3.31–3.38); then (3.40).
  data.column_norms = data.jacobian.colwise().norm().transpose();
  if (data.transitional.empty() && !data.selected.empty()) {
    // No joint in transition: J^⊕ = Σ g_i (scattered v_i) u_iᵀ is already an SVD (the scattered v_i stay
    // orthonormal), so the one of J_Q serves and no second decomposition is needed.
    const int c = data.selected.size();
    const ThinSvd& svd = data.svd_by_columns[static_cast<std::size_t>(c - 1)];
    const Eigen::Index r = svd.singularValues().size();
    data.scattered.setZero();
    for (int row = 0; row < c; ++row) data.scattered.row(data.selected[row]).head(r) = svd.V().row(row);
    selectiveDampingSum(data.gains.head(r), data.scattered.leftCols(r), svd.U(), data.column_norms, data.task,
                        p.gamma_max, data.component, data.task_step);
  } else {
    if (!data.svd_inverse.compute(data.inverse)) return false;
    selectiveDampingSum(data.svd_inverse.singularValues(), data.svd_inverse.U(), data.svd_inverse.V(),
                        data.column_norms, data.task, p.gamma_max, data.component, data.task_step);
  }
  data.task_image.noalias() = data.jacobian * data.limit_step;
  data.dq = data.limit_step + data.task_step;
  data.dq.noalias() -= data.inverse * data.task_image;
  clampMaxAbs(data.dq, p.gamma_max);
  return true;
}

}  // namespace bimanual_skills::kinematics::clik_detail
