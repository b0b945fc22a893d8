/// \file
/// Configuration of a simulation (`config/sim.yaml`): the robot description and its arms, the step, the table, the
/// cloth, the true plant and the seed.
#pragma once

#include "bimanual_skills/sim/cloth.hpp"
#include "bimanual_skills/sim/object_path.hpp"
#include "bimanual_skills/sim/obstacle.hpp"
#include "bimanual_skills/sim/plant_model.hpp"
#include "bimanual_skills/sim/table.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace bimanual_skills::sim {

/// One simulated arm: the serial chain between two links of the URDF.
struct ArmConfig {
  std::string name;           ///< Arm name (the key of its true plant in the plant model).
  std::string base_link;      ///< Link fixed to the world (through fixed joints only); the chain's base frame.
  std::string tip_link;       ///< The tool link: payloads hang and grippers sit at its origin.
  Eigen::VectorXd start;      ///< The robot file's start posture (empty when the simulation file names the arms).
  std::string friction_file;  ///< The robot file's friction model of its controller ("" for none, or no file).
  /// The posture task poses are solved from (IK seed): the branch the arm works in. The robot file's `ik_seed` or
  /// start; empty when the simulation file names the arms.
  Eigen::VectorXd ik_seed;
};

/// An object a person carries along a path for an arm to track and grasp (thesis Sec. 4.3.2). It stays upright; a
/// gripper that closes with its tool near the grasp point holds it (it then moves with the tool), and one that opens
/// leaves it resting where it is until the next reset. The arms collide with it when `body.collides`, until a gripper
/// takes it (then it is part of the hand, and let go it rests inside the open hand: no contact until the reset); the
/// cloth does not.
struct MovingObject {
  Obstacle body;  ///< Name, shape, size, colour, friction, collides (its pose is the path's).
  ObjectPathConfig path;
  Eigen::Vector3d grasp_point = Eigen::Vector3d::Zero();  ///< Where a tool holds it, from its centre (world axes) [m].
  double grasp_radius = 0.03;  ///< A closing gripper holds it when its tool is this near the grasp point [m].

  /// \throws std::invalid_argument naming `where` and the entry out of range.
  void validate(const std::string& where) const;
};

struct SimConfig {
  std::string urdf_path;  ///< Robot description (URDF file).
  std::vector<ArmConfig> arms;
  double step = 0.001;                                         ///< Fixed time step of the arms [s] (1 kHz).
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -9.81);  ///< World frame [m/s²].
  bool has_table = true;
  Table table;
  /// Static shapes besides the table (a mannequin): `obstacles:` a list, or the name of a file that holds one.
  std::vector<Obstacle> obstacles;
  bool has_object = false;
  MovingObject object;  ///< `object:`, only when has_object.
  bool has_cloth = false;
  ClothParameters cloth;       ///< Its `step` must be a whole multiple of `step` (the cloth runs at its own rate).
  double grasp_radius = 0.04;  ///< Nodes within this distance of a tool are grasped [m].
  PlantModel plant;            ///< True plant, one entry per arm name.
  std::string plant_path;      ///< Where `plant` was read from (informative).
  std::string robot_path;      ///< The robot file the arms, URDF and plant came from ("" when the file names them).
  Eigen::VectorXd kp, kv;      ///< The robot file's computed-torque gains (empty without a robot file).
  std::uint32_t seed = 1;      ///< Seed of the sensor noise generator.

  /// Reads a simulation file; relative paths in it (`urdf`, `plant`) are relative to the file's directory:
  /// \code
  /// urdf: ../urdf/bimanual_wam.urdf
  /// plant: plant.yaml
  /// step: 0.001
  /// seed: 1
  /// gravity: [0, 0, -9.81]
  /// arms:
  ///   - {name: left, base_link: left_wam_base, tip_link: left_wam_tool}
  /// table: {xyz: [0.55, 0, 0], rpy: [0, 0, 0], size: [0.7, 1.2, 0.3], friction: 0.5}   # optional
  /// object:                                                                            # optional
  ///   {name: target, shape: cylinder, size: [0.03, 0.12], colour: [0.9, 0.4, 0.1], friction: 0.8, collides: true,
  ///    grasp_point: [0, 0, 0.06], grasp_radius: 0.03,
  ///    path: {centre: [...], size: [...], max_speed: 0.2, max_acceleration: 0.5, min_speed_ratio: 0.3,
  ///           pause_probability: 0.3, pause: [0.5, 2], away_probability: 0.1, away: [0, 0.9, 0], start_pause: 2,
  ///           duration: 60, seed: 1}}
  /// cloth:                                                                             # optional
  ///   {xyz: [...], rpy: [...], size: [0.5, 0.6], nodes: [20, 24], mass: 0.22, stretch_stiffness: 0.9,
  ///    bending_stiffness: 0.05, damping: 0.01, friction: 0.5, thickness: 0.004, position_iterations: 4,
  ///    self_collision: true, strain_limit: 0.05, step: 0.004, max_node_speed: 20, max_stretch: 3, grasp_radius: 0.04}
  /// \endcode
  /// \throws std::invalid_argument naming the file and the entry (missing or unknown entries, wrong types, values
  /// out of range, a cloth step that is not a multiple of the step, unreadable plant file).
  /// Instead of `urdf`, `plant` and `arms`, a simulation file may name a robot file (`robot: robots/wam.yaml`,
  /// sim/robot_file.hpp) that gives them; a non-empty `robot` here replaces whichever the file names (the scene,
  /// step and seed stay the file's).
  static SimConfig fromYamlFile(const std::string& path, const std::string& robot = "");

  /// The world a simulation file describes (with `robot` as fromYamlFile), as a digest (16 hex digits) of its bytes
  /// and those of the robot, URDF and plant files it names: two processes that report the same digest simulate the
  /// same world. \throws like fromYamlFile.
  static std::string worldDigest(const std::string& path, const std::string& robot = "");

  /// Throws std::invalid_argument naming the first inconsistent value (checked again by the simulation).
  void validate() const;
};

}  // namespace bimanual_skills::sim
