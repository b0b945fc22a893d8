// Inverse operators of the CLIK solver (thesis Table 3.1): the gains g(σ), their application through an SVD or a
// damped Cholesky, selective damping, and the continuous pseudoinverse (3.22).
#include "clik_internal.hpp"

#include <limits>

namespace bimanual_skills::kinematics {
namespace {

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
      data.always.push(i);
    } else if (activation[i] > 0.0) {
      data.transitional.push(i);
    }
  }
  const int k = data.transitional.size();
  for (unsigned long mask = 0; mask < (1UL << k); ++mask) {
    // Weight of subset Q = always ∪ {transitional joints whose bit is set} (3.22).
    double weight = 1.0;
    data.selected.clear();
    for (int i : data.always) data.selected.push(i);
    for (int t = 0; t < k; ++t) {
      const int joint = data.transitional[t];
      if (mask & (1UL << t)) {
        weight *= activation[joint];
        data.selected.push(joint);
      } else {
        weight *= 1.0 - activation[joint];
      }
    }
    const int c = data.selected.size();
    if (c == 0 || weight == 0.0) continue;
    for (int col = 0; col < c; ++col) data.columns.col(col) = J.col(data.selected[col]);
    ThinSvd& svd = data.svd_by_columns[static_cast<std::size_t>(c - 1)];
    if (!svd.compute(data.columns.leftCols(c))) {
      out.setConstant(std::numeric_limits<double>::quiet_NaN());
      return;
    }
    clik_detail::computeGains(parameters, inner, svd, error_energy, data);
    const Eigen::MatrixXd& U = svd.U();
    const Eigen::MatrixXd& V = svd.V();
    for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i) {
      const double g = weight * data.gains[i];
      if (g == 0.0) continue;
      for (int row = 0; row < c; ++row) {
        out.row(data.selected[row]).noalias() += (g * V(row, i)) * U.col(i).transpose();
      }
    }
  }
}

namespace clik_detail {

void clampMaxAbs(Eigen::Ref<Eigen::VectorXd> v, double bound) noexcept {
  const double largest = v.cwiseAbs().maxCoeff();
  if (largest > bound) v *= bound / largest;
}

void computeGains(const ClikParameters& p, InverseOperator op, const ThinSvd& svd, double E, ClikData& data) noexcept {
  const Eigen::VectorXd& sigma = svd.singularValues();
  const double sigma_min = sigma.size() > 0 ? sigma.minCoeff() : 0.0;
  for (Eigen::Index i = 0; i < sigma.size(); ++i) data.gains[i] = inverseOperatorGain(p, op, sigma[i], sigma_min, E);
}

void applyGains(const ThinSvd& svd, const ClikData& data, const Eigen::Ref<const Eigen::VectorXd>& e,
                Eigen::Ref<Eigen::VectorXd> out) noexcept {
  out.setZero();
  const Eigen::MatrixXd& U = svd.U();
  const Eigen::MatrixXd& V = svd.V();
  for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i) {
    out.noalias() += (data.gains[i] * U.col(i).dot(e)) * V.col(i);
  }
}

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

bool applyInverse(const ClikParameters& p, InverseOperator op, ThinSvd& svd, const Eigen::Ref<const Eigen::MatrixXd>& A,
                  const Eigen::Ref<const Eigen::VectorXd>& e, double E, ClikData& data,
                  Eigen::Ref<Eigen::VectorXd> out) noexcept {
  if (op == InverseOperator::Transpose) {
    // (3.1) with Buss's step length α = ⟨e, J Jᵀ e⟩ / ‖J Jᵀ e‖², which minimises ‖e − α J Jᵀ e‖: a unit gain
    // diverges as soon as σ_max² > 2, as it is for the WAM.
    if (!A.allFinite()) return false;
    out.noalias() = A.transpose() * e;
    auto JJte = data.task_scratch.head(A.rows());
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
      auto y = data.task_scratch.head(A.rows());
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
  selectiveDampingSum(data.gains.head(r), svd.V(), svd.U(), data.column_norms.head(c), e, p.gamma_max,
                      data.component.head(c), out);
  clampMaxAbs(out, p.gamma_max);  // (3.40)
  return true;
}

}  // namespace clik_detail
}  // namespace bimanual_skills::kinematics
