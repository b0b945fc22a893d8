// A real RGB-D camera's images back to what the library models, against ground truth rendered by the perspective
// renderer: distorted raw images (plumb_bob, equidistant) rectified back to the pinhole image, depth of a camera
// 2.5 cm beside the colour camera registered into it (and into a colour camera of twice its resolution), millimetre
// depth to metres, calibrations that cannot serve refused with the reason, and the simulated raw sensor read back.
#include "bimanual_skills/vision/camera_calibration.hpp"
#include "bimanual_skills/vision/depth_registration.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"
#include "bimanual_skills/vision/raw_rgbd_sensor.hpp"
#include "bimanual_skills/vision/synthetic_cloth.hpp"
#include "vision_test_scene.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace bv = bimanual_skills::vision;

namespace {

bv::ClothRendererParameters scene() {
  return bimanual_skills::test_support::foldScene();
}
bv::DepthSensorNoise perfect() {
  return bimanual_skills::test_support::perfectSensor();
}
bv::PinholeCamera colourCamera() {
  return bimanual_skills::test_support::kinectOverTable();
}

/// Renders the flat cloth on the table as `camera` sees it.
bv::PerspectiveRenderer rendered(const bv::PinholeCamera& camera) {
  bv::PerspectiveRenderer renderer(scene(), camera, perfect());
  const bv::ClothMesh cloth =
      bv::foldCloth(bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.55, 0.0, 0.154)), 0.6, 0.01);
  renderer.render(cloth.vertices, cloth.triangles);
  return renderer;
}

bv::CameraCalibration calibrationOf(const bv::PinholeCamera& camera) {
  bv::CameraCalibration c;
  c.width = camera.width;
  c.height = camera.height;
  c.K << camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0;
  c.P.leftCols<3>() = c.K;
  return c;
}

/// The raw (distorted) image a camera of calibration `c` takes of the scene whose rectified image is `rectified`:
/// each raw pixel looks where the undistorted ray of that pixel lands in the rectified image.
cv::Mat distort(const cv::Mat& rectified, const bv::CameraCalibration& c, int interpolation) {
  std::vector<cv::Point2f> raw;
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u) raw.emplace_back(static_cast<float>(u), static_cast<float>(v));
  }
  cv::Mat k(3, 3, CV_64F), p(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      k.at<double>(i, j) = c.K(i, j);
      p.at<double>(i, j) = c.P(i, j);
    }
  }
  std::vector<cv::Point2f> undistorted;
  if (c.distortion_model == "equidistant") {
    cv::fisheye::undistortPoints(raw, undistorted, k, cv::Mat(c.D, true), cv::Mat(), p);
  } else {
    cv::undistortPoints(raw, undistorted, k, cv::Mat(c.D, true), cv::Mat(), p);
  }
  cv::Mat map_x(c.height, c.width, CV_32FC1), map_y(c.height, c.width, CV_32FC1);
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u) {
      map_x.at<float>(v, u) = undistorted[static_cast<std::size_t>(v * c.width + u)].x;
      map_y.at<float>(v, u) = undistorted[static_cast<std::size_t>(v * c.width + u)].y;
    }
  }
  cv::Mat out;
  cv::remap(rectified, out, map_x, map_y, interpolation, cv::BORDER_CONSTANT,
            cv::Scalar::all(rectified.type() == CV_32FC1 ? std::nan("") : 0.0));
  return out;
}

/// Median and 95th percentile of |a − b| over the pixels both have, with their count.
struct Agreement {
  double median = 0.0, p95 = 0.0;
  int pixels = 0;
};
Agreement agreement(const cv::Mat& a, const cv::Mat& b, int border) {
  std::vector<double> e;
  for (int v = border; v < a.rows - border; ++v) {
    for (int u = border; u < a.cols - border; ++u) {
      const float x = a.at<float>(v, u), y = b.at<float>(v, u);
      if (std::isfinite(x) && std::isfinite(y)) e.push_back(std::abs(x - y));
    }
  }
  Agreement out;
  out.pixels = static_cast<int>(e.size());
  if (e.empty()) return out;
  std::sort(e.begin(), e.end());
  out.median = e[e.size() / 2];
  out.p95 = e[e.size() * 95 / 100];
  return out;
}

}  // namespace

TEST(CameraCalibration, RawImagesOfADistortedCameraAreRectifiedBackToItsPinholeImages) {
  const bv::PerspectiveRenderer truth = rendered(colourCamera());
  for (const char* model : {"plumb_bob", "equidistant"}) {
    bv::CameraCalibration c = calibrationOf(truth.camera());
    c.distortion_model = model;
    // A Kinect v1 colour camera's distortion (Smisek et al. 2011: k1 ≈ 0.2, k2 ≈ −0.5), or a fisheye's.
    c.D = std::string(model) == "plumb_bob" ? std::vector<double>{0.19, -0.45, 0.001, -0.002, 0.2}
                                            : std::vector<double>{0.05, -0.01, 0.002, 0.0};
    ASSERT_EQ(c.problem(), "") << model;
    EXPECT_FALSE(c.rectified());
    const cv::Mat raw_depth = distort(truth.depth(), c, cv::INTER_NEAREST);
    const cv::Mat raw_bgr = distort(truth.bgr(), c, cv::INTER_LINEAR);
    // The raw image is not the pinhole image (the distortion moves the table's edges by pixels).
    const Agreement unrectified = agreement(raw_depth, truth.depth(), 40);
    bv::Rectifier rectifier(c);
    ASSERT_TRUE(rectifier.remaps());
    cv::Mat depth, bgr;
    ASSERT_TRUE(rectifier.rectifyDepth(raw_depth, depth));
    ASSERT_TRUE(rectifier.rectifyColour(raw_bgr, bgr));
    const Agreement rectified = agreement(depth, truth.depth(), 40);
    std::printf("%s: depth |error| p95 %.4f m raw, %.4f m rectified (%d pixels)\n", model, unrectified.p95,
                rectified.p95, rectified.pixels);
    EXPECT_GT(unrectified.p95, 0.01) << model << ": the distortion did not move anything";
    EXPECT_LT(rectified.median, 1e-4) << model;
    EXPECT_LT(rectified.p95, 5e-3) << model;
    EXPECT_GT(rectified.pixels, truth.camera().width * truth.camera().height / 2);
    cv::Mat difference;
    cv::absdiff(bgr, truth.bgr(), difference);
    EXPECT_LT(cv::mean(difference(cv::Rect(40, 40, c.width - 80, c.height - 80)))[0], 4.0) << model;
  }
}

TEST(CameraCalibration, RectifiedImagesPassAsTheyAreAndBadCalibrationsAreRefusedWithTheReason) {
  const bv::CameraCalibration good = calibrationOf(colourCamera());
  EXPECT_TRUE(good.rectified());
  bv::Rectifier rectifier(good);
  EXPECT_FALSE(rectifier.remaps());
  const bv::PinholeCamera camera = good.rectifiedCamera();
  EXPECT_EQ(camera.fx, colourCamera().fx);
  EXPECT_EQ(camera.cy, colourCamera().cy);
  cv::Mat wrong(10, 10, CV_32FC1), out;
  EXPECT_FALSE(rectifier.rectifyDepth(wrong, out));
  const auto refused = [](bv::CameraCalibration c, const std::string& says) {
    EXPECT_NE(c.problem().find(says), std::string::npos) << c.problem();
    EXPECT_THROW(bv::Rectifier{c}, std::invalid_argument);
  };
  bv::CameraCalibration c = good;
  c.distortion_model = "fov";
  c.D = {0.1};
  refused(c, "'fov' is not handled");
  c = good;
  c.D = {0.1, 0.2, 0.0};
  refused(c, "3 coefficients");
  c = good;
  c.P(0, 3) = -30.0;
  refused(c, "second camera of a stereo pair");
  c = good;
  c.K(0, 0) = std::nan("");
  refused(c, "not finite");
  c = good;
  c.width = 4;
  refused(c, "4 x 480");
}

TEST(DepthRegistration, TheDepthCameraBesideTheColourCameraIsRegisteredAsTheColourCameraSeesIt) {
  const bv::PinholeCamera colour = colourCamera();
  // A Kinect's IR camera 2.5 cm to the colour camera's side (along its optical x), slightly rotated, with its own
  // intrinsics; and a colour camera of twice the resolution (registration fills between the points).
  Eigen::Isometry3d colour_from_depth = Eigen::Isometry3d::Identity();
  colour_from_depth.translation() = Eigen::Vector3d(-0.025, 0.0005, 0.001);
  colour_from_depth.linear() = Eigen::AngleAxisd(0.004, Eigen::Vector3d::UnitY()).toRotationMatrix();
  bv::PinholeCamera depth_camera = colour;
  depth_camera.fx = depth_camera.fy = 580.0;
  depth_camera.cx = 314.5;
  depth_camera.cy = 235.5;
  depth_camera.pose = colour.pose * colour_from_depth;
  const bv::PerspectiveRenderer seen_by_depth = rendered(depth_camera);
  for (const int scale : {1, 2}) {
    bv::PinholeCamera target = colour;
    target.width *= scale;
    target.height *= scale;
    target.fx *= scale;
    target.fy *= scale;
    target.cx = scale * (colour.cx + 0.5) - 0.5;
    target.cy = scale * (colour.cy + 0.5) - 0.5;
    const bv::PerspectiveRenderer truth = rendered(target);
    bv::DepthRegistration registration(depth_camera, target, colour_from_depth);
    cv::Mat registered;
    ASSERT_TRUE(registration.registerDepth(seen_by_depth.depth(), registered));
    ASSERT_EQ(registered.cols, target.width);
    const Agreement registered_error = agreement(registered, truth.depth(), 10 * scale);
    const Agreement unregistered = scale == 1 ? agreement(seen_by_depth.depth(), truth.depth(), 10) : Agreement();
    std::printf("scale %d: registered depth |error| median %.5f m, p95 %.5f m over %d pixels%s\n", scale,
                registered_error.median, registered_error.p95, registered_error.pixels,
                scale == 1 ? (", unregistered p95 " + std::to_string(unregistered.p95) + " m").c_str() : "");
    EXPECT_LT(registered_error.median, 2e-3) << "scale " << scale;
    EXPECT_LT(registered_error.p95, 0.02) << "scale " << scale;
    EXPECT_GT(registered_error.pixels, 0.9 * target.width * target.height * 0.8) << "holes in the registered image";
    if (scale == 1) {
      EXPECT_GT(unregistered.p95, 0.02) << "the cameras' offset changed nothing";
    }
  }
  cv::Mat out;
  EXPECT_FALSE(
      bv::DepthRegistration(depth_camera, colour, colour_from_depth).registerDepth(cv::Mat(5, 5, CV_32FC1), out));
  Eigen::Isometry3d sheared = colour_from_depth;
  sheared.linear()(0, 1) = 0.5;
  EXPECT_THROW(bv::DepthRegistration(depth_camera, colour, sheared), std::invalid_argument);
}

TEST(DepthEncodings, MillimetresAndMetresWithZeroAsNoReturn) {
  cv::Mat mm = (cv::Mat_<std::uint16_t>(1, 3) << 0, 1500, 65535), out;
  ASSERT_TRUE(bv::depthToMetres(mm, true, out));
  EXPECT_TRUE(std::isnan(out.at<float>(0, 0)));
  EXPECT_FLOAT_EQ(out.at<float>(0, 1), 1.5f);
  EXPECT_FLOAT_EQ(out.at<float>(0, 2), 65.535f);
  cv::Mat m = (cv::Mat_<float>(1, 3) << 0.0f, 1.5f, -1.0f);
  ASSERT_TRUE(bv::depthToMetres(m, false, out));
  EXPECT_TRUE(std::isnan(out.at<float>(0, 0)));
  EXPECT_FLOAT_EQ(out.at<float>(0, 1), 1.5f);
  EXPECT_TRUE(std::isnan(out.at<float>(0, 2)));
  EXPECT_FALSE(bv::depthToMetres(mm, false, out)) << "16UC1 read as metres";
  EXPECT_FALSE(bv::depthToMetres(m, true, out)) << "32FC1 read as millimetres";
}

TEST(RawRgbdSensor, ItsImagesReadBackAsThePinholeCamerasWithItsOwnCalibrations) {
  // What a driver of the simulated Kinect sends, read as RgbdReader reads it (rectified with the colour camera's
  // calibration, millimetres to metres, registered from the depth camera's frame), against the pinhole camera's
  // own noise-free images.
  const bv::PinholeCamera colour = colourCamera();
  bv::RawRgbdSensorConfig config;
  config.colour = colour;
  config.noise = perfect();
  bv::RawRgbdSensor sensor(scene(), config);
  const bv::ClothMesh cloth =
      bv::foldCloth(bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.55, 0.0, 0.154)), 0.6, 0.01);
  std::mt19937 rng(3);
  ASSERT_EQ(sensor.render(cloth.vertices, cloth.triangles, rng), bv::VisionStatus::Ok);
  EXPECT_EQ(sensor.depthMillimetres().type(), CV_16UC1);
  EXPECT_EQ(sensor.colourCalibration().problem(), "");
  EXPECT_FALSE(sensor.colourCalibration().rectified()) << "a raw colour image without distortion";
  EXPECT_TRUE(sensor.depthCalibration().rectified());
  const bv::PerspectiveRenderer truth = rendered(colour);
  cv::Mat bgr, metres, registered;
  ASSERT_TRUE(bv::Rectifier(sensor.colourCalibration()).rectifyColour(sensor.rawBgr(), bgr));
  ASSERT_TRUE(bv::depthToMetres(sensor.depthMillimetres(), true, metres));
  const bv::PinholeCamera depth = sensor.depthCalibration().rectifiedCamera();
  ASSERT_TRUE(bv::DepthRegistration(depth, colour, config.colour_from_depth).registerDepth(metres, registered));
  const Agreement error = agreement(registered, truth.depth(), 20);
  std::printf("raw sensor read back: depth |error| median %.5f m, p95 %.5f m over %d pixels\n", error.median, error.p95,
              error.pixels);
  EXPECT_LT(error.median, 2e-3);
  EXPECT_LT(error.p95, 0.02);
  cv::Mat difference;
  cv::absdiff(bgr, truth.bgr(), difference);
  EXPECT_LT(cv::mean(difference(cv::Rect(40, 40, colour.width - 80, colour.height - 80)))[0], 4.0);
  bv::RawRgbdSensorConfig bad = config;
  bad.distortion.pop_back();
  EXPECT_THROW(bv::RawRgbdSensor(scene(), bad), std::invalid_argument);
}
