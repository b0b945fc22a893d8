/// \file
/// Rigid shapes of a scene besides the table, such as the mannequin a scarf goes around (thesis Sec. 4.3.1): the arms
/// and the cloth collide with them, markers and cameras show them in their colours. Static, or free (a mass): a free
/// one stands at its pose from every reset and the arms can knock it over (the bottles of thesis Sec. 6.2, Fig. 6.8).
/// A simulation file lists them (`obstacles:`, or the name of a file that does; config/scenes/mannequin.yaml).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace bimanual_skills::sim {

struct Obstacle {
  enum class Shape { Box, Sphere, Cylinder };
  std::string name;  ///< Unique in the scene ("head", "nose_mark").
  Shape shape = Shape::Box;
  /// Its centre in the world; a cylinder's axis is its z axis.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  /// Box: full extents; sphere: (radius, 0, 0); cylinder: (radius, length, 0) [m].
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  Eigen::Vector3d colour = Eigen::Vector3d::Constant(0.8);  ///< RGB in [0, 1].
  double friction = 0.5;                                    ///< Bullet friction coefficient, ≥ 0.
  bool collides = true;  ///< false: seen, not felt (a mark painted on another shape).
  double mass = 0.0;     ///< 0: static; > 0 [kg]: free (uniform density; not in a scene with a cloth).

  /// \throws std::invalid_argument naming `where`, the obstacle and the entry out of range.
  void validate(const std::string& where) const;
};

/// "box", "sphere", "cylinder".
const char* toString(Obstacle::Shape shape) noexcept;

/// How many of `size`'s values a shape uses: 3 (box), 1 (sphere), 2 (cylinder).
int sizeValues(Obstacle::Shape shape) noexcept;

}  // namespace bimanual_skills::sim
