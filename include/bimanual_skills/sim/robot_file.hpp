/// \file
/// A robot file: everything about a pair (or any number) of arms that the simulator, the controllers and the launch
/// files need, in one YAML file (config/robots/wam.yaml is the default): the URDF of all arms, the simulator's plant
/// file, each arm's chain (base and tip links), start posture and friction model, the controllers' gains, the
/// braking damping and the rated payload. A simulation file names it (`robot:`), and sim.launch takes it
/// (`robot:=FILE`), so that arms of another make need one file, not edits across the package.
///
/// What a user would rather not tune by hand comes from the model when the file leaves it out: the gains from a
/// bandwidth and the inertias, the braking from the torque and speed limits, the payload from the effort limits, the
/// start posture from a tool pose by global IK (the functions below; docs/ARCHITECTURE.md "Bring your own arms").
#pragma once

#include "bimanual_skills/kinematics/chain_model.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace bimanual_skills::sim {

struct RobotArm {
  std::string name;           ///< The arm's name (its ROS namespace and its key in the plant file).
  std::string base_link;      ///< Its chain's base in the URDF (fixed to the world).
  std::string tip_link;       ///< Its tool link.
  Eigen::VectorXd start;      ///< Posture at start and after a reset [rad], within the URDF's limits (given, or
                              ///< solved from `start_tool`).
  std::string friction_file;  ///< Friction model its controller compensates (absolute path; "" for none).
  Eigen::VectorXd ik_seed;    ///< Seed of the IK of task poses (the branch the arm works in); default its start.
};

struct RobotFile {
  std::string path;        ///< The file read.
  std::string name;        ///< The robot's name (for messages and records).
  std::string urdf_path;   ///< All arms' URDF (absolute path).
  std::string plant_path;  ///< The simulator's true plant (absolute path).
  std::vector<RobotArm> arms;
  Eigen::VectorXd kp, kv;           ///< Computed-torque gains per joint [N m/rad, N m s/rad], every arm.
  Eigen::VectorXd braking_damping;  ///< [N m s/rad] per joint when an external controller's commands stop.
  double rated_payload = 0.0;       ///< [kg] per arm.
  /// The entries derived from the model, each with how ("kp, kv: bandwidth 3 Hz, damping ratio 1, at the first
  /// arm's start"), for the log of the nodes that read the file.
  std::vector<std::string> derived;

  /// Reads and checks a robot file: relative paths against the file's directory; every arm's chain loads from
  /// the URDF, its start lies within the chain's limits, gains and damping have one value per joint. Entries left
  /// out are derived from the model: `kp`/`kv` from `bandwidth` [Hz, one or one per joint] and `damping_ratio`
  /// (default 1) by gainsFromBandwidth at the first arm's start; `braking_damping` by brakingFromLimits;
  /// `rated_payload` by payloadFromEfforts (the smallest over the arms at their starts); an arm's `start` from its
  /// `start_tool` ({xyz, rpy} of the tool in the world frame) by postureFromToolPose.
  /// \throws std::invalid_argument naming the file and the entry (missing, unknown, of the wrong size or range, or
  /// not derivable, with what to give instead).
  static RobotFile fromYamlFile(const std::string& path);

  /// The arm named `name`, or nullptr.
  const RobotArm* arm(const std::string& name) const noexcept;
};

/// Computed-torque gains of a closed-loop bandwidth: with M_ii(q) the inertia joint i sees at q (the URDF's
/// inertias), kp_i = M_ii ω_i² and kv_i = 2 ζ M_ii ω_i, ω_i = 2π `hz`_i: each joint's error
/// obeys ë + 2ζω ė + ω² e = 0 where the model is exact (thesis eq. 4.4 with K_p, K_v scaled by M's diagonal).
/// \throws std::invalid_argument naming the joint when M_ii is not positive and finite.
void gainsFromBandwidth(const kinematics::ChainModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& hz,
                        double zeta, Eigen::VectorXd& kp, Eigen::VectorXd& kv);

/// Braking damping from the URDF's limits: d_i = τ_max,i / (2 v_max,i), the damping whose torque at the speed limit
/// is half the joint's effort limit (the other half holds the arm against gravity).
/// \throws std::invalid_argument naming the joint when the URDF gives it no effort or velocity limit.
Eigen::VectorXd brakingFromLimits(const kinematics::ChainModel& model);

/// The rated payload at posture q from the URDF's effort limits: the largest mass at the tool whose weight, added
/// to the arm's own, keeps every joint's gravity torque within half its effort limit (the other half for motion):
/// min over joints i with a lever of (τ_max,i / 2 − |G_i(q)|) / |G_i(q, 1 kg) − G_i(q)| [kg].
/// \throws std::invalid_argument when a joint has no effort limit or cannot hold the arm itself at q.
double payloadFromEfforts(const kinematics::ChainModel& model, const Eigen::VectorXd& q);

/// A posture for a tool pose (in the chain's base frame) by global IK: of the distinct solutions of 200 seeded
/// attempts, the one nearest the middle of the joint ranges (least Σ ((q_i − mid_i) / range_i)², the joint-limit
/// criterion of Liégeois 1977): the same answer on every machine.
/// \throws std::invalid_argument when no attempt reaches the pose within the limits.
Eigen::VectorXd postureFromToolPose(const kinematics::ChainModel& model, const Eigen::Isometry3d& tool_in_base);

}  // namespace bimanual_skills::sim
