/// \file
/// A robot file: everything about a pair (or any number) of arms that the simulator, the controllers and the launch
/// files need, in one YAML file (config/robots/wam.yaml is the default): the URDF of all arms, the simulator's plant
/// file, each arm's chain (base and tip links), start posture and friction model, the controllers' gains, the
/// braking damping and the rated payload. A simulation file names it (`robot:`), and sim.launch takes it
/// (`robot:=FILE`), so that arms of another make need one file, not edits across the package.
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

namespace bimanual_skills::sim {

struct RobotArm {
  std::string name;           ///< The arm's name (its ROS namespace and its key in the plant file).
  std::string base_link;      ///< Its chain's base in the URDF (fixed to the world).
  std::string tip_link;       ///< Its tool link.
  Eigen::VectorXd start;      ///< Posture at start and after a reset [rad], within the URDF's limits.
  std::string friction_file;  ///< Friction model its controller compensates (absolute path; "" for none).
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

  /// Reads and checks a robot file: relative paths against the file's directory; every arm's chain loads from
  /// the URDF, its start lies within the chain's limits, gains and damping have one value per joint.
  /// \throws std::invalid_argument naming the file and the entry (missing, unknown, of the wrong size or range).
  static RobotFile fromYamlFile(const std::string& path);

  /// The arm named `name`, or nullptr.
  const RobotArm* arm(const std::string& name) const noexcept;
};

}  // namespace bimanual_skills::sim
