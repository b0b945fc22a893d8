#include "bimanual_skills/kinematics/thin_svd.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace bimanual_skills::kinematics {

ThinSvd::ThinSvd(int rows, int cols, bool vectors)
    : rows_(rows),
      cols_(cols),
      transposed_(cols > rows),
      tall_(std::max(rows, cols), std::min(rows, cols)),
      svd_(tall_.rows(), tall_.cols(), vectors ? Eigen::ComputeThinU | Eigen::ComputeThinV : 0) {
  if (rows < 1 || cols < 1) {
    throw std::invalid_argument("ThinSvd: shape must be positive, got " + std::to_string(rows) + " x " +
                                std::to_string(cols));
  }
}

bool ThinSvd::compute(const Eigen::Ref<const Eigen::MatrixXd>& A) noexcept {
  if (A.rows() != rows_ || A.cols() != cols_ || !A.allFinite()) return false;
  if (transposed_) {
    tall_ = A.transpose();
  } else {
    tall_ = A;
  }
  svd_.compute(tall_);
  return true;
}

}  // namespace bimanual_skills::kinematics
