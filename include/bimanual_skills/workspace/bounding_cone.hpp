/// \file
/// The minimal bounding cone of a set of directions (thesis Sec. 3.2.1, Fig. 3.6: the cone of the feasible forearm
/// axes at a point of the workspace, [103] Barequet and Elber): the cone with apex at the origin and the smallest
/// half-angle that contains every direction. Target bimanual_skills_workspace. Offline: allocates; errors are
/// exceptions.
///
/// For directions inside an open hemisphere the answer is a cone of less than 90°, whose axis is the point of the
/// directions' convex hull nearest to the origin (the cosine of its half-angle is that distance); Welzl's randomised
/// incremental algorithm finds it in expected linear time, with at most three directions on its boundary. Directions
/// that no open hemisphere contains need a cone of 90° or more: it is found by trying every cone through two or three
/// of them (quartic time: meant for the few tens of directions of a workspace point).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace bimanual_skills::workspace {

struct BoundingCone {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  ///< Unit vector.
  double angle = 0.0;                               ///< Half-angle [rad], in [0, π].

  /// True when the direction `v` (any length > 0) is within angle + tolerance of the axis.
  bool contains(const Eigen::Vector3d& v, double tolerance = 1e-9) const;
};

/// The minimal bounding cone of `directions` (any lengths > 0; they are normalised). `seed` orders the randomised
/// algorithm (the cone does not depend on it beyond rounding). \throws std::invalid_argument for no directions or a
/// zero or non-finite one.
BoundingCone minimalBoundingCone(const std::vector<Eigen::Vector3d>& directions, std::uint32_t seed = 1);

/// Welzl's algorithm alone: the minimal cone when the directions lie in an open hemisphere, else a cone that may
/// not hold them all (minimalBoundingCone() checks and falls back). \throws as minimalBoundingCone.
BoundingCone welzlBoundingCone(const std::vector<Eigen::Vector3d>& directions, std::uint32_t seed = 1);

/// The same by trying every cone through one, two or three of the directions (both cones through three, the one
/// around the normal of their plane and the one around its opposite) and keeping the smallest that contains them
/// all: O(n⁴), the reference of the tests and the answer for directions outside every open hemisphere.
/// \throws as minimalBoundingCone.
BoundingCone bruteForceBoundingCone(const std::vector<Eigen::Vector3d>& directions);

}  // namespace bimanual_skills::workspace
