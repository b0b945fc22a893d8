#include "bimanual_skills/kinematics/clik.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::kinematics {
namespace {

bool isSelectiveDamping(InverseOperator op) noexcept {
  return op == InverseOperator::SelectiveDamping || op == InverseOperator::SvfSelectiveDamping;
}

/// Singular value filter h_{ν,σ0}(σ) (thesis eq. 3.11): h(0) = σ0, h(σ) → σ for large σ.
double svfFilter(double sigma, double sigma0, double nu) noexcept {
  return (sigma * sigma * sigma + nu * sigma * sigma + 2.0 * sigma + 2.0 * sigma0) / (sigma * sigma + nu * sigma + 2.0);
}

}  // namespace

double inverseOperatorGain(const ClikParameters& p, InverseOperator op, double sigma, double sigma_min,
                           double E) noexcept {
  const auto pinv = [&](double s) { return s > p.pinv_tolerance ? 1.0 / s : 0.0; };
  switch (op) {
    case InverseOperator::Pseudoinverse:
    case InverseOperator::SelectiveDamping:
      return pinv(sigma);
    case InverseOperator::Transpose:
      return sigma;
    case InverseOperator::Damping:
      return sigma / (sigma * sigma + p.lambda * p.lambda);
    case InverseOperator::Filtering: {
      // (3.6): damping only inside the singular region σ_min < ε.
      if (sigma_min >= p.filter_epsilon) return pinv(sigma);
      const double ratio = sigma_min / p.filter_epsilon;
      return sigma / (sigma * sigma + (1.0 - ratio * ratio) * p.lambda_max * p.lambda_max);
    }
    case InverseOperator::ErrorDamping:
      return sigma / (sigma * sigma + E);
    case InverseOperator::ImprovedErrorDamping:
      return sigma / (sigma * sigma + E + p.ied_omega);
    case InverseOperator::SingularValueFilter:
    case InverseOperator::SvfSelectiveDamping:
      return 1.0 / svfFilter(sigma, p.sigma0, p.nu);
    case InverseOperator::SvfErrorDamping: {
      const double h = svfFilter(sigma, p.sigma0, p.nu);
      return h / (h * h + E);
    }
  }
  return 0.0;
}

namespace {

/// Scales v so that max_i |v_i| ≤ bound (Buss & Kim's ClampMaxAbs).
void clampMaxAbs(Eigen::Ref<Eigen::VectorXd> v, double bound) noexcept {
  const double largest = v.cwiseAbs().maxCoeff();
  if (largest > bound) v *= bound / largest;
}

/// Fills data.gains.head(r) with the operator gains of the singular values of `svd`.
void computeGains(const ClikParameters& p, InverseOperator op, const ThinSvd& svd, double E, ClikData& data) noexcept {
  const Eigen::VectorXd& sigma = svd.singularValues();
  const double sigma_min = sigma.size() > 0 ? sigma.minCoeff() : 0.0;
  for (Eigen::Index i = 0; i < sigma.size(); ++i) data.gains[i] = inverseOperatorGain(p, op, sigma[i], sigma_min, E);
}

/// out = Σ_i g_i v_i (u_iᵀ e) with the gains in data.gains.
void applyGains(const ThinSvd& svd, const ClikData& data, const Eigen::Ref<const Eigen::VectorXd>& e,
                Eigen::Ref<Eigen::VectorXd> out) noexcept {
  out.setZero();
  const Eigen::MatrixXd& U = svd.U();
  const Eigen::MatrixXd& V = svd.V();
  for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i) {
    out.noalias() += (data.gains[i] * U.col(i).dot(e)) * V.col(i);
  }
}

/// Selective damping sum (Buss & Kim; thesis eqs. 3.35–3.38) for an inverse written as Σ_s τ_s a_s b_sᵀ:
/// w_s = τ_s a_s (b_sᵀ e), M_s = τ_s Σ_j |a_{js}| ‖J^j‖, γ_s = min(1, 1/M_s) γ_max, each w_s clamped to γ_s.
void selectiveDampingSum(const Eigen::Ref<const Eigen::VectorXd>& tau, const Eigen::Ref<const Eigen::MatrixXd>& A,
                         const Eigen::Ref<const Eigen::MatrixXd>& B, const Eigen::Ref<const Eigen::VectorXd>& norms,
                         const Eigen::Ref<const Eigen::VectorXd>& e, double gamma_max, Eigen::Ref<Eigen::VectorXd> w,
                         Eigen::Ref<Eigen::VectorXd> out) noexcept {
  out.setZero();
  for (Eigen::Index s = 0; s < tau.size(); ++s) {
    if (tau[s] == 0.0) continue;
    w.noalias() = (tau[s] * B.col(s).dot(e)) * A.col(s);
    const double M = tau[s] * A.col(s).cwiseAbs().dot(norms);
    clampMaxAbs(w, (M > 1.0 ? 1.0 / M : 1.0) * gamma_max);
    out += w;
  }
}

/// out = A* e for the operator `op`, decomposing A with `svd` (sized for A). False if A is not finite.
bool applyInverse(const ClikParameters& p, InverseOperator op, ThinSvd& svd, const Eigen::Ref<const Eigen::MatrixXd>& A,
                  const Eigen::Ref<const Eigen::VectorXd>& e, double E, ClikData& data,
                  Eigen::Ref<Eigen::VectorXd> out) noexcept {
  if (op == InverseOperator::Transpose) {
    // (3.1) with Buss's step length α = ⟨e, J Jᵀ e⟩ / ‖J Jᵀ e‖², which minimises ‖e − α J Jᵀ e‖: a unit gain
    // diverges as soon as σ_max² > 2, as it is for the WAM.
    if (!A.allFinite()) return false;
    out.noalias() = A.transpose() * e;
    auto JJte = data.rows.head(A.rows());
    JJte.noalias() = A * out;
    const double norm2 = JJte.squaredNorm();
    out *= norm2 > 0.0 ? e.dot(JJte) / norm2 : 0.0;
    return true;
  }
  if ((op == InverseOperator::Damping || op == InverseOperator::ErrorDamping ||
       op == InverseOperator::ImprovedErrorDamping) &&
      A.rows() == data.task.size()) {
    // σ / (σ² + c) gains are J^T (J J^T + c I)^{-1} (3.3, 3.7, 3.8): one m × m Cholesky instead of an SVD.
    const double c = op == InverseOperator::Damping        ? p.lambda * p.lambda
                     : op == InverseOperator::ErrorDamping ? E
                                                           : E + p.ied_omega;
    if (c > 0.0) {
      if (!A.allFinite()) return false;
      data.gram.noalias() = A * A.transpose();
      data.gram.diagonal().array() += c;
      data.gram_llt.compute(data.gram);
      auto y = data.rows.head(A.rows());
      y = data.gram_llt.solve(e);
      out.noalias() = A.transpose() * y;
      return data.gram_llt.info() == Eigen::Success;
    }
  }
  if (!svd.compute(A)) return false;
  computeGains(p, op, svd, E, data);
  if (!isSelectiveDamping(op)) {
    applyGains(svd, data, e, out);
    return true;
  }
  const Eigen::Index c = A.cols();
  const Eigen::Index r = svd.singularValues().size();
  data.column_norms.head(c) = A.colwise().norm().transpose();
  selectiveDampingSum(data.gains.head(r), svd.V(), svd.U(), data.column_norms.head(c), e, p.gamma_max, data.n3.head(c),
                      out);
  clampMaxAbs(out, p.gamma_max);  // (3.40)
  return true;
}

/// Gradient of the joint-centring function H (thesis eq. 3.19), which grows towards the range centre:
/// ∂H/∂q_i = (q_max − q_min)² (q_max + q_min − 2 q_i) / (2n f_i²), f_i = (q_max − q_i)(q_i − q_min).
/// Taken literally beyond the limits too (it still points to the centre there, decaying with distance); only f = 0
/// is kept away from. Clamping q inside the range instead makes steps of hundreds of radians near the limits
/// (measured: GP then solved 19 % of Table 3.5 problems instead of 100 %).
void centringGradient(const ChainModel& model, const Eigen::Ref<const Eigen::VectorXd>& q,
                      Eigen::Ref<Eigen::VectorXd> out) noexcept {
  const int n = model.nq();
  for (int i = 0; i < n; ++i) {
    const double lo = model.lowerLimits()[i];
    const double hi = model.upperLimits()[i];
    if (!std::isfinite(lo) || !std::isfinite(hi) || hi <= lo) {
      out[i] = 0.0;
      continue;
    }
    const double range = hi - lo;
    const double qi = q[i];
    double f = (hi - qi) * (qi - lo);
    if (std::abs(f) < 1e-12) f = 1e-12;
    out[i] = range * range * (hi + lo - 2.0 * qi) / (2.0 * n * f * f);
  }
}

/// Chan & Dubey's joint weights (3.16): w_i = 1 + |∂H/∂q_i| while |∂H/∂q_i| grows (moving towards a limit), else 1,
/// with H = Σ (q_max − q_min)² / (4 (q_max − q_i)(q_i − q_min)); writes W^{-1/2} into data.scale.
void jointWeights(const ChainModel& model, const Eigen::Ref<const Eigen::VectorXd>& q, ClikData& data) noexcept {
  for (int i = 0; i < model.nq(); ++i) {
    const double lo = model.lowerLimits()[i];
    const double hi = model.upperLimits()[i];
    if (!std::isfinite(lo) || !std::isfinite(hi)) {
      data.scale[i] = 1.0;
      continue;
    }
    // Beyond a limit the criterion is undefined: no weighting there (JW does not enforce limits, Table 3.5).
    double gradient = 0.0;
    if (q[i] > lo && q[i] < hi) {
      const double a = hi - q[i];
      const double b = q[i] - lo;
      gradient = std::abs((hi - lo) * (hi - lo) * (2.0 * q[i] - hi - lo) / (4.0 * a * a * b * b));
    }
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

/// FK, Jacobian and weighted task error at q. False on invalid input.
bool evaluate(const ChainModel& model, const ClikParameters& p, ClikData& data,
              const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Isometry3d& target) noexcept {
  if (!target.matrix().allFinite()) return false;
  if (computeJacobian(model, data.kinematics, q) != KinematicsStatus::Success) return false;
  const int m = taskDimension(p.mode);
  poseError(data.kinematics.tipPose(), target, p.mode, data.error);
  data.task = data.error;
  data.jacobian = data.kinematics.jacobian.topRows(m);
  if (p.mode == TaskMode::Pose) {
    data.task.tail<3>() *= p.rotation_weight;
    data.jacobian.bottomRows<3>() *= p.rotation_weight;
  }
  return true;
}

/// The step of the configured scheme with activation buffer `beta`, from the state left by evaluate(). False on a
/// numerical failure.
bool computeStep(const ChainModel& model, const ClikParameters& p, double beta, ClikData& data,
                 const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  const int n = model.nq();
  const double E = 0.5 * data.task.squaredNorm();
  ThinSvd& full = data.svd_by_columns.back();
  Eigen::VectorXd& dq = data.dq;
  switch (p.limits) {
    case LimitScheme::None:
      if (!applyInverse(p, p.inverse, full, data.jacobian, data.task, E, data, dq)) return false;
      break;
    case LimitScheme::JointWeighting:
      jointWeights(model, q, data);
      data.columns = data.jacobian * data.scale.asDiagonal();
      if (!applyInverse(p, p.inverse, full, data.columns, data.task, E, data, data.n1)) return false;
      dq = data.scale.cwiseProduct(data.n1);
      break;
    case LimitScheme::GradientProjection: {
      if (!applyInverse(p, p.inverse, full, data.jacobian, data.task, E, data, data.n1)) return false;
      // Projection onto ker J with the ordinary pseudoinverse of the same decomposition.
      centringGradient(model, q, data.n2);
      data.m1.noalias() = data.jacobian * data.n2;
      computeGains(p, InverseOperator::Pseudoinverse, full, E, data);
      applyGains(full, data, data.m1, data.n3);
      dq = data.n1 + p.gp_gain * (data.n2 - data.n3);
      break;
    }
    case LimitScheme::JointClamping:
      activations(model, beta, q, data);
      data.scale = Eigen::VectorXd::Ones(n) - data.activation;
      data.columns = data.jacobian * data.scale.asDiagonal();
      if (!applyInverse(p, p.inverse, full, data.columns, data.task, E, data, data.n1)) return false;
      dq = data.scale.cwiseProduct(data.n1);
      break;
    case LimitScheme::TaskAugmentation: {
      activations(model, beta, q, data);
      const int m = static_cast<int>(data.task.size());
      data.augmented.topRows(m) = data.jacobian;
      data.augmented.bottomRows(n) = data.activation.asDiagonal();
      data.augmented_task.head(m) = data.task;
      data.augmented_task.tail(n) = -p.lambda_jl * data.activation.cwiseProduct(q - data.centre);
      if (!applyInverse(p, p.inverse, data.svd_augmented, data.augmented, data.augmented_task, E, data, dq)) {
        return false;
      }
      break;
    }
    case LimitScheme::TaskPriority: {
      // (3.18) with J1 = H_β, e1 = −λ_JL (q − q_c), ordinary pseudoinverses: J1^† = diag(1/h_i) on active joints.
      activations(model, beta, q, data);
      for (int i = 0; i < n; ++i) {
        const double h = data.activation[i];
        data.n1[i] = h > 0.0 ? -p.lambda_jl * (q[i] - data.centre[i]) / h : 0.0;
        data.scale[i] = h > 0.0 ? 0.0 : 1.0;  // P1 = I − J1^† J1
      }
      data.columns = data.jacobian * data.scale.asDiagonal();
      data.m1.noalias() = data.task - data.jacobian * data.n1;
      if (!applyInverse(p, p.inverse, full, data.columns, data.m1, E, data, data.n2)) return false;
      dq = data.n1 + data.scale.cwiseProduct(data.n2);
      break;
    }
    case LimitScheme::ContinuousTaskPriority: {
      activations(model, beta, q, data);
      data.n1 = -p.lambda_jl * data.activation.cwiseProduct(q - data.centre);  // Δq1 = H (−λ (q − q_c))
      data.scale = Eigen::VectorXd::Ones(n) - data.activation;                 // task activation I − H
      const InverseOperator inner = p.inverse == InverseOperator::SelectiveDamping ? InverseOperator::Pseudoinverse
                                    : p.inverse == InverseOperator::SvfSelectiveDamping
                                        ? InverseOperator::SingularValueFilter
                                        : p.inverse;
      continuousPseudoinverse(p, data, data.jacobian, data.scale, inner, E, data.inverse);
      if (!data.inverse.allFinite()) return false;
      if (!isSelectiveDamping(p.inverse)) {
        // (3.28): Δq = Δq1 + J^{(I−H)⊕} (e − J Δq1).
        data.m1.noalias() = data.task - data.jacobian * data.n1;
        dq.noalias() = data.n1 + data.inverse * data.m1;
        break;
      }
      // (3.39): Δq̂ = (I − J^⊕ J) Δq1 + Σ_s clamp(w_s), the w_s from the SVD of J^⊕ (3.31–3.38); then (3.40).
      data.column_norms = data.jacobian.colwise().norm().transpose();
      if (data.transitional.empty() && !data.selected.empty()) {
        // No joint in transition: J^⊕ = Σ g_i (scattered v_i) u_iᵀ is already an SVD (the scattered v_i stay
        // orthonormal), so the one of J_Q serves and no second decomposition is needed.
        const int c = static_cast<int>(data.selected.size());
        const ThinSvd& svd = data.svd_by_columns[static_cast<std::size_t>(c - 1)];
        const Eigen::Index r = svd.singularValues().size();
        data.scattered.setZero();
        for (int row = 0; row < c; ++row) {
          data.scattered.row(data.selected[static_cast<std::size_t>(row)]).head(r) = svd.V().row(row);
        }
        selectiveDampingSum(data.gains.head(r), data.scattered.leftCols(r), svd.U(), data.column_norms, data.task,
                            p.gamma_max, data.n3, data.n2);
      } else {
        if (!data.svd_inverse.compute(data.inverse)) return false;
        selectiveDampingSum(data.svd_inverse.singularValues(), data.svd_inverse.U(), data.svd_inverse.V(),
                            data.column_norms, data.task, p.gamma_max, data.n3, data.n2);
      }
      data.m1.noalias() = data.jacobian * data.n1;
      dq = data.n1 + data.n2;
      dq.noalias() -= data.inverse * data.m1;
      clampMaxAbs(dq, p.gamma_max);
      break;
    }
  }
  return dq.allFinite();
}

}  // namespace

const char* methodName(InverseOperator op, LimitScheme scheme) noexcept {
  if (scheme == LimitScheme::ContinuousTaskPriority) {
    switch (op) {
      case InverseOperator::Pseudoinverse:
        return "CTP";
      case InverseOperator::SingularValueFilter:
        return "CTP+SVF";
      case InverseOperator::SelectiveDamping:
        return "CTP+SD";
      case InverseOperator::SvfSelectiveDamping:
        return "CTP+SD+SVF";
      default:
        return "CTP+other";
    }
  }
  switch (scheme) {
    case LimitScheme::JointWeighting:
      return "JW";
    case LimitScheme::GradientProjection:
      return "GP";
    case LimitScheme::JointClamping:
      return "JC";
    case LimitScheme::TaskAugmentation:
      return "TA";
    case LimitScheme::TaskPriority:
      return "TP";
    default:
      break;
  }
  switch (op) {
    case InverseOperator::Pseudoinverse:
      return "JP";
    case InverseOperator::Transpose:
      return "JT";
    case InverseOperator::SelectiveDamping:
      return "SD";
    case InverseOperator::Damping:
      return "JD";
    case InverseOperator::Filtering:
      return "JF";
    case InverseOperator::ErrorDamping:
      return "ED";
    case InverseOperator::ImprovedErrorDamping:
      return "IED";
    case InverseOperator::SingularValueFilter:
      return "SVF";
    case InverseOperator::SvfErrorDamping:
      return "SVF+ED";
    case InverseOperator::SvfSelectiveDamping:
      return "SVF+SD";
  }
  return "unknown";
}

bool parseMethodName(const std::string& name, InverseOperator& op, LimitScheme& scheme) noexcept {
  constexpr InverseOperator kOperators[] = {InverseOperator::Pseudoinverse,
                                            InverseOperator::Transpose,
                                            InverseOperator::SelectiveDamping,
                                            InverseOperator::Damping,
                                            InverseOperator::Filtering,
                                            InverseOperator::ErrorDamping,
                                            InverseOperator::ImprovedErrorDamping,
                                            InverseOperator::SingularValueFilter,
                                            InverseOperator::SvfErrorDamping,
                                            InverseOperator::SvfSelectiveDamping};
  constexpr LimitScheme kSchemes[] = {LimitScheme::None,
                                      LimitScheme::JointWeighting,
                                      LimitScheme::GradientProjection,
                                      LimitScheme::JointClamping,
                                      LimitScheme::TaskAugmentation,
                                      LimitScheme::TaskPriority,
                                      LimitScheme::ContinuousTaskPriority};
  // JW, GP, JC, TA and TP are named after their scheme alone: they pair with the pseudoinverse.
  for (LimitScheme s : kSchemes) {
    for (InverseOperator o : kOperators) {
      const bool named_by_scheme = s != LimitScheme::None && s != LimitScheme::ContinuousTaskPriority;
      if (named_by_scheme && o != InverseOperator::Pseudoinverse) continue;
      if (name == methodName(o, s)) {
        op = o;
        scheme = s;
        return true;
      }
    }
  }
  return false;
}

const char* toString(IkStatus status) noexcept {
  switch (status) {
    case IkStatus::Converged:
      return "converged";
    case IkStatus::MaxIterations:
      return "iteration limit reached";
    case IkStatus::Timeout:
      return "time budget exhausted";
    case IkStatus::InvalidInput:
      return "invalid input (wrong size or non-finite configuration or target)";
    case IkStatus::NumericalFailure:
      return "numerical failure (non-finite step)";
  }
  return "unknown status";
}

void ClikParameters::validate() const {
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("ClikParameters: ") + what);
  };
  require(std::isfinite(rotation_weight) && rotation_weight > 0.0, "rotation_weight must be positive");
  require(std::isfinite(pinv_tolerance) && pinv_tolerance >= 0.0, "pinv_tolerance must be >= 0");
  require(std::isfinite(lambda) && lambda > 0.0, "lambda must be positive");
  require(std::isfinite(filter_epsilon) && filter_epsilon > 0.0, "filter_epsilon must be positive");
  require(std::isfinite(lambda_max) && lambda_max > 0.0, "lambda_max must be positive");
  require(std::isfinite(ied_omega) && ied_omega >= 0.0, "ied_omega must be >= 0");
  require(std::isfinite(sigma0) && sigma0 > 0.0, "sigma0 must be positive");
  require(std::isfinite(nu) && nu > sigma0 && nu * sigma0 < 2.0, "nu must satisfy sigma0 < nu < 2 / sigma0 (3.11)");
  require(std::isfinite(gamma_max) && gamma_max > 0.0, "gamma_max must be positive");
  require(std::isfinite(gp_gain), "gp_gain must be finite");
  require(std::isfinite(beta) && beta > 0.0, "beta must be positive");
  require(stall_window >= 1, "stall_window must be >= 1");
  require(std::isfinite(beta_decay) && beta_decay > 0.0 && beta_decay <= 1.0, "beta_decay must be in (0, 1]");
  require(std::isfinite(lambda_jl) && lambda_jl >= 0.0, "lambda_jl must be >= 0");
  require(max_iterations >= 1, "max_iterations must be >= 1");
  require(!(limits == LimitScheme::ContinuousTaskPriority && inverse == InverseOperator::Transpose),
          "CTP needs an inverse operator inside its continuous pseudoinverse; the transpose (JT) is none");
  require(std::isfinite(tolerance) && tolerance > 0.0, "tolerance must be positive");
  require(std::isfinite(timeout) && timeout >= 0.0, "timeout must be >= 0 (0: none)");
}

double limitActivation(double q, double lower, double upper, double beta) noexcept {
  const double distance = std::min(q - lower, upper - q);
  if (!(distance < beta)) return 0.0;  // also for infinite limits
  if (distance <= 0.0) return 1.0;
  const double x = distance / beta;
  return 0.5 * (1.0 + std::tanh(1.0 / x - 1.0 / (1.0 - x)));
}

ClikData::ClikData(const ChainModel& model, const ClikParameters& parameters)
    : kinematics(model),
      error(taskDimension(parameters.mode)),
      task(taskDimension(parameters.mode)),
      jacobian(taskDimension(parameters.mode), model.nq()),
      dq(Eigen::VectorXd::Zero(model.nq())),
      svd_augmented(taskDimension(parameters.mode) + model.nq(), model.nq()),
      svd_inverse(model.nq(), taskDimension(parameters.mode)),
      columns(taskDimension(parameters.mode), model.nq()),
      augmented(taskDimension(parameters.mode) + model.nq(), model.nq()),
      augmented_task(taskDimension(parameters.mode) + model.nq()),
      inverse(model.nq(), taskDimension(parameters.mode)),
      activation(Eigen::VectorXd::Zero(model.nq())),
      centre(model.nq()),
      column_norms(model.nq()),
      scale(Eigen::VectorXd::Ones(model.nq())),
      previous_gradient(Eigen::VectorXd::Zero(model.nq())),
      n1(model.nq()),
      n2(model.nq()),
      n3(model.nq()),
      m1(taskDimension(parameters.mode)),
      gains(taskDimension(parameters.mode) + model.nq()),
      rows(taskDimension(parameters.mode) + model.nq()),
      gram(taskDimension(parameters.mode), taskDimension(parameters.mode)),
      gram_llt(taskDimension(parameters.mode)),
      scattered(model.nq(), taskDimension(parameters.mode)) {
  parameters.validate();
  const int m = taskDimension(parameters.mode);
  const int n = model.nq();
  if (n > 30) {
    throw std::invalid_argument("ClikData: chains of more than 30 joints are not supported");
  }
  svd_by_columns.reserve(static_cast<std::size_t>(n));
  for (int c = 1; c <= n; ++c) svd_by_columns.emplace_back(m, c);
  for (int i = 0; i < n; ++i) {
    const double lo = model.lowerLimits()[i];
    const double hi = model.upperLimits()[i];
    centre[i] = std::isfinite(lo) && std::isfinite(hi) ? 0.5 * (lo + hi) : 0.0;
  }
  always.reserve(static_cast<std::size_t>(n));
  transitional.reserve(static_cast<std::size_t>(n));
  selected.reserve(static_cast<std::size_t>(n));
}

void continuousPseudoinverse(const ClikParameters& parameters, ClikData& data,
                             const Eigen::Ref<const Eigen::MatrixXd>& J,
                             const Eigen::Ref<const Eigen::VectorXd>& activation, InverseOperator inner,
                             double error_energy, Eigen::Ref<Eigen::MatrixXd> out) noexcept {
  const int n = static_cast<int>(J.cols());
  out.setZero();
  data.always.clear();
  data.transitional.clear();
  for (int i = 0; i < n; ++i) {
    if (activation[i] >= 1.0) {
      data.always.push_back(i);
    } else if (activation[i] > 0.0) {
      data.transitional.push_back(i);
    }
  }
  const int k = static_cast<int>(data.transitional.size());
  for (unsigned long mask = 0; mask < (1UL << k); ++mask) {
    // Weight of subset Q = always ∪ {transitional joints whose bit is set} (3.22).
    double weight = 1.0;
    data.selected.clear();
    for (int i : data.always) data.selected.push_back(i);
    for (int t = 0; t < k; ++t) {
      const int joint = data.transitional[static_cast<std::size_t>(t)];
      if (mask & (1UL << t)) {
        weight *= activation[joint];
        data.selected.push_back(joint);
      } else {
        weight *= 1.0 - activation[joint];
      }
    }
    const int c = static_cast<int>(data.selected.size());
    if (c == 0 || weight == 0.0) continue;
    for (int col = 0; col < c; ++col) data.columns.col(col) = J.col(data.selected[static_cast<std::size_t>(col)]);
    ThinSvd& svd = data.svd_by_columns[static_cast<std::size_t>(c - 1)];
    if (!svd.compute(data.columns.leftCols(c))) {
      out.setConstant(std::numeric_limits<double>::quiet_NaN());
      return;
    }
    computeGains(parameters, inner, svd, error_energy, data);
    const Eigen::MatrixXd& U = svd.U();
    const Eigen::MatrixXd& V = svd.V();
    for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i) {
      const double g = weight * data.gains[i];
      if (g == 0.0) continue;
      for (int row = 0; row < c; ++row) {
        out.row(data.selected[static_cast<std::size_t>(row)]).noalias() += (g * V(row, i)) * U.col(i).transpose();
      }
    }
  }
}

IkStatus step(const ChainModel& model, const ClikParameters& parameters, ClikData& data,
              const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Isometry3d& target) noexcept {
  if (!evaluate(model, parameters, data, q, target)) return IkStatus::InvalidInput;
  return computeStep(model, parameters, parameters.beta, data, q) ? IkStatus::Converged : IkStatus::NumericalFailure;
}

IkResult solve(const ChainModel& model, const ClikParameters& parameters, ClikData& data, Eigen::Ref<Eigen::VectorXd> q,
               const Eigen::Isometry3d& target) noexcept {
  IkResult result;
  const auto start = std::chrono::steady_clock::now();
  data.previous_gradient.setZero();
  double beta = parameters.beta;
  double reference = std::numeric_limits<double>::infinity();  // residual at the start of the current window
  int stalled = 0;
  for (int iteration = 0;; ++iteration) {
    if (!evaluate(model, parameters, data, q, target)) {
      result.status = IkStatus::InvalidInput;
      return result;
    }
    result.iterations = iteration;
    result.residual = data.error.cwiseAbs().maxCoeff();
    if (result.residual <= parameters.tolerance) {
      result.status = IkStatus::Converged;
      return result;
    }
    if (result.residual < 0.9 * reference) {
      reference = result.residual;
      stalled = 0;
    } else if (++stalled >= parameters.stall_window) {
      beta *= parameters.beta_decay;
      reference = result.residual;
      stalled = 0;
    }
    if (iteration >= parameters.max_iterations) {
      result.status = IkStatus::MaxIterations;
      return result;
    }
    if (parameters.timeout > 0.0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > parameters.timeout) {
      result.status = IkStatus::Timeout;
      return result;
    }
    if (!computeStep(model, parameters, beta, data, q)) {
      result.status = IkStatus::NumericalFailure;
      return result;
    }
    q += data.dq;
    if (parameters.clamp_to_limits) q = q.cwiseMax(model.lowerLimits()).cwiseMin(model.upperLimits());
  }
}

}  // namespace bimanual_skills::kinematics
