// The perspective RGB-D camera and its re-projection: projection against the pinhole formula and back, the table's
// depth against the ray-plane intersection at every pixel, the sensor's noise against its model, the re-projected
// height map of a folded cloth against the orthographic camera's image of the same mesh, bad input, no allocation.
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"
#include "bimanual_skills/vision/synthetic_cloth.hpp"
#include "testing/no_alloc_guard.hpp"
#include "vision_test_scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace bv = bimanual_skills::vision;
using bimanual_skills::testing::NoAllocGuard;

namespace {

bv::ClothRendererParameters scene() {
  return bimanual_skills::test_support::foldScene();
}
bv::PinholeCamera kinect() {
  return bimanual_skills::test_support::kinectOverTable();
}
bv::DepthSensorNoise perfect() {
  return bimanual_skills::test_support::perfectSensor();
}

}  // namespace

TEST(PinholeCamera, ProjectsAndBackProjectsAsRosDoes) {
  const bv::PinholeCamera camera = kinect();
  Eigen::Vector3d uvz;
  ASSERT_TRUE(camera.project(Eigen::Vector3d(0.55, 0.0, 0.15), uvz));
  EXPECT_NEAR(uvz.x(), camera.cx, 1e-9);  // the target on the optical axis
  EXPECT_NEAR(uvz.y(), camera.cy, 1e-9);
  EXPECT_NEAR(uvz.z(), std::hypot(0.65, 1.3), 1e-9);
  // Looking towards −x with world up above, the image's x runs along world +y (the viewer's right) and its y towards
  // the camera's side of the table.
  Eigen::Vector3d right, near;
  ASSERT_TRUE(camera.project(Eigen::Vector3d(0.55, 0.1, 0.15), right));
  ASSERT_TRUE(camera.project(Eigen::Vector3d(0.75, 0.0, 0.15), near));
  EXPECT_GT(right.x(), camera.cx);
  EXPECT_GT(near.y(), camera.cy);
  // The pinhole formula in the optical frame, and the round trip.
  const Eigen::Vector3d p(0.4, -0.2, 0.3);
  const Eigen::Vector3d c = camera.pose.inverse() * p;
  ASSERT_TRUE(camera.project(p, uvz));
  EXPECT_NEAR(uvz.x(), camera.fx * c.x() / c.z() + camera.cx, 1e-9);
  EXPECT_NEAR(uvz.y(), camera.fy * c.y() / c.z() + camera.cy, 1e-9);
  EXPECT_LT((camera.backProject(uvz.x(), uvz.y(), uvz.z()) - p).norm(), 1e-12);
  EXPECT_FALSE(camera.project(Eigen::Vector3d(2.0, 0.0, 2.0), uvz)) << "a point behind the camera";
}

TEST(PerspectiveRenderer, TheTablesDepthIsTheRayPlaneIntersectionAtEveryPixel) {
  const bv::ClothRendererParameters s = scene();
  const bv::PinholeCamera camera = kinect();
  bv::PerspectiveRenderer renderer(s, camera, perfect());
  const Eigen::Matrix3Xd none(3, 0);
  const Eigen::Matrix3Xi no_triangles(3, 0);
  EXPECT_EQ(renderer.render(none, no_triangles), bv::VisionStatus::EmptyMesh);
  int checked = 0;
  double worst = 0.0;
  for (int v = 0; v < camera.height; v += 7) {
    for (int u = 0; u < camera.width; u += 7) {
      // The ray through pixel (u, v), in the world, against the plane z = table height.
      const Eigen::Vector3d direction =
          camera.pose.linear() * Eigen::Vector3d((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      const double t = (s.table.height - camera.pose.translation().z()) / direction.z();
      const Eigen::Vector3d hit = camera.pose.translation() + t * direction;
      // Clearly inside the top (not at its edges, where a side face may win the pixel).
      if (std::abs(hit.x() - 0.55) > 0.33 || std::abs(hit.y()) > 0.58) continue;
      const double expected = t;  // direction's optical z is 1: t is the depth z
      const float depth = renderer.depth().at<float>(v, u);
      ASSERT_TRUE(std::isfinite(depth)) << u << ", " << v;
      worst = std::max(worst, std::abs(depth - expected) / expected);
      ++checked;
    }
  }
  EXPECT_GT(checked, 500);
  EXPECT_LT(worst, 1e-6) << "relative depth error on the table top";
}

TEST(PerspectiveRenderer, TheSensorsErrorsFollowItsModel) {
  const bv::ClothRendererParameters s = scene();
  const bv::PinholeCamera camera = kinect();
  bv::DepthSensorNoise noise;
  noise.edge_dropout = 0.0;
  bv::PerspectiveRenderer clean(s, camera, perfect()), noisy(s, camera, noise);
  const Eigen::Matrix3Xd none(3, 0);
  const Eigen::Matrix3Xi no_triangles(3, 0);
  clean.render(none, no_triangles);
  std::mt19937 rng(7);
  noisy.render(none, no_triangles, rng);
  double sum = 0.0, sum2 = 0.0;
  long n = 0, lost = 0, valid = 0;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const float z = clean.depth().at<float>(v, u), d = noisy.depth().at<float>(v, u);
      if (!std::isfinite(z)) continue;
      ++valid;
      if (!std::isfinite(d)) {
        ++lost;
        continue;
      }
      const double standardised = (d - z) / (noise.axial * z * z);
      sum += standardised;
      sum2 += standardised * standardised;
      ++n;
    }
  }
  ASSERT_GT(n, 100000);
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 0.02);
  EXPECT_NEAR(sd, 1.0, 0.02) << "σ_z = k z²";
  const double share = static_cast<double>(lost) / valid;
  EXPECT_NEAR(share, noise.dropout, 4.0 * std::sqrt(noise.dropout / valid) + 2e-4) << lost << " of " << valid;
  // Same seed, same image; a depth edge (the table's) loses pixels when edges do.
  std::mt19937 again(7);
  bv::PerspectiveRenderer twin(s, camera, noise);
  twin.render(none, no_triangles, again);
  EXPECT_EQ(cv::norm(twin.bgr(), noisy.bgr(), cv::NORM_INF), 0.0);
  noise.edge_dropout = 1.0;
  noise.dropout = 0.0;
  bv::PerspectiveRenderer edges(s, camera, noise);
  edges.render(none, no_triangles, rng);
  long edge_lost = 0;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      edge_lost += std::isfinite(clean.depth().at<float>(v, u)) && !std::isfinite(edges.depth().at<float>(v, u));
    }
  }
  EXPECT_GT(edge_lost, 300) << "the table's edge against the floor lost no pixel";
  EXPECT_LT(edge_lost, valid / 20);
}

TEST(HeightMapProjector, ReprojectsAFoldedClothAsTheOrthographicCameraSeesIt) {
  const bv::ClothRendererParameters s = scene();
  const bv::ClothMesh flat = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.55, 0.0, 0.154));
  for (const bool folded : {false, true}) {
    const bv::ClothMesh cloth = folded ? bv::foldCloth(flat, 0.55, 0.01) : flat;
    bv::ClothRenderer orthographic(s);
    orthographic.render(cloth.vertices, cloth.triangles);
    bv::PerspectiveRenderer perspective(s, kinect(), perfect());
    perspective.render(cloth.vertices, cloth.triangles);
    bv::HeightMapProjector projector(s.camera);
    ASSERT_EQ(projector.project(perspective.bgr(), perspective.depth(), perspective.camera()), bv::VisionStatus::Ok);
    const bv::HeightMapCoverage& coverage = projector.coverage();
    EXPECT_GT(coverage.observed, 0.6 * s.camera.rows * s.camera.columns);
    // Over the orthographic camera's cloth (off its border, where a neighbour's table may win): the same height.
    std::vector<double> errors;
    int cloth_cells = 0, blue = 0;
    for (int v = 1; v + 1 < s.camera.rows; ++v) {
      for (int u = 1; u + 1 < s.camera.columns; ++u) {
        bool interior = true;
        for (int dv = -1; dv <= 1; ++dv) {
          for (int du = -1; du <= 1; ++du)
            interior = interior && orthographic.clothMask().at<unsigned char>(v + dv, u + du);
        }
        if (!interior) continue;
        ++cloth_cells;
        errors.push_back(std::abs(projector.depth().at<float>(v, u) - orthographic.depth().at<float>(v, u)));
        const cv::Vec3b c = projector.bgr().at<cv::Vec3b>(v, u);
        blue += c[0] > c[2] + 40;
      }
    }
    ASSERT_GT(cloth_cells, 1000);
    std::sort(errors.begin(), errors.end());
    EXPECT_LT(errors[errors.size() / 2], 0.001) << (folded ? "folded" : "flat") << ": median height error";
    EXPECT_LT(errors[errors.size() * 95 / 100], 0.01) << (folded ? "folded" : "flat") << ": 95th percentile";
    EXPECT_GT(blue, 0.97 * cloth_cells) << "the cloth's colour carried over";
  }
}

TEST(HeightMapProjector, BadInputGetsAStatusAndNothingAllocates) {
  const bv::ClothRendererParameters s = scene();
  bv::PerspectiveRenderer renderer(s, kinect());
  bv::HeightMapProjector projector(s.camera);
  const bv::ClothMesh cloth = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.55, 0.0, 0.154));
  std::mt19937 rng(3);
  bv::PinholeCamera moved = renderer.camera();
  {
    NoAllocGuard guard;
    EXPECT_EQ(renderer.render(cloth.vertices, cloth.triangles, rng), bv::VisionStatus::Ok);
    EXPECT_EQ(projector.project(renderer.bgr(), renderer.depth(), renderer.camera()), bv::VisionStatus::Ok);
    moved.pose.translation().x() = std::nan("");
    EXPECT_EQ(projector.project(renderer.bgr(), renderer.depth(), moved), bv::VisionStatus::BadCameraPose);
  }
  moved = renderer.camera();
  moved.width = 320;
  EXPECT_EQ(projector.project(renderer.bgr(), renderer.depth(), moved), bv::VisionStatus::WrongImageSize);
  bv::PinholeCamera bad = kinect();
  bad.fx = 0.0;
  EXPECT_THROW(bv::PerspectiveRenderer(s, bad), std::invalid_argument);
  EXPECT_THROW(bv::PinholeCamera::lookingAt(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()), std::invalid_argument);
  EXPECT_THROW(bv::PinholeCamera::lookingAt(Eigen::Vector3d(0, 0, 2), Eigen::Vector3d::Zero()), std::invalid_argument)
      << "straight down along up: no image rows";
  bv::DepthSensorNoise noise;
  noise.dropout = 2.0;
  EXPECT_THROW(bv::PerspectiveRenderer(s, kinect(), noise), std::invalid_argument);
}

// ---- solids: a scene's static shapes (a mannequin), tessellated and drawn in their colours ----

TEST(SceneSolids, TessellationsEncloseTheShapesVolumeOutwards) {
  // Divergence theorem: Σ a·(b × c) / 6 over outward triangles is the enclosed volume (> 0), against the analytic one.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.3, -0.2, 0.5);
  pose.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  const auto volume = [](const std::vector<Eigen::Matrix3d>& triangles) {
    double v = 0.0;
    for (const Eigen::Matrix3d& t : triangles) v += t.col(0).dot(t.col(1).cross(t.col(2))) / 6.0;
    return v;
  };
  bv::SceneSolid box{bv::SceneSolid::Shape::Box, pose, Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d::Ones()};
  EXPECT_EQ(bv::solidTriangles(box).size(), 12u);
  EXPECT_NEAR(volume(bv::solidTriangles(box)), 0.1 * 0.2 * 0.3, 1e-12);
  bv::SceneSolid sphere{bv::SceneSolid::Shape::Sphere, pose, Eigen::Vector3d(0.09, 0.0, 0.0), Eigen::Vector3d::Ones()};
  const double ball = 4.0 / 3.0 * M_PI * std::pow(0.09, 3);
  EXPECT_NEAR(volume(bv::solidTriangles(sphere)) / ball, 1.0, 0.03);  // facets cut a little off
  EXPECT_LT(volume(bv::solidTriangles(sphere)), ball);
  bv::SceneSolid cylinder{bv::SceneSolid::Shape::Cylinder, pose, Eigen::Vector3d(0.045, 0.09, 0.0),
                          Eigen::Vector3d::Ones()};
  const double can = M_PI * 0.045 * 0.045 * 0.09;
  EXPECT_NEAR(volume(bv::solidTriangles(cylinder)) / can, 1.0, 0.01);
}

TEST(PerspectiveRenderer, SolidsAreSeenInTheirColoursAtTheirDepthAndATablelessSceneHasNoTable) {
  bv::ClothRendererParameters s = scene();
  s.has_table = false;
  bv::SceneSolid head{bv::SceneSolid::Shape::Sphere, Eigen::Isometry3d::Identity(), Eigen::Vector3d(0.1, 0.0, 0.0),
                      Eigen::Vector3d(0.9, 0.1, 0.1)};
  head.pose.translation() = Eigen::Vector3d(0.55, 0.0, 0.5);
  s.solids.push_back(head);
  // A camera level with the head, 1 m in front of it.
  const bv::PinholeCamera camera =
      bv::PinholeCamera::lookingAt(Eigen::Vector3d(1.55, 0.0, 0.5), Eigen::Vector3d(0.55, 0.0, 0.5));
  bv::PerspectiveRenderer renderer(s, camera, perfect());
  (void)renderer.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0));
  const int u = static_cast<int>(camera.cx), v = static_cast<int>(camera.cy);
  EXPECT_NEAR(renderer.depth().at<float>(v, u), 0.9, 2e-3);  // the sphere's front, 1 m − 0.1 m
  const cv::Vec3b bgr = renderer.bgr().at<cv::Vec3b>(v, u);
  EXPECT_GT(bgr[2], 2 * bgr[1]);  // red
  EXPECT_GT(bgr[2], 2 * bgr[0]);
  // Above the head and the horizon: nothing (no table, no floor) gives no return.
  EXPECT_TRUE(std::isnan(renderer.depth().at<float>(5, u)));
  // Seen from the fold's camera, the table's place shows the floor 0.3 m lower.
  bv::ClothRendererParameters empty = scene();
  empty.has_table = false;
  bv::PerspectiveRenderer over(empty, kinect(), perfect());
  bv::PerspectiveRenderer with_table(scene(), kinect(), perfect());
  (void)over.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0));
  (void)with_table.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0));
  const int cu = static_cast<int>(kinect().cx), cv_ = static_cast<int>(kinect().cy);
  EXPECT_GT(over.depth().at<float>(cv_, cu), with_table.depth().at<float>(cv_, cu) + 0.2);
  // A solid with a zero size is refused.
  head.size.setZero();
  s.solids = {head};
  EXPECT_THROW(bv::PerspectiveRenderer(s, camera, perfect()), std::invalid_argument);
}
