#include "bimanual_skills/vision/synthetic_cloth.hpp"

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::vision {

ClothMesh flatCloth(double length, double width, int nodes_x, int nodes_y, const Eigen::Vector3d& centre) {
  if (!(std::isfinite(length) && length > 0.0 && std::isfinite(width) && width > 0.0)) {
    throw std::invalid_argument("flatCloth: length and width must be finite and > 0");
  }
  if (nodes_x < 2 || nodes_y < 2) throw std::invalid_argument("flatCloth: at least 2 nodes along each side");
  if (!centre.allFinite()) throw std::invalid_argument("flatCloth: centre must be finite");
  ClothMesh mesh;
  mesh.vertices.resize(3, nodes_x * nodes_y);
  for (int j = 0; j < nodes_y; ++j) {
    for (int i = 0; i < nodes_x; ++i) {
      mesh.vertices.col(j * nodes_x + i) = centre + Eigen::Vector3d(length * (double(i) / (nodes_x - 1) - 0.5),
                                                                    width * (double(j) / (nodes_y - 1) - 0.5), 0.0);
    }
  }
  mesh.triangles.resize(3, 2 * (nodes_x - 1) * (nodes_y - 1));
  int t = 0;
  for (int j = 0; j + 1 < nodes_y; ++j) {
    for (int i = 0; i + 1 < nodes_x; ++i) {
      const int a = j * nodes_x + i, b = a + 1, c = a + nodes_x, d = c + 1;
      mesh.triangles.col(t++) = Eigen::Vector3i(a, b, d);
      mesh.triangles.col(t++) = Eigen::Vector3i(a, d, c);
    }
  }
  return mesh;
}

ClothMesh foldCloth(const ClothMesh& flat, double fold_x, double crease_radius) {
  if (!std::isfinite(fold_x)) throw std::invalid_argument("foldCloth: fold_x must be finite");
  if (!(std::isfinite(crease_radius) && crease_radius > 0.0)) {
    throw std::invalid_argument("foldCloth: crease_radius must be finite and > 0");
  }
  ClothMesh folded = flat;
  const double pi = std::acos(-1.0);
  for (Eigen::Index k = 0; k < folded.vertices.cols(); ++k) {
    auto p = folded.vertices.col(k);
    const double beyond = p.x() - fold_x;  // Arc length past the fold line.
    if (beyond <= 0.0) continue;
    const double arc = pi * crease_radius;
    if (beyond < arc) {
      const double phi = beyond / crease_radius;
      p.x() = fold_x + crease_radius * std::sin(phi);
      p.z() += crease_radius * (1.0 - std::cos(phi));
    } else {
      p.x() = fold_x - (beyond - arc);
      p.z() += 2.0 * crease_radius;
    }
  }
  return folded;
}

ClothMesh crumpleCloth(const ClothMesh& flat, std::mt19937& rng) {
  ClothMesh crumpled = flat;
  if (flat.vertices.cols() == 0) return crumpled;
  const Eigen::Vector3d centroid = flat.vertices.rowwise().mean();
  std::normal_distribution<double> normal(0.0, 1.0);
  for (Eigen::Index k = 0; k < crumpled.vertices.cols(); ++k) {
    auto p = crumpled.vertices.col(k);
    const double dx = p.x() - centroid.x(), dy = p.y() - centroid.y();
    const double pull = 0.55 + 0.25 * std::cos(3.0 * std::atan2(dy, dx));
    p.x() = centroid.x() + pull * dx + 0.01 * normal(rng);
    p.y() = centroid.y() + pull * dy + 0.01 * normal(rng);
    p.z() += 0.02 * std::abs(normal(rng));
  }
  return crumpled;
}

}  // namespace bimanual_skills::vision
