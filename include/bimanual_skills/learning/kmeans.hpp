/// \file
/// Deterministic k-means (Lloyd's iterations) for the clustering of Dual REPS (thesis Alg. 6.1).
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::learning {

struct KMeansResult {
  Eigen::VectorXi labels;   ///< Cluster of each point, in [0, k).
  Eigen::MatrixXd centres;  ///< k × dimension.
  int iterations = 0;       ///< Lloyd iterations until no label changed (or the limit).
};

/// k-means of the rows of `points` (N × dimension) into k clusters. Deterministic: the centres start from the
/// maximin initialisation of Katsavounidis, Kuo and Zhang (1994) — the point of largest norm, then repeatedly the
/// point farthest from its nearest chosen centre (lowest index on ties) — so the same points always give the same
/// clusters, which the KL repair of Dual REPS relies on (thesis Sec. 6.1.2). A cluster that loses all its points
/// keeps its centre. \throws std::invalid_argument for k < 1, k > N or non-finite points.
KMeansResult kMeans(const Eigen::MatrixXd& points, int k, int max_iterations = 100);

}  // namespace bimanual_skills::learning
