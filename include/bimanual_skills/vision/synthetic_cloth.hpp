/// \file
/// Cloth meshes made without a simulator, for tests, benchmarks and figures of the vision module: a flat patch with
/// the node layout of sim::Cloth (node (i, j) is column j·nodes_x + i) and the same patch folded in half over a
/// rounded crease.
#pragma once

#include <Eigen/Core>

#include <random>

namespace bimanual_skills::vision {

/// A triangle mesh: vertices 3 × N (world frame [m]) and triangles 3 × M (vertex indices).
struct ClothMesh {
  Eigen::Matrix3Xd vertices;
  Eigen::Matrix3Xi triangles;
};

/// A flat rectangular patch `length` × `width` [m] along world x × y, centred at `centre`, in the plane z = centre.z,
/// with nodes_x × nodes_y nodes (each ≥ 2) and two triangles per grid cell.
/// \throws std::invalid_argument for non-positive sizes, fewer than 2 nodes per side or a non-finite centre.
ClothMesh flatCloth(double length, double width, int nodes_x, int nodes_y, const Eigen::Vector3d& centre);

/// Folds a flat patch (of flatCloth) along the line x = fold_x: every node beyond it (x > fold_x) is carried over
/// the crease, a half cylinder of radius `crease_radius` [m] (> 0), and lies upside down on the lower half at
/// height 2 · crease_radius above it. Arc length is kept, so the folded cloth is not stretched.
/// \throws std::invalid_argument for a non-finite fold line or a non-positive radius.
ClothMesh foldCloth(const ClothMesh& flat, double fold_x, double crease_radius);

/// A crumpled version of a flat patch: the nodes are pulled towards the patch's centroid by a factor that varies
/// with the direction from it (three lobes, 0.3 to 0.8 of the distance), jittered by 1 cm in x and y, and lifted
/// by |N(0, (2 cm)²)|, drawing from `rng`: an irregular, wrinkled heap for tests of the reward terms.
ClothMesh crumpleCloth(const ClothMesh& flat, std::mt19937& rng);

}  // namespace bimanual_skills::vision
