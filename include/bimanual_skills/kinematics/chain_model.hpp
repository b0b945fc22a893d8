/// \file
/// Serial kinematic chain model: immutable geometry and limits of the joints between a base and a tip link.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace bimanual_skills::kinematics {

/// Kind of a movable joint. URDF "continuous" joints are revolute joints with infinite position limits.
enum class JointType { Revolute, Prismatic };

/// Mass properties of a rigid body: mass [kg], centre of mass [m] and inertia about the centre of mass [kg m²], both
/// expressed in the frame the body is attached to.
struct BodyInertia {
  double mass = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();

  /// The union of this body and `other` (both in the same frame), by the parallel-axis theorem.
  BodyInertia combined(const BodyInertia& other) const;
  /// The same body expressed in a frame whose pose in the current one is `pose` (com' = pose⁻¹ com, I' = Rᵀ I R).
  BodyInertia expressedIn(const Eigen::Isometry3d& pose) const;
};

/// One movable joint as read from a robot description, before the model preprocesses it.
struct ChainJoint {
  std::string name;        ///< Joint name (URDF joint).
  std::string child_link;  ///< Name of the link the joint moves (its frame is the joint frame at q = 0 offset).
  JointType type = JointType::Revolute;
  /// Pose of the joint frame in the previous movable link's frame (or in the base frame for the first joint),
  /// with every fixed joint in between folded in.
  Eigen::Isometry3d origin = Eigen::Isometry3d::Identity();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();          ///< Joint axis in the joint frame; normalised by the model.
  double lower = -std::numeric_limits<double>::infinity();  ///< Position limit [rad or m].
  double upper = std::numeric_limits<double>::infinity();   ///< Position limit [rad or m].
  double velocity = std::numeric_limits<double>::infinity();  ///< Speed limit [rad/s or m/s].
  double effort = std::numeric_limits<double>::infinity();    ///< Torque or force limit [N m or N].
  /// Mass properties of the child link and of every link fixed to it along the chain, in the child link's frame.
  BodyInertia body;
  double rotor_inertia = 0.0;  ///< Reflected rotor inertia about the joint axis [kg m²] (adds J q̈ to the torque).
};

/// Immutable model of a serial chain. Build it once (it may allocate and throw), share it between any number of
/// ChainData scratch objects.
///
/// Internally each joint frame is re-expressed so that its axis is the local z axis (F_i = L_i R_i, where L_i is the
/// URDF link frame and R_i a constant rotation taking z onto the joint axis); forward kinematics then needs only a
/// rotation about z per joint. For URDFs whose axes are already z (the WAM's), R_i is the identity.
class ChainModel {
 public:
  /// Builds a chain from its movable joints (base to tip) and the fixed pose of the tip in the last joint's link frame.
  /// \throws std::invalid_argument on an empty chain, a zero axis, non-finite poses or inverted limits.
  ChainModel(std::string base_link, std::string tip_link, std::vector<ChainJoint> joints,
             const Eigen::Isometry3d& tip_offset);

  /// Loads the chain between two links of a URDF file (urdfdom). Fixed joints are folded into the next joint.
  /// \throws std::invalid_argument if the file cannot be read or parsed, a link is unknown, base is not an ancestor
  /// of tip (not a serial chain from base to tip), or the chain has unsupported (floating, planar, mimic) joints.
  static ChainModel fromUrdfFile(const std::string& path, const std::string& base_link, const std::string& tip_link);
  /// As fromUrdfFile, from the XML text of the robot description (e.g. the robot_description parameter).
  static ChainModel fromUrdfString(const std::string& urdf_xml, const std::string& base_link,
                                   const std::string& tip_link);

  /// Number of movable joints n (the size of q).
  int nq() const noexcept { return static_cast<int>(joints_.size()); }
  const std::string& baseLink() const noexcept { return base_link_; }
  const std::string& tipLink() const noexcept { return tip_link_; }
  /// The movable joints as given, base to tip (origins and axes in URDF frames).
  const std::vector<ChainJoint>& joints() const noexcept { return joints_; }
  std::vector<std::string> jointNames() const;
  /// Frame names for FK output: the child link of every movable joint, then the tip link (n + 1 names).
  const std::vector<std::string>& frameNames() const noexcept { return frame_names_; }
  /// Index of a frame in frameNames(), or -1 when the chain has no such frame.
  int frameIndex(const std::string& name) const noexcept;

  const Eigen::VectorXd& lowerLimits() const noexcept { return lower_; }
  const Eigen::VectorXd& upperLimits() const noexcept { return upper_; }
  const Eigen::VectorXd& velocityLimits() const noexcept { return velocity_; }
  const Eigen::VectorXd& effortLimits() const noexcept { return effort_; }
  /// Upper bound on the distance from the first joint's origin to the tip over all configurations (sum of the
  /// link offsets after the first joint, plus the largest travel of prismatic joints). Targets farther than this
  /// from the first joint are unreachable.
  double reachBound() const noexcept { return reach_bound_; }
  /// Origin of the first joint in the base frame (fixed: the first joint does not move itself).
  Eigen::Vector3d firstJointOrigin() const noexcept { return joints_.front().origin.translation(); }

  /// True when q has size nq(), is finite and lies within [lower - tolerance, upper + tolerance].
  /// Real-time safe: no allocation, no exceptions.
  bool withinLimits(const Eigen::Ref<const Eigen::VectorXd>& q, double tolerance = 0.0) const noexcept;

  /// Gravity acceleration in the base frame [m/s²] (default (0, 0, −9.81)).
  const Eigen::Vector3d& gravity() const noexcept { return gravity_; }
  /// A copy of this model with another gravity vector (base frame).
  ChainModel withGravity(const Eigen::Vector3d& gravity) const;
  /// A copy of this model with reflected rotor inertias (one per joint, ≥ 0) added to the dynamics.
  /// \throws std::invalid_argument on a wrong size, negative or non-finite values.
  ChainModel withRotorInertia(const Eigen::VectorXd& rotor_inertia) const;
  const Eigen::VectorXd& rotorInertia() const noexcept { return rotor_; }

  /// Internal z-axis frame data (see class comment), for the kinematics functions.
  struct AxisFrame {
    Eigen::Matrix3d rotation;     ///< Rotation part of R_{i-1}^T O_i R_i.
    Eigen::Vector3d translation;  ///< Translation part of R_{i-1}^T O_i R_i.
    Eigen::Matrix3d to_link;      ///< R_i^T: L_i = F_i R_i^T (identity when the URDF axis is +z).
    bool axis_is_z = true;        ///< R_i is the identity.
    bool prismatic = false;
    BodyInertia body;                ///< The joint's body in the internal frame F_i (for the dynamics).
    Eigen::Vector3d first_moment;    ///< m c of the body in F_i (for the composite-rigid-body algorithm).
    Eigen::Matrix3d origin_inertia;  ///< The body's rotational inertia about F_i's origin, I_c + m (|c|² 1 − c cᵀ).
  };
  const std::vector<AxisFrame>& axisFrames() const noexcept { return axis_frames_; }
  /// `out` = `R` Rz(q): a revolute joint turns the x and y columns of its frame about its z axis (2 sin/cos, 12
  /// multiplications instead of a 3 × 3 product). Real-time safe.
  static void turnAboutZ(const Eigen::Matrix3d& R, double q, Eigen::Matrix3d& out) noexcept {
    const double c = std::cos(q), s = std::sin(q);
    out.col(0) = c * R.col(0) + s * R.col(1);
    out.col(1) = c * R.col(1) - s * R.col(0);
    out.col(2) = R.col(2);
  }
  /// Pose of the tip in the internal frame of the last joint, R_n^T T_tip.
  const Eigen::Isometry3d& tipInLastFrame() const noexcept { return tip_in_last_; }

 private:
  std::string base_link_;
  std::string tip_link_;
  std::vector<ChainJoint> joints_;
  std::vector<std::string> frame_names_;
  std::vector<AxisFrame> axis_frames_;
  Eigen::Isometry3d tip_in_last_;
  Eigen::VectorXd lower_, upper_, velocity_, effort_, rotor_;
  Eigen::Vector3d gravity_ = Eigen::Vector3d(0.0, 0.0, -9.81);
  double reach_bound_ = 0.0;
};

/// A configuration uniform within the joint limits (±π for unlimited joints), drawn from `rng` joint by joint.
Eigen::VectorXd randomWithinLimits(const ChainModel& model, std::mt19937& rng);

/// The middle of each joint's range (0 for unlimited joints): a seed that favours no branch.
Eigen::VectorXd middleOfLimits(const ChainModel& model);

/// Where a link fixed to a URDF's root sits: its pose in the root link's frame, and the root's name.
struct FixedLinkPose {
  Eigen::Isometry3d pose;
  std::string root;
};

/// The pose of `link` in the root frame of the robot description `urdf_xml` (an arm's base in the world).
/// \throws std::invalid_argument for invalid URDF, an unknown link, or a moving joint between it and the root.
FixedLinkPose fixedLinkPose(const std::string& urdf_xml, const std::string& link);

}  // namespace bimanual_skills::kinematics
