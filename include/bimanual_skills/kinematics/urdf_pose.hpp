/// \file
/// A URDF pose (urdfdom) as an Eigen transform, and a fixed link's pose in the model's root, for the loaders of URDF
/// files (kinematics' chain loader, the simulator's Bullet arms). Public, so that no module includes another's private
/// header; it needs urdfdom's headers (urdf_model/pose.h), which only the loaders have.
#pragma once

#include <urdf_model/model.h>
#include <urdf_model/pose.h>

#include <Eigen/Geometry>

#include <stdexcept>
#include <string>

namespace bimanual_skills::kinematics {

/// The rigid transform of a URDF pose (its quaternion normalised).
inline Eigen::Isometry3d toIsometry(const urdf::Pose& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() << pose.position.x, pose.position.y, pose.position.z;
  out.linear() = Eigen::Quaterniond(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z)
                     .normalized()
                     .toRotationMatrix();
  return out;
}

/// The pose of link `name` (which `urdf` has) in the frame of the model's root link, through fixed joints only (an
/// arm's base in the world); `root` gets the root's name. \throws std::invalid_argument naming the link and the joint
/// when a joint on the way moves: "link 'x' is not fixed to the world (joint 'j' moves)".
inline Eigen::Isometry3d poseInRoot(const urdf::ModelInterface& urdf, const std::string& name, std::string* root) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  urdf::LinkConstSharedPtr link = urdf.getLink(name);
  while (link->parent_joint) {
    const urdf::JointConstSharedPtr& joint = link->parent_joint;
    if (joint->type != urdf::Joint::FIXED) {
      throw std::invalid_argument("link '" + name + "' is not fixed to the world (joint '" + joint->name + "' moves)");
    }
    pose = toIsometry(joint->parent_to_joint_origin_transform) * pose;
    link = urdf.getLink(joint->parent_link_name);
  }
  if (root) *root = link->name;
  return pose;
}

}  // namespace bimanual_skills::kinematics
