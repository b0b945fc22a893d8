/// \file
/// Allocation-free thin singular value decomposition of a matrix of fixed shape.
#pragma once

#include <Eigen/Core>
#include <Eigen/SVD>

namespace bimanual_skills::kinematics {

/// Thin SVD A = U diag(σ) Vᵀ of a rows × cols matrix, r = min(rows, cols) singular values in decreasing order.
/// Eigen's JacobiSVD allocates when it preconditions a wide matrix, so a wide A is decomposed as Aᵀ = V Σ Uᵀ; the
/// accessors hide the swap. All memory is taken at construction for exactly one shape.
class ThinSvd {
 public:
  /// For rows × cols matrices; `vectors` false: singular values only (U() and V() are then empty).
  ThinSvd(int rows, int cols, bool vectors = true);

  int rows() const noexcept { return rows_; }
  int cols() const noexcept { return cols_; }

  /// Decomposes A (must be rows() × cols(); returns false otherwise or if A is not finite).
  /// Real-time safe: no allocation, no exceptions.
  bool compute(const Eigen::Ref<const Eigen::MatrixXd>& A) noexcept;

  /// rows × r left singular vectors.
  const Eigen::MatrixXd& U() const noexcept { return transposed_ ? svd_.matrixV() : svd_.matrixU(); }
  /// cols × r right singular vectors.
  const Eigen::MatrixXd& V() const noexcept { return transposed_ ? svd_.matrixU() : svd_.matrixV(); }
  /// r singular values, decreasing.
  const Eigen::VectorXd& singularValues() const noexcept { return svd_.singularValues(); }

 private:
  int rows_;
  int cols_;
  bool transposed_;
  Eigen::MatrixXd tall_;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd_;
};

}  // namespace bimanual_skills::kinematics
