#include "bimanual_skills/tasks/fold_quality.hpp"

#include <Eigen/Geometry>

#include <stdexcept>

namespace bimanual_skills::tasks {

namespace {

/// The mean distance of the nodes i ≥ nodes_x / 2 of `mesh` to their mirror nodes of `mirror_of`.
double mirrorDistance(const Eigen::Matrix3Xd& mesh, int nodes_x, int nodes_y) {
  double sum = 0.0;
  for (int j = 0; j < nodes_y; ++j) {
    for (int i = nodes_x / 2; i < nodes_x; ++i) {
      sum += (mesh.col(j * nodes_x + i) - mesh.col(j * nodes_x + (nodes_x - 1 - i))).norm();
    }
  }
  return sum / (0.5 * nodes_x * nodes_y);
}

}  // namespace

FoldQuality foldQuality(const Eigen::Matrix3Xd& vertices, const Eigen::Matrix3Xd& rest, int nodes_x, int nodes_y,
                        double thickness) {
  if (nodes_x < 2 || nodes_x % 2 != 0 || nodes_y < 1 || vertices.cols() != nodes_x * nodes_y ||
      rest.cols() != vertices.cols() || !(thickness > 0.0) || !vertices.allFinite() || !rest.allFinite()) {
    throw std::invalid_argument(
        "foldQuality: meshes of nodes_x x nodes_y nodes (nodes_x even), finite, and a "
        "positive thickness are needed");
  }
  FoldQuality f;
  f.distance = mirrorDistance(vertices, nodes_x, nodes_y);
  double moved = 0.0;
  for (int j = 0; j < nodes_y; ++j) {
    for (int i = 0; i < nodes_x / 2; ++i) moved += (vertices.col(j * nodes_x + i) - rest.col(j * nodes_x + i)).norm();
  }
  f.displacement = moved / (0.5 * nodes_x * nodes_y);
  const double flat = mirrorDistance(rest, nodes_x, nodes_y);
  if (!(flat > thickness)) throw std::invalid_argument("foldQuality: the flat cloth's halves are not apart");
  f.q = (flat - (f.distance + 1.2 * f.displacement)) / (flat - thickness);
  return f;
}

Eigen::Matrix3Xd idealFold(const Eigen::Matrix3Xd& rest, int nodes_x, int nodes_y, double thickness) {
  (void)foldQuality(rest, rest, nodes_x, nodes_y, thickness);  // the same checks
  if (nodes_y < 2) throw std::invalid_argument("idealFold: the rest mesh must span a plane (nodes_y >= 2)");
  Eigen::Vector3d normal = (rest.col(1) - rest.col(0)).cross(rest.col(nodes_x) - rest.col(0));
  if (!(normal.norm() > 0.0)) throw std::invalid_argument("idealFold: the rest mesh must span a plane");
  normal.normalize();
  if (normal.z() < 0.0) normal = -normal;
  Eigen::Matrix3Xd ideal = rest;
  for (int j = 0; j < nodes_y; ++j) {
    for (int i = nodes_x / 2; i < nodes_x; ++i) {
      ideal.col(j * nodes_x + i) = rest.col(j * nodes_x + (nodes_x - 1 - i)) + thickness * normal;
    }
  }
  return ideal;
}

}  // namespace bimanual_skills::tasks
