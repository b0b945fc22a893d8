#include "bimanual_skills/vision/cloth_renderer.hpp"

#include <cmath>

namespace bimanual_skills::vision {

namespace {

constexpr int kSphereSlices = 24, kSphereStacks = 16, kCylinderSides = 32;

Eigen::Matrix3d triangle(const Eigen::Isometry3d& pose, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c) {
  Eigen::Matrix3d t;
  t.col(0) = pose * a;
  t.col(1) = pose * b;
  t.col(2) = pose * c;
  return t;
}

}  // namespace

std::vector<Eigen::Matrix3d> solidTriangles(const SceneSolid& solid) {
  std::vector<Eigen::Matrix3d> out;
  const Eigen::Isometry3d& pose = solid.pose;
  switch (solid.shape) {
    case SceneSolid::Shape::Box: {
      const Eigen::Vector3d h = 0.5 * solid.size;
      // Each face: its outward axis k with sign s, and the two other axes in right-handed order.
      for (int k = 0; k < 3; ++k) {
        for (const double s : {-1.0, 1.0}) {
          const int i = (k + 1) % 3, j = (k + 2) % 3;
          const auto corner = [&](double u, double v) {
            Eigen::Vector3d p;
            p[k] = s * h[k];
            p[i] = u * h[i];
            p[j] = v * h[j];
            return p;
          };
          // Outward: (e_i × e_j) = e_k, so for s < 0 the order is reversed.
          if (s > 0) {
            out.push_back(triangle(pose, corner(-1, -1), corner(1, -1), corner(1, 1)));
            out.push_back(triangle(pose, corner(-1, -1), corner(1, 1), corner(-1, 1)));
          } else {
            out.push_back(triangle(pose, corner(-1, -1), corner(1, 1), corner(1, -1)));
            out.push_back(triangle(pose, corner(-1, -1), corner(-1, 1), corner(1, 1)));
          }
        }
      }
      break;
    }
    case SceneSolid::Shape::Sphere: {
      const double r = solid.size[0];
      const auto point = [&](int stack, int slice) {
        const double theta = M_PI * stack / kSphereStacks, phi = 2.0 * M_PI * slice / kSphereSlices;
        return Eigen::Vector3d(r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi),
                               r * std::cos(theta));
      };
      for (int stack = 0; stack < kSphereStacks; ++stack) {
        for (int slice = 0; slice < kSphereSlices; ++slice) {
          const Eigen::Vector3d a = point(stack, slice), b = point(stack + 1, slice), c = point(stack + 1, slice + 1),
                                d = point(stack, slice + 1);
          if (stack > 0) out.push_back(triangle(pose, a, b, d));
          if (stack + 1 < kSphereStacks) out.push_back(triangle(pose, b, c, d));
        }
      }
      break;
    }
    case SceneSolid::Shape::Cylinder: {
      const double r = solid.size[0], h = 0.5 * solid.size[1];
      const auto rim = [&](int side, double z) {
        const double phi = 2.0 * M_PI * side / kCylinderSides;
        return Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
      };
      const Eigen::Vector3d top(0.0, 0.0, h), bottom(0.0, 0.0, -h);
      for (int side = 0; side < kCylinderSides; ++side) {
        const Eigen::Vector3d a = rim(side, -h), b = rim(side + 1, -h), c = rim(side + 1, h), d = rim(side, h);
        out.push_back(triangle(pose, a, b, c));
        out.push_back(triangle(pose, a, c, d));
        out.push_back(triangle(pose, top, d, c));
        out.push_back(triangle(pose, bottom, b, a));
      }
      break;
    }
  }
  return out;
}

}  // namespace bimanual_skills::vision
