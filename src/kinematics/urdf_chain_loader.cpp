// Loading a ChainModel from a URDF robot description with urdfdom.
#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/kinematics/urdf_pose.hpp"

#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::kinematics {
namespace {

/// Mass properties of a URDF link in the link's frame (none when it has no <inertial>).
BodyInertia linkInertia(const urdf::LinkConstSharedPtr& link) {
  BodyInertia body;
  if (!link || !link->inertial) return body;
  const urdf::Inertial& in = *link->inertial;
  const Eigen::Isometry3d frame = toIsometry(in.origin);  // the inertial frame in the link frame
  body.mass = in.mass;
  body.com = frame.translation();
  Eigen::Matrix3d inertia;
  inertia << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
  body.inertia = frame.linear() * inertia * frame.linear().transpose();
  return body;
}

std::string describe(const std::string& base_link, const std::string& tip_link) {
  return "URDF chain '" + base_link + "' -> '" + tip_link + "': ";
}

}  // namespace

ChainModel ChainModel::fromUrdfString(const std::string& urdf_xml, const std::string& base_link,
                                      const std::string& tip_link) {
  const std::string where = describe(base_link, tip_link);
  const urdf::ModelInterfaceSharedPtr urdf = urdf::parseURDF(urdf_xml);
  if (!urdf) {
    throw std::invalid_argument(where + "the robot description is not valid URDF");
  }
  for (const std::string& name : {base_link, tip_link}) {
    if (!urdf->getLink(name)) {
      throw std::invalid_argument(where + "unknown link '" + name + "' in robot '" + urdf->getName() + "'");
    }
  }

  // Walk from the tip up to the base; every joint on the way must be a child-of relation (a serial path).
  std::vector<urdf::JointConstSharedPtr> path;
  for (urdf::LinkConstSharedPtr link = urdf->getLink(tip_link); link->name != base_link;) {
    const urdf::JointConstSharedPtr joint = link->parent_joint;
    if (!joint) {
      throw std::invalid_argument(where + "'" + base_link + "' is not an ancestor of '" + tip_link +
                                  "': the links are not joined by a serial chain from base to tip");
    }
    path.push_back(joint);
    link = urdf->getLink(joint->parent_link_name);
  }
  std::reverse(path.begin(), path.end());

  std::vector<ChainJoint> joints;
  Eigen::Isometry3d fixed = Eigen::Isometry3d::Identity();  // fixed joints since the last movable one
  for (const urdf::JointConstSharedPtr& joint : path) {
    const Eigen::Isometry3d origin = fixed * toIsometry(joint->parent_to_joint_origin_transform);
    if (joint->type == urdf::Joint::FIXED) {
      fixed = origin;
      // A link fixed to the last moving body moves with it (links before the first movable joint do not move).
      if (!joints.empty()) {
        const BodyInertia attached = linkInertia(urdf->getLink(joint->child_link_name)).expressedIn(fixed.inverse());
        joints.back().body = joints.back().body.combined(attached);
      }
      continue;
    }
    if (joint->type != urdf::Joint::REVOLUTE && joint->type != urdf::Joint::CONTINUOUS &&
        joint->type != urdf::Joint::PRISMATIC) {
      throw std::invalid_argument(where + "joint '" + joint->name +
                                  "' is floating or planar; only revolute, continuous, prismatic and fixed "
                                  "joints make a serial chain");
    }
    if (joint->mimic) {
      throw std::invalid_argument(where + "joint '" + joint->name +
                                  "' mimics another joint; coupled joints are "
                                  "not supported in a serial chain");
    }
    ChainJoint out;
    out.name = joint->name;
    out.child_link = joint->child_link_name;
    out.type = joint->type == urdf::Joint::PRISMATIC ? JointType::Prismatic : JointType::Revolute;
    out.origin = origin;
    out.axis << joint->axis.x, joint->axis.y, joint->axis.z;
    if (joint->limits) {
      if (joint->type != urdf::Joint::CONTINUOUS) {
        out.lower = joint->limits->lower;
        out.upper = joint->limits->upper;
      }
      if (joint->limits->velocity > 0.0) out.velocity = joint->limits->velocity;
      if (joint->limits->effort > 0.0) out.effort = joint->limits->effort;
    }
    out.body = linkInertia(urdf->getLink(joint->child_link_name));
    joints.push_back(out);
    fixed.setIdentity();
  }
  return ChainModel(base_link, tip_link, std::move(joints), fixed);
}

FixedLinkPose fixedLinkPose(const std::string& urdf_xml, const std::string& link_name) {
  const urdf::ModelInterfaceSharedPtr urdf = urdf::parseURDF(urdf_xml);
  if (!urdf) throw std::invalid_argument("the robot description is not valid URDF");
  urdf::LinkConstSharedPtr link = urdf->getLink(link_name);
  if (!link) throw std::invalid_argument("unknown link '" + link_name + "' in robot '" + urdf->getName() + "'");
  FixedLinkPose out;
  out.pose = poseInRoot(*urdf, link_name, &out.root);
  return out;
}

ChainModel ChainModel::fromUrdfFile(const std::string& path, const std::string& base_link,
                                    const std::string& tip_link) {
  std::ifstream file(path);
  if (!file) {
    throw std::invalid_argument(describe(base_link, tip_link) + "cannot read URDF file '" + path + "'");
  }
  std::stringstream text;
  text << file.rdbuf();
  return fromUrdfString(text.str(), base_link, tip_link);
}

}  // namespace bimanual_skills::kinematics
