/// \file
/// Seeded random matrices for tests and benchmarks (header-only; test and benchmark support, not installed).
#pragma once

#include <Eigen/Core>
#include <Eigen/QR>

#include <random>

namespace bimanual_skills::testing {

/// A rows × cols matrix of independent N(0, 1) entries, drawn column by column from `rng`.
inline Eigen::MatrixXd randomMatrix(int rows, int cols, std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd m(rows, cols);
  for (int j = 0; j < cols; ++j) {
    for (int i = 0; i < rows; ++i) m(i, j) = normal(rng);
  }
  return m;
}

/// A rows × cols matrix with orthonormal columns (cols ≤ rows): the Q factor of a random matrix.
inline Eigen::MatrixXd randomOrthonormal(int rows, int cols, std::mt19937& rng) {
  return Eigen::HouseholderQR<Eigen::MatrixXd>(randomMatrix(rows, cols, rng)).householderQ() *
         Eigen::MatrixXd::Identity(rows, cols);
}

}  // namespace bimanual_skills::testing
