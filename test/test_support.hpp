/// \file
/// Helpers shared by the tests: the WAM models, seeded random configurations, FK, and the closed-loop test setup.
#pragma once

#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace bimanual_skills::test_support {

inline const std::string kWamUrdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/wam.urdf";

inline std::string readFile(const std::string& path) {
  return bimanual_skills::testing::readTextFile(path);
}

/// The single-arm WAM, base to tool.
inline kinematics::ChainModel wam() {
  return kinematics::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
}

/// The WAM with its reflected rotor inertias (reference/wam.md).
inline kinematics::ChainModel wamWithRotors() {
  const Eigen::VectorXd rotor = (Eigen::VectorXd(7) << 0.164, 0.148, 0.053, 0.030, 0.0028, 0.0028, 0.0003).finished();
  return wam().withRotorInertia(rotor);
}

/// A 14-joint chain of production size (both arms' worth of joints): two WAMs with rotors in series, the second
/// mounted on the first one's tool.
inline kinematics::ChainModel twoWamsInSeries() {
  const kinematics::ChainModel one = wamWithRotors();
  std::vector<kinematics::ChainJoint> joints = one.joints();
  for (kinematics::ChainJoint joint : one.joints()) {
    joint.name += "_2";
    joint.child_link += "_2";
    if (joints.size() == one.joints().size()) joint.origin = one.tipInLastFrame() * joint.origin;
    joints.push_back(joint);
  }
  return kinematics::ChainModel("wam_base", "wam_tool_2", joints, one.tipInLastFrame());
}

/// Uniform configuration within the limits (±π for unlimited joints).
using kinematics::randomWithinLimits;

/// Pose of the chain's tip at q.
inline Eigen::Isometry3d tipPose(const kinematics::ChainModel& model, const Eigen::VectorXd& q) {
  kinematics::ChainData data(model);
  EXPECT_EQ(kinematics::forwardKinematics(model, data, q), kinematics::KinematicsStatus::Success);
  return data.tipPose();
}

/// The closed-loop tests' "true" friction: a basic hysteretic model on every joint.
inline dynamics::FrictionModel hystereticFriction() {
  dynamics::FrictionModel friction;
  for (int j = 0; j < 7; ++j) {
    dynamics::JointFriction f;
    f.type = dynamics::FrictionModelType::Basic;
    f.b = Eigen::Vector2d(1.0 - 0.12 * j, 0.3);
    f.s = 20.0;
    f.z = 0.6;
    friction.joints.push_back(f);
  }
  return friction;
}

/// Computed-torque gains about a tenth of libbarrett's stiff position gains (900, 2500, 600, 500, 50, 50, 8).
inline control::ComputedTorqueGains lowGains() {
  control::ComputedTorqueGains gains;
  gains.kp = (Eigen::VectorXd(7) << 150, 150, 60, 60, 10, 10, 2.5).finished();
  gains.kv = (Eigen::VectorXd(7) << 15, 15, 6, 6, 0.6, 0.6, 0.15).finished();
  return gains;
}

/// A 1 kHz arm controller of the WAM for loop tests: low gains, a plain observer, no friction compensation, room for
/// 10 waypoints.
inline control::ArmControllerConfig loopControllerConfig() {
  control::ArmControllerConfig c;
  c.gains = lowGains();
  c.observer = control::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0);
  c.observer.rate_hz = 1000.0;
  c.friction_compensation = false;
  c.trajectory_capacity = 10;
  return c;
}

/// No friction on any of the WAM's 7 joints.
inline dynamics::FrictionModel noFriction() {
  dynamics::FrictionModel f;
  f.joints.assign(7, dynamics::JointFriction{});
  return f;
}

}  // namespace bimanual_skills::test_support
