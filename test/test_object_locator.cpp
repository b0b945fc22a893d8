// The tracking experiment's perception (thesis Sec. 4.3.2): an object of known shape and colour found in the
// perspective RGB-D camera's rendered frames (with the Kinect-like depth noise and holes) and its centre measured in
// the world, against the centre the renderer drew it at (ground truth); the distances the fit uses against points
// set by hand; the frames it must refuse.
#include "bimanual_skills/sim/object_path.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/object_locator.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

namespace bs = bimanual_skills;
using bs::vision::LocateStatus;
using bs::vision::ObjectLocator;
using bs::vision::ObjectLocatorConfig;
using bs::vision::ObjectMeasurement;
using bs::vision::SceneSolid;

namespace {

bs::sim::SimConfig trackScene() {
  return bs::sim::SimConfig::fromYamlFile(std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/track_sim.yaml");
}

ObjectLocatorConfig locatorFor(const SceneSolid& solid) {
  ObjectLocatorConfig config;
  config.shape = solid;
  return config;
}

Eigen::Isometry3d at(const Eigen::Vector3d& p) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = p;
  return pose;
}

struct Errors {
  double rms = 0.0, max = 0.0, nees = 0.0;
  int frames = 0;
};

/// Locates a solid of `solid`'s shape and colour at `count` places of a seeded object path in noisy frames.
Errors locateAlongAPath(const SceneSolid& solid, int count, std::uint32_t seed) {
  const bs::sim::SimConfig scene = trackScene();
  bs::vision::PerspectiveRenderer camera(bs::tasks::rendererFor(scene), bs::tasks::rgbdCameraFor(scene));
  const int index = camera.addMovingSolid(solid);
  ObjectLocator locator(locatorFor(solid));
  bs::sim::ObjectPathConfig path_config = scene.object.path;
  path_config.seed = seed;
  path_config.away_probability = 0.0;
  const bs::sim::ObjectPath path(path_config);
  std::mt19937 rng(seed);
  Errors errors;
  const Eigen::Matrix3Xd none(3, 0);
  const Eigen::Matrix3Xi no_triangles(3, 0);
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector3d truth = path.at(path.end() * k / count).position;
    camera.setMovingPose(index, at(truth));
    (void)camera.render(none, no_triangles, rng);
    ObjectMeasurement m;
    const LocateStatus status = locator.locate(camera.bgr(), camera.depth(), camera.camera(), m);
    EXPECT_EQ(status, LocateStatus::Ok) << "frame " << k << " at " << truth.transpose();
    if (status != LocateStatus::Ok) continue;
    const Eigen::Vector3d e = m.position - truth;
    errors.rms += e.squaredNorm();
    errors.max = std::max(errors.max, e.norm());
    errors.nees += e.dot(m.covariance.inverse() * e);
    ++errors.frames;
    // The component taken is the object: most of the renderer's own mask of it.
    const double overlap = cv::countNonZero(locator.objectMask() & camera.movingMask());
    EXPECT_GT(overlap, 0.8 * cv::countNonZero(camera.movingMask())) << "frame " << k;
  }
  errors.rms = std::sqrt(errors.rms / std::max(1, errors.frames));
  errors.nees /= std::max(1, errors.frames);
  return errors;
}

}  // namespace

TEST(ObjectLocator, SurfaceDistancesAreTheShapesOwn) {
  SceneSolid can;
  can.shape = SceneSolid::Shape::Cylinder;
  can.size = Eigen::Vector3d(0.03, 0.12, 0.0);
  const ObjectLocator cylinder(locatorFor(can));
  const Eigen::Vector3d c(0.5, 0.2, 0.4);
  EXPECT_NEAR(cylinder.surfaceDistance(c + Eigen::Vector3d(0.05, 0.0, 0.0), c), 0.02, 1e-12);   // beside
  EXPECT_NEAR(cylinder.surfaceDistance(c + Eigen::Vector3d(0.0, 0.0, 0.10), c), 0.04, 1e-12);   // above the top
  EXPECT_NEAR(cylinder.surfaceDistance(c + Eigen::Vector3d(0.0, 0.01, 0.0), c), -0.02, 1e-12);  // inside
  EXPECT_NEAR(cylinder.surfaceDistance(c + Eigen::Vector3d(0.06, 0.0, 0.1), c), std::hypot(0.03, 0.04), 1e-12);
  SceneSolid ball;
  ball.shape = SceneSolid::Shape::Sphere;
  ball.size = Eigen::Vector3d(0.05, 0.0, 0.0);
  EXPECT_NEAR(ObjectLocator(locatorFor(ball)).surfaceDistance(c + Eigen::Vector3d(0.0, 0.06, 0.08), c), 0.05, 1e-12);
  SceneSolid box;
  box.shape = SceneSolid::Shape::Box;
  box.size = Eigen::Vector3d(0.1, 0.2, 0.3);
  const ObjectLocator cube(locatorFor(box));
  EXPECT_NEAR(cube.surfaceDistance(c + Eigen::Vector3d(0.0, 0.0, 0.2), c), 0.05, 1e-12);
  EXPECT_NEAR(cube.surfaceDistance(c + Eigen::Vector3d(0.08, 0.13, 0.0), c), std::hypot(0.03, 0.03), 1e-12);
  EXPECT_NEAR(cube.surfaceDistance(c + Eigen::Vector3d(0.04, 0.0, 0.0), c), -0.01, 1e-12);
}

TEST(ObjectLocator, MeasuresTheCansCentreInNoisyFramesWithinMillimetres) {
  const Errors e = locateAlongAPath(bs::tasks::sceneSolid(trackScene().object.body), 60, 11);
  std::printf("can: %d frames, error rms %.2f mm, max %.2f mm, mean NEES %.2f\n", e.frames, 1e3 * e.rms, 1e3 * e.max,
              e.nees);
  EXPECT_EQ(e.frames, 60);
  EXPECT_LT(e.rms, 0.002);
  EXPECT_LT(e.max, 0.005);
  // The covariance is not overconfident: the mean normalised error squared stays near 3 (the χ² mean) or below (the
  // floor of 2 mm dominates on a simulated sensor whose pixels' errors are independent).
  EXPECT_LT(e.nees, 6.0);
}

TEST(ObjectLocator, FitsABallAndABoxToo) {
  SceneSolid ball = bs::tasks::sceneSolid(trackScene().object.body);
  ball.shape = SceneSolid::Shape::Sphere;
  ball.size = Eigen::Vector3d(0.04, 0.0, 0.0);
  const Errors sphere = locateAlongAPath(ball, 30, 12);
  SceneSolid box = ball;
  box.shape = SceneSolid::Shape::Box;
  box.size = Eigen::Vector3d(0.06, 0.08, 0.1);
  const Errors cube = locateAlongAPath(box, 30, 13);
  std::printf("ball: rms %.2f mm, max %.2f mm; box: rms %.2f mm, max %.2f mm\n", 1e3 * sphere.rms, 1e3 * sphere.max,
              1e3 * cube.rms, 1e3 * cube.max);
  EXPECT_LT(sphere.rms, 0.003);
  EXPECT_LT(cube.rms, 0.003);
}

TEST(ObjectLocator, PointsOfAnArmInFrontOfTheCanAreLeftOut) {
  // An arm's hand above the can, between it and the camera: its depth, registered from a depth camera beside the
  // colour one, lands on the can's pixels at the edge. Here the upper fifth of the can's pixels get a depth 12 cm
  // nearer (the hand's). Fitted with them, the centre is pulled centimetres towards the hand.
  const bs::sim::SimConfig scene = trackScene();
  bs::vision::PerspectiveRenderer camera(bs::tasks::rendererFor(scene), bs::tasks::rgbdCameraFor(scene));
  const SceneSolid solid = bs::tasks::sceneSolid(scene.object.body);
  const int index = camera.addMovingSolid(solid);
  const Eigen::Vector3d truth = scene.object.path.centre;
  camera.setMovingPose(index, at(truth));
  std::mt19937 rng(14);
  (void)camera.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0), rng);
  cv::Mat depth = camera.depth().clone();
  const cv::Mat& mask = camera.movingMask();
  const cv::Rect box = cv::boundingRect(mask);
  int changed = 0;
  for (int row = box.y; row < box.y + box.height / 5; ++row) {
    for (int column = box.x; column < box.x + box.width; ++column) {
      if (mask.at<unsigned char>(row, column) == 0 || !std::isfinite(depth.at<float>(row, column))) continue;
      depth.at<float>(row, column) -= 0.12f;
      ++changed;
    }
  }
  ASSERT_GT(changed, 20);
  ObjectLocatorConfig kept = locatorFor(solid);
  kept.outlier_distance = 1.0;  // nothing dropped
  double errors[2] = {0.0, 0.0};
  int used[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    ObjectLocator locator(k == 0 ? locatorFor(solid) : kept);
    ObjectMeasurement m;
    ASSERT_EQ(locator.locate(camera.bgr(), depth, camera.camera(), m), LocateStatus::Ok);
    errors[k] = (m.position - truth).norm();
    used[k] = m.points;
  }
  std::printf("%d of the can's depth pixels 12 cm nearer: error %.2f mm with %d points (%.2f mm with all %d)\n",
              changed, 1e3 * errors[0], used[0], 1e3 * errors[1], used[1]);
  EXPECT_LT(errors[0], 0.005);
  EXPECT_GT(errors[1], 0.01);
}

TEST(ObjectLocator, SaysWhyAFrameGivesNoMeasurement) {
  const bs::sim::SimConfig scene = trackScene();
  bs::vision::PerspectiveRenderer camera(bs::tasks::rendererFor(scene), bs::tasks::rgbdCameraFor(scene));
  const SceneSolid solid = bs::tasks::sceneSolid(scene.object.body);
  const int index = camera.addMovingSolid(solid);
  ObjectLocator locator(locatorFor(solid));
  ObjectMeasurement m;
  const Eigen::Matrix3Xd none(3, 0);
  const Eigen::Matrix3Xi no_triangles(3, 0);
  // Out of view: the table and the floor alone have no pixel of its colour.
  camera.setMovingPose(index, at(scene.object.path.centre + scene.object.path.away));
  (void)camera.render(none, no_triangles);
  EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m), LocateStatus::NotSeen);
  // Half out of view (cut by the image's left or right edge): not measured, its fit would be biased.
  for (const double u : {0.0, 639.0}) {
    const bs::vision::PinholeCamera& c = camera.camera();
    const double depth = (scene.object.path.centre - c.pose.translation()).norm();
    camera.setMovingPose(index, at(c.backProject(u, 240.0, depth)));
    (void)camera.render(none, no_triangles);
    EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m), LocateStatus::AtEdge) << "u " << u;
  }
  camera.setMovingPose(index, at(scene.object.path.centre));
  (void)camera.render(none, no_triangles);
  ASSERT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m), LocateStatus::Ok);
  // Depth registered from a camera of its own that sees the can cut by its edge (here: the colour camera turned
  // so that the can's centre is at its image's left edge): part of the can has no depth, and what that camera sees
  // past its edge lands on the rest. The same camera turned back: measured.
  {
    bs::vision::PinholeCamera depth_camera = camera.camera();
    Eigen::Vector3d uvz;
    ASSERT_TRUE(depth_camera.project(scene.object.path.centre, uvz));
    depth_camera.cx -= uvz.x();
    EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m, &depth_camera), LocateStatus::AtEdge);
    depth_camera = camera.camera();
    depth_camera.pose.translation() += depth_camera.pose.linear().col(0) * 0.025;  // a Kinect's baseline
    EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m, &depth_camera), LocateStatus::Ok);
    depth_camera.fx = std::nan("");
    EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m, &depth_camera), LocateStatus::BadCamera);
  }
  // No depth (a sensor that returned nothing), the wrong encoding or size, a camera pose that is not rigid.
  cv::Mat holes(camera.depth().size(), CV_32FC1, cv::Scalar(std::nan("")));
  EXPECT_EQ(locator.locate(camera.bgr(), holes, camera.camera(), m), LocateStatus::NoDepth);
  cv::Mat depth16;
  camera.depth().convertTo(depth16, CV_16UC1, 1000.0);
  EXPECT_EQ(locator.locate(camera.bgr(), depth16, camera.camera(), m), LocateStatus::WrongImage);
  bs::vision::PinholeCamera smaller = camera.camera();
  smaller.width = 320;
  EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), smaller, m), LocateStatus::WrongImage);
  bs::vision::PinholeCamera skewed = camera.camera();
  skewed.pose.linear()(0, 1) += 0.1;
  EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), skewed, m), LocateStatus::BadCamera);
  skewed = camera.camera();
  skewed.fx = std::nan("");
  EXPECT_EQ(locator.locate(camera.bgr(), camera.depth(), skewed, m), LocateStatus::BadCamera);
  // A wrong colour finds nothing; bad settings are refused by name.
  ObjectLocatorConfig blue = locatorFor(solid);
  blue.hue = 220.0;
  ObjectLocator wrong(blue);
  EXPECT_EQ(wrong.locate(camera.bgr(), camera.depth(), camera.camera(), m), LocateStatus::NotSeen);
  ObjectLocatorConfig bad = locatorFor(solid);
  bad.min_points = 2;
  EXPECT_THROW(ObjectLocator{bad}, std::invalid_argument);
  bad = locatorFor(solid);
  bad.shape.size[0] = -1.0;
  EXPECT_THROW(ObjectLocator{bad}, std::invalid_argument);
}

TEST(ObjectLocator, AHueRangeAcrossZeroFindsARedObject) {
  const bs::sim::SimConfig scene = trackScene();
  bs::vision::PerspectiveRenderer camera(bs::tasks::rendererFor(scene), bs::tasks::rgbdCameraFor(scene),
                                         bs::vision::DepthSensorNoise{0, 0, 0, 0, 0, 0});
  SceneSolid red = bs::tasks::sceneSolid(scene.object.body);
  red.colour = Eigen::Vector3d(0.9, 0.05, 0.12);  // hue ≈ 353°
  const int index = camera.addMovingSolid(red);
  camera.setMovingPose(index, at(scene.object.path.centre));
  (void)camera.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0));
  ObjectLocatorConfig config = locatorFor(red);
  config.hue = 2.0;  // 350°-14° by the tolerance of 12°: across 0
  ObjectLocator locator(config);
  ObjectMeasurement m;
  ASSERT_EQ(locator.locate(camera.bgr(), camera.depth(), camera.camera(), m), LocateStatus::Ok);
  EXPECT_LT((m.position - scene.object.path.centre).norm(), 0.003);
}
