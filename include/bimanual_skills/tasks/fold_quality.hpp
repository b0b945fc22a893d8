/// \file
/// A ground-truth measure of a fold in half, from the simulated cloth mesh (what the simulator knows and the
/// camera-based learner does not): SoftGym's ClothFold measure, normalised. The fold line is the cloth's middle
/// across its x axis (the patch's x = 0): the far half (patch x > 0) moves, the near half stays. With node (i, j) of
/// the nodes_x × nodes_y grid mirrored to node (nodes_x − 1 − i, j),
///   distance     = mean over the moving half of ‖p(i, j) − p(mirror(i, j))‖,
///   displacement = mean over the staying half of ‖p(i, j) − p_rest(i, j)‖,
///   D = distance + 1.2 displacement   (SoftGym's weighting),
///   q = (D_flat − D) / (D_flat − D_ideal),
/// with D_flat the distance of the flat cloth at rest (the start: q = 0) and D_ideal one cloth thickness (the halves
/// stacked with the staying half unmoved: q = 1). q < 0 for a cloth left worse than flat.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::tasks {

struct FoldQuality {
  double q = 0.0;             ///< Normalised fold quality: 1 the ideal fold, 0 the flat start.
  double distance = 0.0;      ///< Mean distance of the moving half's nodes to their mirror nodes [m].
  double displacement = 0.0;  ///< Mean displacement of the staying half from rest [m].
};

/// The fold quality of the mesh `vertices` (3 × nodes_x·nodes_y, node (i, j) at column j·nodes_x + i, any frame)
/// against the flat cloth at rest `rest` (same layout, same frame; its x direction is the cloth's) for a cloth
/// `thickness` thick. \throws std::invalid_argument for sizes that do not match, nodes_x < 2 or an odd nodes_x, a
/// non-positive thickness, or non-finite meshes.
FoldQuality foldQuality(const Eigen::Matrix3Xd& vertices, const Eigen::Matrix3Xd& rest, int nodes_x, int nodes_y,
                        double thickness);

/// The ideal fold of the flat cloth `rest` (layout as foldQuality's): the staying half at rest, each node of the
/// moving half on its mirror node, one `thickness` above it along the rest plane's upward normal (the normal whose
/// world z is ≥ 0). foldQuality() of it is 1. What the goal image of the fold reward is rendered from.
/// \throws std::invalid_argument as foldQuality().
Eigen::Matrix3Xd idealFold(const Eigen::Matrix3Xd& rest, int nodes_x, int nodes_y, double thickness);

}  // namespace bimanual_skills::tasks
