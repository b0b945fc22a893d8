/// \file
/// The workspace map of one arm by inverse sampling (thesis Sec. 3.2.1, Fig. 3.7): a voxel grid over the arm's reach;
/// at each voxel centre M tool orientations spread uniformly over SO(3) (seeded per voxel) are tried with the global
/// IK solver; per voxel the ratio of orientations solved, the mean manipulability and Jacobian condition number of the
/// solutions, and the minimal bounding cone of the feasible forearm axes (the first wrist joint's axis, oriented from
/// the elbow to the wrist), widened by the wrist joint's limit into the cone of feasible tool z axes (Fig. 3.6).
///
/// For an arm with a spherical shoulder and a spherical wrist (the WAM), the distance from the shoulder centre to the
/// wrist centre depends on the elbow joint only; an orientation whose wrist centre lies outside that range is
/// unreachable without an IK call (an exact necessary condition), which is where most failed attempts would spend the
/// solver's whole budget. Other arms are mapped with IK calls only. Voxels are built in parallel over threads, each
/// from its own seed, so the map does not depend on the number of threads. Target bimanual_skills_workspace.
/// Offline: allocates; errors are exceptions.
#pragma once

#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/workspace/bounding_cone.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace bimanual_skills::workspace {

struct WorkspaceMapSettings {
  double resolution = 0.05;  ///< Voxel edge [m] (> 0).
  int orientations = 50;     ///< M: tool orientations tried per voxel (≥ 1).
  std::uint32_t seed = 1;    ///< Of the orientations (per voxel) and of the IK restarts.
  int threads = 0;           ///< 0: one per hardware thread.
  /// Local solves (restarts) the global IK may spend on one orientation: a count, not a time budget, so that the
  /// map does not depend on the machine's load (≥ 1).
  int ik_attempts = 20;
  /// Index of the first wrist joint, whose axis is the forearm axis; −1: the fifth of a 7-joint chain (the WAM's),
  /// else the third from the tip.
  int forearm_joint = -1;
  /// Rule out poses by the wrist-centre test before any IK call (where the arm allows it); false: IK calls only,
  /// the baseline the test is measured against.
  bool wrist_test = true;

  /// \throws std::invalid_argument naming the first setting out of range.
  void validate() const;
};

struct WorkspaceVoxel {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< Base frame [m].
  int solved = 0;                                    ///< Orientations with an IK solution within the limits.
  int pruned = 0;                                    ///< Orientations ruled out by the wrist-centre reach.
  double solution_ratio = 0.0;                       ///< solved / M.
  double manipulability = 0.0;                       ///< Mean over the solutions (0 without any).
  double condition = 0.0;                            ///< Mean Jacobian condition number over the solutions.
  BoundingCone forearm;                              ///< Of the solutions' forearm axes (angle 0 without any).
  BoundingCone tool;                                 ///< forearm widened by the wrist limit (at most π).
};

class WorkspaceMap {
 public:
  /// Maps `model` (the tip is the tool). `progress` (optional) gets the voxels done and their total now and then.
  /// \throws std::invalid_argument for bad settings or a chain with fewer than 3 joints.
  static WorkspaceMap build(const kinematics::ChainModel& model, const WorkspaceMapSettings& settings,
                            const std::function<void(std::size_t done, std::size_t total)>& progress = {});

  /// A fingerprint of everything a map depends on: the chain's kinematics (joint types, origins, axes, limits, the
  /// tip) and the settings but `threads` (the map does not depend on them), with the file format's version.
  static std::uint64_t key(const kinematics::ChainModel& model, const WorkspaceMapSettings& settings);
  /// Writes the map to `path`: a binary file of this format version holding `key`, for this host's byte order.
  /// \throws std::runtime_error when it cannot be written.
  void save(const std::string& path, std::uint64_t key) const;
  /// The map saved in `path` with `key`; none when the file is missing, of another format version, byte order or
  /// key, or damaged (then the caller builds the map again).
  static std::optional<WorkspaceMap> load(const std::string& path, std::uint64_t key);
  /// The map of `model` and `settings` from the cache directory `directory` (a file named by its key) or, when it is
  /// not there, built and saved there; `from_cache` (optional) says which. An empty directory: build only.
  static WorkspaceMap cached(const kinematics::ChainModel& model, const WorkspaceMapSettings& settings,
                             const std::string& directory,
                             const std::function<void(std::size_t done, std::size_t total)>& progress = {},
                             bool* from_cache = nullptr);
  /// Where maps are kept unless told otherwise: $HOME/.cache/bimanual_skills/workspace ("" without HOME: no cache).
  static std::string defaultCacheDirectory();
  /// The cache file of `model` and `settings` in `directory`.
  static std::string cachePath(const std::string& directory, const kinematics::ChainModel& model,
                               const WorkspaceMapSettings& settings);

  const WorkspaceMapSettings& settings() const noexcept { return settings_; }
  /// Every voxel within the reach bound (reachable or not), in grid order (x fastest, then y, then z).
  const std::vector<WorkspaceVoxel>& voxels() const noexcept { return voxels_; }
  /// Voxels with at least one solved orientation.
  std::size_t reachable() const noexcept;
  /// True when the arm has the spherical shoulder and wrist the wrist-centre test needs (the grid is then centred
  /// on the shoulder and bounded by the wrist's reach plus the tool).
  bool sphericalWrist() const noexcept { return spherical_; }
  /// The bound of the tool's distance from the shoulder centre [m] the grid covers.
  double reach() const noexcept { return reach_; }
  /// The wrist-centre test: false when no configuration can put the tool at `tool` (its wrist centre is out of the
  /// elbow's range); true otherwise, and always for arms without the spherical shoulder and wrist.
  bool mayReach(const Eigen::Isometry3d& tool) const noexcept;

 private:
  /// The map's fields before its voxels in the cache file, in file order (one list for save() and load()): `field`
  /// is called on each until it returns false.
  template <typename Map, typename Field>
  static bool headerFields(Map& map, Field&& field);

  WorkspaceMapSettings settings_;
  std::vector<WorkspaceVoxel> voxels_;
  bool spherical_ = false;
  double reach_ = 0.0;
  Eigen::Vector3d shoulder_ = Eigen::Vector3d::Zero(), wrist_in_tool_ = Eigen::Vector3d::Zero();
  double wrist_min_ = 0.0, wrist_max_ = 0.0;
};

}  // namespace bimanual_skills::workspace
