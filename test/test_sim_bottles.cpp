// Free obstacles (the bottles of thesis Sec. 6.2, Fig. 6.8): one standing on the table stays up, one started past
// its tipping angle (atan(2r / h)) falls and one short of it rights itself, one beside the table falls off, an arm
// sweeping through one knocks it over while the arm held still does not, a reset stands it up again, and bad files are
// refused by name.
#include "bimanual_skills/sim/bimanual_simulation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
using bs::sim::BimanualSimulation;
using bs::sim::Obstacle;
using bs::sim::SimConfig;

namespace {

constexpr double kRadius = 0.035, kLength = 0.25;

std::string configFile(const std::string& name) {
  return std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/" + name;
}

/// The tracking scene without its object: two WAMs and the table.
SimConfig scene() {
  SimConfig config = SimConfig::fromYamlFile(configFile("track_sim.yaml"));
  config.has_object = false;
  return config;
}

Obstacle bottle(const std::string& name, const Eigen::Vector3d& base, double tilt = 0.0) {
  Obstacle o;
  o.name = name;
  o.shape = Obstacle::Shape::Cylinder;
  o.size = Eigen::Vector3d(kRadius, kLength, 0.0);
  o.mass = 0.4;
  o.friction = 0.6;
  // Upright with its bottom's centre on `base`, then turned by `tilt` about the world x axis (its axis leaning
  // towards −y) about the point of its bottom rim on that side, which stays on the table.
  const Eigen::AngleAxisd turn(tilt, Eigen::Vector3d::UnitX());
  const Eigen::Vector3d rim(0.0, tilt > 0.0 ? -kRadius : 0.0, 0.0);
  o.pose.linear() = turn.toRotationMatrix();
  o.pose.translation() = base + rim + turn * (Eigen::Vector3d(0.0, 0.0, 0.5 * kLength) - rim);
  return o;
}

double tiltOf(const BimanualSimulation& simulation, int k) {
  return std::acos(std::clamp(simulation.obstaclePose(k).linear()(2, 2), -1.0, 1.0));
}

/// Steps `seconds` holding every arm at its state with a stiff joint PD, `target(arm, t)` as the set point.
template <typename Target>
void hold(BimanualSimulation& simulation, double seconds, Target target) {
  const int steps = static_cast<int>(std::lround(seconds / simulation.stepSize()));
  for (int i = 0; i < steps; ++i) {
    for (int a = 0; a < simulation.armCount(); ++a) {
      const bs::sim::ArmState& s = simulation.trueState(a);
      const Eigen::VectorXd tau = 300.0 * (target(a, simulation.time()) - s.q) - 20.0 * s.qd;
      ASSERT_EQ(simulation.writeJointTorques(a, tau), bs::sim::RobotStatus::Ok);
    }
    ASSERT_EQ(simulation.step(), bs::sim::SimStatus::Ok) << "at step " << i;
  }
}

}  // namespace

TEST(SimulatedBottles, StandFallPastTheirTippingAngleAndRightThemselvesShortOfIt) {
  SimConfig config = scene();
  const double top = config.table.pose.translation().z() + 0.5 * config.table.size.z();
  const double tipping = std::atan(2.0 * kRadius / kLength);  // 15.6°
  const Eigen::Vector3d centre = config.table.pose.translation();
  // In a row across x, each leaning (if at all) towards −y: apart as they fall.
  config.obstacles = {bottle("upright", Eigen::Vector3d(centre.x() - 0.2, centre.y(), top)),
                      bottle("past", Eigen::Vector3d(centre.x(), centre.y(), top), tipping + 0.25),
                      bottle("short", Eigen::Vector3d(centre.x() + 0.2, centre.y(), top), tipping - 0.08),
                      // Upright beside the table: it falls off, upright, and is down all the same.
                      bottle("off", Eigen::Vector3d(centre.x(), centre.y() + 0.5 * config.table.size.y() + 0.1, top))};
  BimanualSimulation simulation(config);
  ASSERT_EQ(simulation.resetToStart(), bs::sim::SimStatus::Ok);
  std::vector<Eigen::VectorXd> q0;
  for (int a = 0; a < simulation.armCount(); ++a) q0.push_back(simulation.trueState(a).q);
  hold(simulation, 2.0, [&](int a, double) { return q0[static_cast<std::size_t>(a)]; });
  std::printf("after 2 s: upright %.4f rad, past %.3f rad, short %.4f rad (tipping angle %.3f)\n",
              tiltOf(simulation, 0), tiltOf(simulation, 1), tiltOf(simulation, 2), tipping);
  EXPECT_LT(tiltOf(simulation, 0), 0.01);
  EXPECT_LT((simulation.obstaclePose(0).translation() - config.obstacles[0].pose.translation()).norm(), 0.002);
  EXPECT_GT(tiltOf(simulation, 1), 1.2) << "it should lie on the table";
  EXPECT_LT(tiltOf(simulation, 2), 0.05) << "it should stand up again";
  EXPECT_LT(tiltOf(simulation, 3), 0.01);
  EXPECT_LT(simulation.obstaclePose(3).translation().z(), top - 1.0);
  EXPECT_EQ(simulation.knockedOver(), 2);
  // A static obstacle's pose is its own; an index outside the list is refused.
  EXPECT_THROW(simulation.obstaclePose(4), std::out_of_range);
  EXPECT_THROW(simulation.obstaclePose(-1), std::out_of_range);
}

TEST(SimulatedBottles, AnArmSweepingThroughOneKnocksItOverAndAResetStandsItUp) {
  SimConfig config = scene();
  BimanualSimulation probe(config);
  ASSERT_EQ(probe.resetToStart(), bs::sim::SimStatus::Ok);
  const Eigen::Isometry3d base = probe.basePose(0);
  const Eigen::Vector3d tool = probe.toolPose(0).translation();
  // After 3 s at rest (past Bullet's 2 s before a resting body sleeps: the arm's link must wake it) the left arm turns
  // its first joint (about its base's z axis) by 0.6 rad in 1.5 s; a bottle stands on a pedestal where the tool passes
  // at 0.3 rad, its middle at the tool's height.
  const Eigen::Vector3d axis = base.linear().col(2);
  const Eigen::Vector3d at = base.translation() + Eigen::AngleAxisd(0.3, axis) * (tool - base.translation());
  Obstacle pedestal;
  pedestal.name = "pedestal";
  pedestal.shape = Obstacle::Shape::Box;
  pedestal.size = Eigen::Vector3d(0.4, 0.4, 0.02);  // wide enough to catch it lying
  pedestal.pose.translation() = at - Eigen::Vector3d(0.0, 0.0, 0.5 * kLength + 0.01);
  config.obstacles = {pedestal, bottle("bottle", at - Eigen::Vector3d(0.0, 0.0, 0.5 * kLength))};
  for (const bool sweep : {false, true}) {
    BimanualSimulation simulation(config);
    ASSERT_EQ(simulation.resetToStart(), bs::sim::SimStatus::Ok);
    std::vector<Eigen::VectorXd> q0;
    for (int a = 0; a < simulation.armCount(); ++a) q0.push_back(simulation.trueState(a).q);
    hold(simulation, 5.5, [&](int a, double t) {
      Eigen::VectorXd q = q0[static_cast<std::size_t>(a)];
      if (sweep && a == 0) q[0] += 0.6 * std::clamp((t - 3.0) / 1.5, 0.0, 1.0);
      return q;
    });
    std::printf("%s: the bottle tilted %.3f rad\n", sweep ? "the arm sweeping" : "the arm held still",
                tiltOf(simulation, 1));
    EXPECT_EQ(simulation.knockedOver(), sweep ? 1 : 0);
    if (!sweep) continue;
    EXPECT_GT(tiltOf(simulation, 1), 1.2) << "it should lie on the pedestal";
    std::vector<bs::sim::ArmState> states;
    for (int a = 0; a < simulation.armCount(); ++a) states.push_back(probe.trueState(a));
    ASSERT_EQ(simulation.reset(states), bs::sim::SimStatus::Ok);
    EXPECT_EQ(simulation.knockedOver(), 0);
    EXPECT_TRUE(simulation.obstaclePose(1).isApprox(config.obstacles[1].pose, 1e-12));
  }
}

TEST(SimulatedBottles, BadFreeObstaclesAreRefusedByName) {
  SimConfig config = scene();
  Obstacle b = bottle("b", Eigen::Vector3d(0.5, 0.0, 0.5));
  b.mass = -1.0;
  EXPECT_THROW(b.validate("scene"), std::invalid_argument);
  b.mass = std::nan("");
  EXPECT_THROW(b.validate("scene"), std::invalid_argument);
  b.mass = 0.4;
  b.collides = false;
  EXPECT_THROW(b.validate("scene"), std::invalid_argument);
  // Not with a cloth; from a file with a mass.
  SimConfig with_cloth = SimConfig::fromYamlFile(configFile("sim.yaml"));
  with_cloth.obstacles = {bottle("b", Eigen::Vector3d(0.5, 0.0, 0.5))};
  try {
    with_cloth.validate();
    ADD_FAILURE() << "a free obstacle beside the cloth was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'b'"), std::string::npos) << e.what();
  }
  const std::string file = testing::TempDir() + "/bottle_scene.yaml";
  std::ofstream(file) << "robot: " << configFile("robots/wam.yaml")
                      << "\nobstacles:\n  - {name: b, shape: cylinder, size: [0.035, 0.25], xyz: [0.6, 0, 0.5], "
                         "mass: 0.4}\n";
  const SimConfig read = SimConfig::fromYamlFile(file);
  ASSERT_EQ(read.obstacles.size(), 1u);
  EXPECT_EQ(read.obstacles[0].mass, 0.4);
  std::ofstream(file) << "robot: " << configFile("robots/wam.yaml")
                      << "\nobstacles:\n  - {name: b, shape: cylinder, size: [0.035, 0.25], mass: x}\n";
  EXPECT_THROW(SimConfig::fromYamlFile(file), std::invalid_argument);
}
