// The moving object of the tracking experiment (thesis Sec. 4.3.2): its seeded path (bounds checked by finite
// differences of the sampled positions, not by the formulas that chose the move times), the simulation carrying it,
// a gripper holding it and letting it go, and the camera seeing it where the simulation put it.
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/sim/object_path.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

namespace bs = bimanual_skills;
using bs::sim::ObjectPath;
using bs::sim::ObjectPathConfig;

namespace {

std::string configFile(const std::string& name) {
  return std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/" + name;
}

struct Measured {
  double max_speed = 0.0, max_acceleration = 0.0, max_position_jump = 0.0, resting = 0.0, away = 0.0;
};

/// Speeds and accelerations of the sampled positions by central differences (h = 1 ms) over the whole path.
Measured measure(const ObjectPath& path) {
  Measured m;
  const double h = 1e-3;
  for (double t = h; t < path.end() - h; t += h) {
    const Eigen::Vector3d before = path.at(t - h).position, now = path.at(t).position, after = path.at(t + h).position;
    m.max_speed = std::max(m.max_speed, (after - before).norm() / (2 * h));
    m.max_acceleration = std::max(m.max_acceleration, (after - 2 * now + before).norm() / (h * h));
    m.max_position_jump = std::max(m.max_position_jump, (now - before).norm());
    if ((after - before).norm() < 1e-12) m.resting += h;
    if (path.at(t).away) m.away += h;
  }
  return m;
}

}  // namespace

TEST(ObjectPath, KeepsItsSpeedAndAccelerationBoundsOnEverySeed) {
  ObjectPathConfig config;
  config.duration = 120.0;
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    config.seed = seed;
    const ObjectPath path(config);
    const Measured m = measure(path);
    EXPECT_LE(m.max_speed, config.max_speed * 1.0001) << "seed " << seed;
    EXPECT_LE(m.max_acceleration, config.max_acceleration * 1.001) << "seed " << seed;
    // It moves at its limits on some moves (min_speed_ratio 0.3 leaves the top of the range to chance).
    EXPECT_GT(m.max_speed, 0.6 * config.max_speed) << "seed " << seed;
    EXPECT_LT(m.max_position_jump, config.max_speed * 1e-3 * 1.0001) << "seed " << seed;
    EXPECT_GE(path.end(), config.duration);
  }
}

TEST(ObjectPath, AnalyticVelocityAndAccelerationMatchFiniteDifferences) {
  const ObjectPath path(ObjectPathConfig{});
  const double h = 1e-5;
  for (double t = 0.013; t < path.end(); t += 0.37) {
    const bs::sim::ObjectPathSample s = path.at(t);
    const Eigen::Vector3d v = (path.at(t + h).position - path.at(t - h).position) / (2 * h);
    const Eigen::Vector3d a = (path.at(t + h).velocity - path.at(t - h).velocity) / (2 * h);
    EXPECT_LT((v - s.velocity).norm(), 1e-6) << "t = " << t;
    EXPECT_LT((a - s.acceleration).norm(), 1e-4) << "t = " << t;
  }
}

TEST(ObjectPath, StaysInItsRegionExceptOnTripsAwayAndPausesAsAsked) {
  ObjectPathConfig config;
  config.duration = 300.0;
  config.seed = 3;
  const ObjectPath path(config);
  int trips = 0, pauses = 0;
  for (const ObjectPath::Segment& s : path.segments()) {
    EXPECT_GT(s.length, 0.0);
    if (s.away) {
      trips += s.to == s.from ? 1 : 0;  // the rest out of view
      continue;
    }
    if (s.to == s.from && s.start > 0.0) ++pauses;
    const Eigen::Vector3d offset = (s.to - config.centre).cwiseAbs();
    EXPECT_TRUE((offset.array() <= 0.5 * config.size.array() + 1e-12).all()) << offset.transpose();
  }
  // 300 s of moves of ~1-2 s: about 0.1 of them trips away and 0.3 followed by a pause.
  EXPECT_GE(trips, 3);
  EXPECT_GE(pauses, 5);
  const Measured m = measure(path);
  EXPECT_GT(m.resting, 0.05 * path.end());
  EXPECT_GT(m.away, 0.02 * path.end());
  // Out of view: at centre + away during the rest there.
  for (const ObjectPath::Segment& s : path.segments()) {
    if (s.away && s.to == s.from) {
      EXPECT_TRUE(s.to.isApprox(config.centre + config.away));
    }
  }
}

TEST(ObjectPath, IsTheSameForOneSeedAndDiffersBetweenSeeds) {
  ObjectPathConfig config;
  const ObjectPath a(config), b(config);
  config.seed = 2;
  const ObjectPath c(config);
  EXPECT_EQ(a.at(17.3).position, b.at(17.3).position);
  EXPECT_GT((a.at(17.3).position - c.at(17.3).position).norm(), 1e-3);
  // Before the start it is at the centre; after the end it rests where the last move ended.
  EXPECT_EQ(a.at(-1.0).position, config.centre);
  EXPECT_EQ(a.at(a.end() + 5.0).position, a.segments().back().to);
  EXPECT_TRUE(a.at(a.end() + 5.0).velocity.isZero());
}

TEST(ObjectPath, RefusesBadSettingsByName) {
  const auto refused = [](auto change, const std::string& entry) {
    ObjectPathConfig config;
    change(config);
    try {
      ObjectPath path(config);
      ADD_FAILURE() << entry << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(entry), std::string::npos) << e.what();
    }
  };
  refused([](ObjectPathConfig& c) { c.max_speed = 0.0; }, "max_speed");
  refused([](ObjectPathConfig& c) { c.max_acceleration = std::nan(""); }, "max_acceleration");
  refused([](ObjectPathConfig& c) { c.size.x() = -1.0; }, "size");
  refused([](ObjectPathConfig& c) { c.pause = Eigen::Vector2d(2.0, 1.0); }, "pause");
  refused([](ObjectPathConfig& c) { c.away_probability = 1.5; }, "away_probability");
  refused([](ObjectPathConfig& c) { c.duration = 1e9; }, "duration");
  // A region of no extent is no endless loop: the object rests.
  ObjectPathConfig still;
  still.size.setZero();
  still.away_probability = 0.0;
  const ObjectPath path(still);
  EXPECT_TRUE(path.at(10.0).position.isApprox(still.centre));
}

TEST(SimulatedObject, FollowsItsPathIsHeldByAClosingGripperNearItAndRestsWhereLetGo) {
  bs::sim::SimConfig config = bs::sim::SimConfig::fromYamlFile(configFile("track_sim.yaml"));
  ASSERT_TRUE(config.has_object);
  bs::sim::BimanualSimulation simulation(config);
  const ObjectPath path(config.object.path);
  for (int i = 0; i < 3000; ++i) ASSERT_EQ(simulation.step(), bs::sim::SimStatus::Ok);
  EXPECT_TRUE(simulation.objectPose().translation().isApprox(path.at(simulation.time()).position, 1e-12));
  EXPECT_TRUE(simulation.objectVelocity().isApprox(path.at(simulation.time()).velocity, 1e-12));
  // A tool far from the grasp point closes on nothing and says so.
  bool held = true;
  int nodes = -1;
  EXPECT_EQ(simulation.grasp(0, &nodes, &held), bs::sim::SimStatus::Ok);
  EXPECT_FALSE(held);
  EXPECT_EQ(nodes, 0);
  EXPECT_EQ(simulation.objectHolder(), -1);
  // Put the grasp point at the left tool: bring the path's centre there by moving the object's region.
  bs::sim::SimConfig near = config;
  const Eigen::Vector3d tool = simulation.toolPose(0).translation();
  near.object.path.centre = tool - near.object.grasp_point + Eigen::Vector3d(0.0, 0.0, 0.01);
  near.object.path.size.setZero();
  near.object.path.away_probability = 0.0;
  // Held, it moves with the tool (the first joint pushed round) and keeps its place in the gripper; it overlaps the
  // hand and is part of it: the arm moves as it does with an object it does not feel, to the bit.
  Eigen::VectorXd push = Eigen::VectorXd::Zero(simulation.jointCount(0));
  push[0] = 30.0;
  Eigen::VectorXd felt, unfelt;
  for (const bool collides : {false, true}) {
    bs::sim::SimConfig c = near;
    c.object.body.collides = collides;
    bs::sim::BimanualSimulation probe(c);
    ASSERT_TRUE(probe.grasp(0, nullptr, &held) == bs::sim::SimStatus::Ok && held);
    ASSERT_EQ(probe.writeJointTorques(0, push), bs::sim::RobotStatus::Ok);
    for (int i = 0; i < 300; ++i) ASSERT_EQ(probe.step(), bs::sim::SimStatus::Ok);
    (collides ? felt : unfelt) = probe.trueState(0).q;
  }
  EXPECT_LT((felt - unfelt).cwiseAbs().maxCoeff(), 1e-12) << "the held can pushed the hand";
  bs::sim::BimanualSimulation holding(near);
  ASSERT_TRUE(holding.grasp(1, nullptr, &held) == bs::sim::SimStatus::Ok);
  EXPECT_FALSE(held) << "the right tool is far";
  ASSERT_TRUE(holding.grasp(0, nullptr, &held) == bs::sim::SimStatus::Ok);
  EXPECT_TRUE(held);
  EXPECT_EQ(holding.objectHolder(), 0);
  const Eigen::Isometry3d in_tool = holding.toolPose(0).inverse() * holding.objectPose();
  ASSERT_EQ(holding.writeJointTorques(0, push), bs::sim::RobotStatus::Ok);
  for (int i = 0; i < 500; ++i) ASSERT_EQ(holding.step(), bs::sim::SimStatus::Ok);
  EXPECT_GT((holding.toolPose(0).translation() - tool).norm(), 0.01) << "the arm did not move";
  EXPECT_TRUE((holding.toolPose(0) * in_tool).isApprox(holding.objectPose(), 1e-9));
  // A second gripper cannot take it; let go, it rests there however the arm moves on.
  EXPECT_TRUE(holding.grasp(1, nullptr, &held) == bs::sim::SimStatus::Ok && !held);
  ASSERT_EQ(holding.release(0), bs::sim::SimStatus::Ok);
  const Eigen::Isometry3d let_go = holding.objectPose();
  for (int i = 0; i < 300; ++i) ASSERT_EQ(holding.step(), bs::sim::SimStatus::Ok);
  EXPECT_EQ(holding.objectHolder(), -1);
  EXPECT_TRUE(holding.objectPose().isApprox(let_go));
  EXPECT_TRUE(holding.objectVelocity().isZero());
  // A reset puts it back on its path's start, held by nobody.
  std::vector<bs::sim::ArmState> start;
  for (int a = 0; a < holding.armCount(); ++a) start.push_back(holding.trueState(a));
  ASSERT_EQ(holding.reset(start), bs::sim::SimStatus::Ok);
  EXPECT_TRUE(holding.objectPose().translation().isApprox(near.object.path.centre));
}

TEST(SimulatedObject, APersonCarriesItToTheHandWithinItsBoundsUntilReset) {
  bs::sim::SimConfig config = bs::sim::SimConfig::fromYamlFile(configFile("track_sim.yaml"));
  bs::sim::BimanualSimulation simulation(config);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(simulation.step(), bs::sim::SimStatus::Ok);
  const Eigen::Vector3d start = simulation.objectPose().translation();
  const Eigen::Vector3d hand = start + Eigen::Vector3d(0.1, -0.15, 0.05);
  EXPECT_EQ(simulation.carryObject(Eigen::Vector3d(NAN, 0.0, 0.0)), bs::sim::SimStatus::InvalidArgument);
  EXPECT_EQ(simulation.carryObject(Eigen::Vector3d(0.0, 1e6, 0.0)), bs::sim::SimStatus::InvalidArgument);
  {
    bimanual_skills::testing::NoAllocGuard guard;
    ASSERT_EQ(simulation.carryObject(hand), bs::sim::SimStatus::Ok);
  }
  double fastest = 0.0, hardest = 0.0;
  Eigen::Vector3d before = simulation.objectVelocity();
  for (int i = 0; i < 3000; ++i) {
    ASSERT_EQ(simulation.step(), bs::sim::SimStatus::Ok);
    const Eigen::Vector3d v = simulation.objectVelocity();
    fastest = std::max(fastest, v.norm());
    hardest = std::max(hardest, (v - before).norm() / config.step);
    before = v;
  }
  // Off its path, at the hand, within the path's bounds.
  EXPECT_LT((simulation.objectPose().translation() - hand).norm(), 1e-3);
  EXPECT_GT(
      (simulation.objectPose().translation() - ObjectPath(config.object.path).at(simulation.time()).position).norm(),
      0.01);
  EXPECT_LE(fastest, config.object.path.max_speed + 1e-9);
  EXPECT_LE(hardest, config.object.path.max_acceleration + 1e-6);
  // A reset puts it back on its path.
  std::vector<bs::sim::ArmState> state;
  for (int a = 0; a < simulation.armCount(); ++a) state.push_back(simulation.trueState(a));
  ASSERT_EQ(simulation.reset(state), bs::sim::SimStatus::Ok);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(simulation.step(), bs::sim::SimStatus::Ok);
  EXPECT_TRUE(simulation.objectPose().translation().isApprox(
      ObjectPath(config.object.path).at(simulation.time()).position, 1e-12));
  bs::sim::SimConfig without = bs::sim::SimConfig::fromYamlFile(configFile("bottles_sim.yaml"));
  EXPECT_EQ(bs::sim::BimanualSimulation(without).carryObject(hand), bs::sim::SimStatus::NoCloth);
}

TEST(SimulatedObject, TheArmsFeelItWhenItCollides) {
  // The object driven through the resting left tool pushes it away; one that does not collide passes through.
  bs::sim::SimConfig config = bs::sim::SimConfig::fromYamlFile(configFile("track_sim.yaml"));
  double moved[2];
  for (const bool collides : {true, false}) {
    bs::sim::BimanualSimulation probe(config);
    const Eigen::Isometry3d tool = probe.toolPose(0);
    config.object.body.collides = collides;
    config.object.path.centre = tool.translation() + Eigen::Vector3d(0.0, 0.0, 0.15);
    config.object.path.size.setZero();
    config.object.path.away = Eigen::Vector3d(0.0, 0.0, -0.3);  // down through the tool and back
    config.object.path.away_probability = 1.0;
    config.object.path.start_pause = 0.0;
    bs::sim::BimanualSimulation simulation(config);
    // Hold the arms still against gravity with a stiff joint PD.
    const bs::sim::ArmState initial = simulation.trueState(0);
    double farthest = 0.0;
    for (int i = 0; i < 2500; ++i) {
      for (int a = 0; a < simulation.armCount(); ++a) {
        const bs::sim::ArmState& s = simulation.trueState(a);
        const Eigen::VectorXd tau = 300.0 * (initial.q - s.q) - 20.0 * s.qd;
        ASSERT_EQ(simulation.writeJointTorques(a, tau), bs::sim::RobotStatus::Ok);
      }
      ASSERT_NE(simulation.step(), bs::sim::SimStatus::ArmDiverged);
      farthest = std::max(farthest, (simulation.toolPose(0).translation() - tool.translation()).norm());
    }
    moved[collides ? 0 : 1] = farthest;
  }
  EXPECT_GT(moved[0], 0.02) << "the object passed through the tool";
  EXPECT_GT(moved[0], 3.0 * moved[1]) << moved[0] << " against " << moved[1];
  std::printf("tool pushed %.4f m by the object that collides, %.4f m by the one that does not\n", moved[0], moved[1]);
}

TEST(SimulatedObject, TheCameraSeesItWhereTheSimulationPutIt) {
  const bs::sim::SimConfig config = bs::sim::SimConfig::fromYamlFile(configFile("track_sim.yaml"));
  bs::vision::PerspectiveRenderer camera(bs::tasks::rendererFor(config), bs::tasks::rgbdCameraFor(config),
                                         bs::vision::DepthSensorNoise{0, 0, 0, 0, 0, 0});
  const int object = camera.addMovingSolid(bs::tasks::sceneSolid(config.object.body));
  const Eigen::Matrix3Xd none(3, 0);
  const Eigen::Matrix3Xi no_triangles(3, 0);
  const ObjectPath path(config.object.path);
  int seen = 0, gone = 0;
  for (double t = 0.0; t < 60.0; t += 0.5) {
    const bs::sim::ObjectPathSample s = path.at(t);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = s.position;
    camera.setMovingPose(object, pose);
    (void)camera.render(none, no_triangles);
    const int pixels = cv::countNonZero(camera.movingMask());
    Eigen::Vector3d uvz;
    ASSERT_TRUE(camera.camera().project(s.position, uvz));
    const bool inside = uvz.x() > 10 && uvz.y() > 10 && uvz.x() < 630 && uvz.y() < 470;
    const bool far_out = uvz.x() < -60 || uvz.y() < -60 || uvz.x() > 700 || uvz.y() > 540;
    if (far_out) {
      EXPECT_EQ(pixels, 0) << "t = " << t;
      ++gone;
      continue;
    }
    if (!inside) continue;
    ++seen;
    ASSERT_GT(pixels, 100) << "t = " << t;
    // The mask's centroid lies near the projected centre (the visible surface is the near side and the top).
    const cv::Moments moments = cv::moments(camera.movingMask(), true);
    const Eigen::Vector2d centroid(moments.m10 / moments.m00, moments.m01 / moments.m00);
    EXPECT_LT((centroid - uvz.head<2>()).norm(), 20.0) << "t = " << t;
    // Every masked pixel's depth back-projects onto the can's surface.
    const cv::Mat& depth = camera.depth();
    for (int v = 0; v < depth.rows; v += 3) {
      for (int u = 0; u < depth.cols; u += 3) {
        if (camera.movingMask().at<unsigned char>(v, u) == 0 || !std::isfinite(depth.at<float>(v, u))) continue;
        const Eigen::Vector3d p = camera.camera().backProject(u, v, depth.at<float>(v, u)) - s.position;
        const double radial = p.head<2>().norm(), height = std::abs(p.z());
        EXPECT_TRUE(radial <= config.object.body.size[0] + 2e-3 && height <= 0.5 * config.object.body.size[1] + 2e-3)
            << "t = " << t << " pixel " << u << ", " << v << ": " << p.transpose();
      }
    }
  }
  EXPECT_GT(seen, 60);
  EXPECT_GT(gone, 2) << "the path never took the object out of view";
  // A frame with the object moved, its sensor errors drawn: no allocation.
  std::mt19937 rng(3);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = config.object.path.centre;
  {
    bimanual_skills::testing::NoAllocGuard guard;
    camera.setMovingPose(object, pose);
    (void)camera.render(none, no_triangles, rng);
  }
}
