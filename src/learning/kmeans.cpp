#include "bimanual_skills/learning/kmeans.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::learning {

KMeansResult kMeans(const Eigen::MatrixXd& points, int k, int max_iterations) {
  const Eigen::Index n = points.rows();
  if (k < 1 || k > n || !points.allFinite() || max_iterations < 1) {
    throw std::invalid_argument("kMeans: need 1 <= k <= " + std::to_string(n) +
                                " points, finite coordinates and max_iterations >= 1 (k = " + std::to_string(k) + ")");
  }
  KMeansResult result;
  result.centres.resize(k, points.cols());
  // Maximin initialisation: squared distance of every point to its nearest chosen centre.
  Eigen::Index first = 0;
  points.rowwise().squaredNorm().maxCoeff(&first);
  result.centres.row(0) = points.row(first);
  Eigen::VectorXd nearest = (points.rowwise() - points.row(first)).rowwise().squaredNorm();
  for (int c = 1; c < k; ++c) {
    Eigen::Index next = 0;
    nearest.maxCoeff(&next);
    result.centres.row(c) = points.row(next);
    nearest = nearest.cwiseMin((points.rowwise() - points.row(next)).rowwise().squaredNorm());
  }
  result.labels = Eigen::VectorXi::Constant(n, -1);
  Eigen::VectorXi counts(k);
  for (result.iterations = 1; result.iterations <= max_iterations; ++result.iterations) {
    bool changed = false;
    for (Eigen::Index p = 0; p < n; ++p) {
      int best = 0;
      double best_distance = std::numeric_limits<double>::infinity();
      for (int c = 0; c < k; ++c) {
        const double d = (points.row(p) - result.centres.row(c)).squaredNorm();
        if (d < best_distance) {
          best_distance = d;
          best = c;
        }
      }
      changed = changed || result.labels[p] != best;
      result.labels[p] = best;
    }
    if (!changed) break;
    counts.setZero();
    Eigen::MatrixXd sums = Eigen::MatrixXd::Zero(k, points.cols());
    for (Eigen::Index p = 0; p < n; ++p) {
      sums.row(result.labels[p]) += points.row(p);
      ++counts[result.labels[p]];
    }
    for (int c = 0; c < k; ++c) {
      if (counts[c] > 0) result.centres.row(c) = sums.row(c) / counts[c];
    }
  }
  result.iterations = std::min(result.iterations, max_iterations);
  return result;
}

}  // namespace bimanual_skills::learning
