/// \file
/// The quality of a relative placement of two arms (thesis Sec. 3.2.3): for a pair of workspace points P1 of the
/// first arm and P2 of the second, F(P1, P2) = DF · SDF · OF · MF · CF (3.42–3.45), and for the placement
/// F = V · Σ_{P1 ∈ W1} Σ_{P2 ∈ W2} F(P1, P2) (3.41), V the volume of the combined workspace. A spatial index of the
/// second arm's points visits only the pairs whose distance can be within L ± δ. Target bimanual_skills_workspace.
/// Offline: allocates; errors are exceptions.
///
/// One reading differs from the printed formula: (3.45) writes CF = κ(P1) κ(P2) with κ the mean condition number,
/// which would reward ill-conditioned points, against the factor's stated purpose (a stable behaviour; κ amplifies
/// errors). CF here is the product of the inverse mean condition numbers, 1/κ̄(P1) · 1/κ̄(P2), in (0, 1] like the
/// other factors.
#pragma once

#include "bimanual_skills/workspace/bounding_cone.hpp"
#include "bimanual_skills/workspace/workspace_map.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

namespace bimanual_skills::workspace {

struct PairQualitySettings {
  double length = 0.4;     ///< L: the object's length [m]; the thesis' objects of 0.3–0.5 m are L = 0.4, δ = 0.1.
  double tolerance = 0.1;  ///< δ [m], 0 < δ < L.
  double k = 2.0;          ///< K of the orientation factor (3.43) (> 0; the thesis' 2).
  double of_min = 0.1;     ///< OF_min of (3.43), in (0, 1] (the thesis leaves it open).
  int threads = 0;         ///< 0: one per hardware thread. The result does not depend on it.

  /// \throws std::invalid_argument naming the first setting out of range.
  void validate() const;
};

/// What F(P1, P2) needs of a workspace point: its position, the cone of feasible tool z axes, and the voxel's
/// solution ratio, mean manipulability and mean condition number (WorkspaceVoxel).
struct WorkspacePoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  BoundingCone tool;
  double solution_ratio = 0.0;
  double manipulability = 0.0;
  double condition = 1.0;  ///< ≥ 1.

  /// The point as seen from a frame in which its own frame has the pose `pose`.
  WorkspacePoint transformed(const Eigen::Isometry3d& pose) const;
};

/// The factors of one pair; every one is 0 when DF is.
struct PairFactors {
  double df = 0.0;   ///< (3.42): 1 when L − δ < |P2 − P1| < L + δ and P2 − P1 is inside both tool cones.
  double sdf = 0.0;  ///< Solution density: the product of the two solution ratios.
  double of = 0.0;   ///< (3.43): max(OF_min, 1 + ln((α1 − a1)/α1 · (α2 − a2)/α2) / K).
  double mf = 0.0;   ///< (3.44): the product of the mean manipulabilities.
  double cf = 0.0;   ///< (3.45) read as 1/κ̄(P1) · 1/κ̄(P2) (see the file's comment).
  double a1 = 0.0, a2 = 0.0;  ///< Angles [rad] of P2 − P1 to cone 1's axis and of P1 − P2 to cone 2's.

  double product() const noexcept { return df * sdf * of * mf * cf; }
};

/// F(P1, P2) factor by factor, both points in one frame.
PairFactors pairFactors(const WorkspacePoint& p1, const WorkspacePoint& p2, const PairQualitySettings& settings);

/// The reachable points of a map (in its arm's base frame), and the volume of one voxel.
struct WorkspacePoints {
  std::vector<WorkspacePoint> points;
  double voxel_volume = 0.0;  ///< [m³]
  double resolution = 0.0;    ///< [m] Voxel edge.

  static WorkspacePoints of(const WorkspaceMap& map);
};

struct PlacementQuality {
  double quality = 0.0;            ///< F (3.41) [m³].
  double pair_sum = 0.0;           ///< Σ Σ F(P1, P2).
  double volume = 0.0;             ///< V: the volume of the union of both arms' reachable voxels [m³].
  std::size_t pairs = 0;           ///< Pairs with DF = 1.
  std::size_t distance_pairs = 0;  ///< Pairs at a distance within L ± δ (orientation not yet checked).
  std::size_t visited = 0;         ///< Pairs whose distance was computed (what the spatial index lets through).
  double seconds = 0.0;
};

/// F (3.41) of the first arm's points (its base at `first_base`) and the second's (at `second_base`), both poses in
/// one world frame; only the relative pose matters. \throws std::invalid_argument for bad settings or points.
PlacementQuality placementQuality(const WorkspacePoints& first, const Eigen::Isometry3d& first_base,
                                  const WorkspacePoints& second, const Eigen::Isometry3d& second_base,
                                  const PairQualitySettings& settings);

/// The same sum over every pair, without the index: the reference the tests hold placementQuality() to.
PlacementQuality bruteForcePlacementQuality(const WorkspacePoints& first, const Eigen::Isometry3d& first_base,
                                            const WorkspacePoints& second, const Eigen::Isometry3d& second_base,
                                            const PairQualitySettings& settings);

}  // namespace bimanual_skills::workspace
