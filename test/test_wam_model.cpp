// The WAM model's inertial data, checked against Barrett's table in its own (DH) frames: at random configurations,
// each link's mass, centre of mass and inertia expressed in the base frame must agree whether computed from the URDF
// (link frames by FK) or straight from the DH table (frames by the standard DH product).
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <urdf/model.h>

#include <array>
#include <cmath>
#include <random>
#include <string>

namespace bk = bimanual_skills::kinematics;

namespace {

using bimanual_skills::test_support::kWamUrdf;

struct DhRow {
  double a, alpha, d;
};
// Thesis Table 3.3 (standard DH).
constexpr std::array<DhRow, 7> kDh = {{{0, -M_PI / 2, 0},
                                       {0, M_PI / 2, 0},
                                       {0.045, -M_PI / 2, 0.55},
                                       {-0.045, M_PI / 2, 0},
                                       {0, -M_PI / 2, 0.3},
                                       {0, M_PI / 2, 0},
                                       {0, 0, 0.06}}};
struct Inertial {
  double mass;
  std::array<double, 3> com;
  std::array<double, 6> inertia;  // Ixx, Iyy, Izz, Ixy, Ixz, Iyz about the COM, DH frame axes
};
// Barrett wam7w.conf (Sept 2008), in DH frame i.
constexpr std::array<Inertial, 7> kBarrett = {{
    {10.7677, {-0.00443, 0.12189, -0.00066}, {0.13488, 0.11328, 0.09046, -0.00213, -0.000125, 0.000686}},
    {3.8749, {-0.00237, 0.03106, 0.01542}, {0.02141, 0.01378, 0.01559, 0.000272, 0.0000246, -0.00182}},
    {1.8023, {-0.03826, 0.20751, 0.00003}, {0.05911, 0.003246, 0.05927, -0.00250, 0.0000074, -0.0000177}},
    {2.17266, {0.005534, 0.0000682, 0.119277}, {0.010675, 0.010587, 0.002820, 0.000045, -0.001356, -0.000110}},
    {0.35656, {0.0000548, 0.028863, 0.001485}, {0.000371, 0.000194, 0.000382, -8e-8, -3e-8, -0.0000161}},
    {0.40916, {-0.0000592, -0.016861, 0.024191}, {0.000549, 0.000238, 0.000451, 1.9e-7, -1e-7, -0.0000443}},
    {0.07548, {0.000148, 0.0000725, -0.003352}, {0.0000391, 0.0000388, 0.0000761, 1.9e-7, 0, 0}},
}};

Eigen::Matrix3d inertiaMatrix(double ixx, double iyy, double izz, double ixy, double ixz, double iyz) {
  Eigen::Matrix3d I;
  I << ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz;
  return I;
}

/// Standard DH transform A_i = Rz(θ) Tz(d) Tx(a) Rx(α).
Eigen::Isometry3d dhTransform(const DhRow& row, double theta) {
  return Eigen::Isometry3d(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ())) *
         Eigen::Translation3d(row.a, 0.0, row.d) * Eigen::AngleAxisd(row.alpha, Eigen::Vector3d::UnitX());
}

}  // namespace

TEST(WamModel, InertialsEqualBarrettsInTheirDhFrames) {
  urdf::Model urdf;
  ASSERT_TRUE(urdf.initFile(kWamUrdf));
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bk::ChainData data(model);
  const Eigen::Isometry3d shoulder(Eigen::Translation3d(0.0, 0.0, 0.346));
  std::mt19937 rng(7);
  double total_mass = 0.0;
  for (int sample = 0; sample < 50; ++sample) {
    Eigen::VectorXd q(7);
    for (int i = 0; i < 7; ++i) {
      q[i] = std::uniform_real_distribution<double>(model.lowerLimits()[i], model.upperLimits()[i])(rng);
    }
    ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
    Eigen::Isometry3d dh_frame = shoulder;
    for (int i = 0; i < 7; ++i) {
      dh_frame = dh_frame * dhTransform(kDh[static_cast<std::size_t>(i)], q[i]);
      const Inertial& barrett = kBarrett[static_cast<std::size_t>(i)];
      const auto link = urdf.getLink("wam_link" + std::to_string(i + 1));
      ASSERT_TRUE(link && link->inertial);
      const auto& inertial = *link->inertial;
      EXPECT_EQ(inertial.mass, barrett.mass);
      if (sample == 0) total_mass += inertial.mass;
      const Eigen::Isometry3d& link_frame = data.frame_poses[static_cast<std::size_t>(i)];
      // The generator writes COM frames without rotation: inertia axes are the link frame's.
      ASSERT_EQ(inertial.origin.rotation.w, 1.0);
      const Eigen::Vector3d com_urdf =
          link_frame *
          Eigen::Vector3d(inertial.origin.position.x, inertial.origin.position.y, inertial.origin.position.z);
      const Eigen::Vector3d com_dh = dh_frame * Eigen::Vector3d(barrett.com[0], barrett.com[1], barrett.com[2]);
      EXPECT_LE((com_urdf - com_dh).norm(), 1e-12) << "link " << i + 1;
      const Eigen::Matrix3d I_urdf =
          link_frame.linear() *
          inertiaMatrix(inertial.ixx, inertial.iyy, inertial.izz, inertial.ixy, inertial.ixz, inertial.iyz) *
          link_frame.linear().transpose();
      const auto& b = barrett.inertia;
      const Eigen::Matrix3d I_dh =
          dh_frame.linear() * inertiaMatrix(b[0], b[1], b[2], b[3], b[4], b[5]) * dh_frame.linear().transpose();
      EXPECT_LE((I_urdf - I_dh).cwiseAbs().maxCoeff(), 1e-12) << "link " << i + 1;
    }
    // The tool frame is DH frame 7 (the flange).
    EXPECT_LE((data.tipPose().matrix() - dh_frame.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }
  EXPECT_NEAR(total_mass, 19.46, 0.01);
}

TEST(WamModel, EffortAndVelocityLimitsArePresent) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  const double effort[] = {62.6, 84.2, 50.1, 26.8, 6.9, 6.9, 1.36};
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(model.effortLimits()[i], effort[i]);
    // A joint without a velocity limit loads as +inf: require the generator's 2 rad/s.
    EXPECT_EQ(model.velocityLimits()[i], 2.0);
  }
}
