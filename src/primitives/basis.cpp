#include "bimanual_skills/primitives/basis.hpp"

#include <cmath>

namespace bimanual_skills::primitives {

void normalisedGaussianBasis(double s, const Eigen::Ref<const Eigen::VectorXd>& centres,
                             const Eigen::Ref<const Eigen::VectorXd>& variances, double scale,
                             Eigen::Ref<Eigen::VectorXd> b) noexcept {
  double sum = 0.0;
  for (Eigen::Index i = 0; i < centres.size(); ++i) {
    const double delta = s - centres[i];
    b[i] = std::exp(-0.5 * delta * delta / variances[i]);
    sum += b[i];
  }
  b *= sum > 0.0 ? scale / sum : 0.0;
}

void normalisedGaussianBasis(double s, const Eigen::Ref<const Eigen::VectorXd>& centres,
                             const Eigen::Ref<const Eigen::VectorXd>& variances, Eigen::Ref<Eigen::VectorXd> b,
                             Eigen::Ref<Eigen::VectorXd> db) noexcept {
  double sum = 0.0, dsum = 0.0;
  for (Eigen::Index i = 0; i < centres.size(); ++i) {
    const double delta = s - centres[i];
    const double phi = std::exp(-0.5 * delta * delta / variances[i]);
    b[i] = phi;
    db[i] = -delta / variances[i] * phi;
    sum += phi;
    dsum += db[i];
  }
  if (!(sum > 0.0)) {
    b.setZero();
    db.setZero();
    return;
  }
  for (Eigen::Index i = 0; i < centres.size(); ++i) {
    db[i] = (db[i] * sum - b[i] * dsum) / (sum * sum);
    b[i] /= sum;
  }
}

}  // namespace bimanual_skills::primitives
