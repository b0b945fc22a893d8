// ros_layer::RgbdReader on the messages real RGB-D drivers send: 16UC1 millimetres read as the 32FC1 metres of the
// same scene, raw distorted colour rectified, depth on its own frame registered from a transform (and refused by
// name without one), the same frame at another resolution resampled, and every other case refused with the reason.
#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/ros_layer/rgbd_reader.hpp"
#include "bimanual_skills/vision/synthetic_cloth.hpp"
#include "vision_test_scene.hpp"

#include <cv_bridge/cv_bridge.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace br = bimanual_skills::ros_layer;
namespace bv = bimanual_skills::vision;

namespace {

bv::PinholeCamera kinect() {
  return bimanual_skills::test_support::kinectOverTable();
}

/// What `camera` sees of a flat cloth on the table, noise-free.
struct Seen {
  cv::Mat bgr, metres;
};
Seen look(const bv::PinholeCamera& camera) {
  bv::PerspectiveRenderer renderer(bimanual_skills::test_support::foldScene(), camera,
                                   bimanual_skills::test_support::perfectSensor());
  const bv::ClothMesh cloth = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.55, 0.0, 0.154));
  renderer.render(cloth.vertices, cloth.triangles);
  return {renderer.bgr().clone(), renderer.depth().clone()};
}

std_msgs::Header header(const std::string& frame) {
  std_msgs::Header h;
  h.frame_id = frame;
  return h;
}

sensor_msgs::Image image(const std::string& frame, const std::string& encoding, const cv::Mat& m) {
  return *cv_bridge::CvImage(header(frame), encoding, m).toImageMsg();
}

/// Millimetres as a driver rounds them (0: no return).
cv::Mat millimetres(const cv::Mat& metres) {
  cv::Mat mm(metres.size(), CV_16UC1);
  for (int v = 0; v < metres.rows; ++v) {
    for (int u = 0; u < metres.cols; ++u) {
      const float z = metres.at<float>(v, u);
      mm.at<std::uint16_t>(v, u) = std::isfinite(z) ? static_cast<std::uint16_t>(std::lround(1000.0 * z)) : 0;
    }
  }
  return mm;
}

/// Largest |a − b| where both are finite, and how many pixels differ in having a value.
std::pair<double, int> compare(const cv::Mat& a, const cv::Mat& b) {
  double worst = 0.0;
  int differ = 0;
  for (int v = 0; v < a.rows; ++v) {
    for (int u = 0; u < a.cols; ++u) {
      const float x = a.at<float>(v, u), y = b.at<float>(v, u);
      if (std::isfinite(x) != std::isfinite(y)) ++differ;
      if (std::isfinite(x) && std::isfinite(y)) worst = std::max(worst, static_cast<double>(std::abs(x - y)));
    }
  }
  return {worst, differ};
}

}  // namespace

TEST(RgbdReader, MillimetreDepthIsReadAsTheMetresOfTheSameScene) {
  const bv::PinholeCamera camera = kinect();
  const Seen seen = look(camera);
  const sensor_msgs::CameraInfo info = br::cameraInfo(camera, header("rgbd_optical"));
  const br::RgbdReader reader(info, info, std::nullopt, false);
  cv::Mat bgr, from_metres, from_millimetres;
  ASSERT_EQ(reader.read(image("rgbd_optical", "bgr8", seen.bgr), image("rgbd_optical", "32FC1", seen.metres), bgr,
                        from_metres),
            "");
  ASSERT_EQ(reader.read(image("rgbd_optical", "rgb8", seen.bgr),
                        image("rgbd_optical", "16UC1", millimetres(seen.metres)), bgr, from_millimetres),
            "");
  const auto [worst, differ] = compare(from_metres, from_millimetres);
  EXPECT_LE(worst, 0.0005 + 1e-6) << "16UC1 read at another scale";
  EXPECT_EQ(differ, 0);
  EXPECT_EQ(reader.camera(Eigen::Isometry3d::Identity()).fx, camera.fx);
  // What is not depth, or not this camera's, is refused by name.
  EXPECT_NE(reader
                .read(image("rgbd_optical", "bgr8", seen.bgr),
                      image("rgbd_optical", "8UC1", cv::Mat(480, 640, CV_8UC1)), bgr, from_metres)
                .find("32FC1 metres or 16UC1 millimetres"),
            std::string::npos);
  EXPECT_NE(reader.read(image("rgbd_optical", "bgr8", seen.bgr), image("other", "32FC1", seen.metres), bgr, from_metres)
                .find("on other"),
            std::string::npos);
  EXPECT_NE(reader.readColour(image("rgbd_optical", "bgr8", cv::Mat(10, 10, CV_8UC3)), bgr).find("10 x 10"),
            std::string::npos);
}

TEST(RgbdReader, DepthOnItsOwnFrameIsRegisteredFromTfOrRefusedByName) {
  const bv::PinholeCamera colour = kinect();
  Eigen::Isometry3d colour_from_depth = Eigen::Isometry3d::Identity();
  colour_from_depth.translation().x() = -0.025;
  bv::PinholeCamera depth = colour;
  depth.fx = depth.fy = 580.0;
  depth.pose = colour.pose * colour_from_depth;
  const Seen by_colour = look(colour), by_depth = look(depth);
  const sensor_msgs::CameraInfo colour_info = br::cameraInfo(colour, header("rgb_optical")),
                                depth_info = br::cameraInfo(depth, header("depth_optical"));
  try {
    br::RgbdReader unregistered(colour_info, depth_info, colour_from_depth, false);
    ADD_FAILURE() << "depth of another frame read without registration";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("depth_registered/"), std::string::npos) << e.what();
  }
  EXPECT_THROW(br::RgbdReader(colour_info, depth_info, std::nullopt, true), std::invalid_argument)
      << "registered without a transform";
  const br::RgbdReader reader(colour_info, depth_info, colour_from_depth, true);
  EXPECT_NE(reader.description().find("registered"), std::string::npos) << reader.description();
  cv::Mat bgr, metres;
  ASSERT_EQ(reader.read(image("rgb_optical", "bgr8", by_colour.bgr),
                        image("depth_optical", "16UC1", millimetres(by_depth.metres)), bgr, metres),
            "");
  int close = 0, both = 0;
  for (int v = 0; v < metres.rows; ++v) {
    for (int u = 0; u < metres.cols; ++u) {
      const float a = metres.at<float>(v, u), b = by_colour.metres.at<float>(v, u);
      if (!std::isfinite(a) || !std::isfinite(b)) continue;
      ++both;
      close += std::abs(a - b) < 0.005;
    }
  }
  EXPECT_GT(both, 200000);
  EXPECT_GT(close, 0.95 * both) << "the registered depth is not the colour camera's";
  // The depth camera as placed by the colour camera's pose (what the locator bounds its measurements by).
  const std::optional<bv::PinholeCamera> placed = reader.depthCamera(colour.pose);
  ASSERT_TRUE(placed.has_value());
  EXPECT_NEAR(placed->fx, 580.0, 1e-9);
  EXPECT_LT((placed->pose.matrix() - depth.pose.matrix()).norm(), 1e-12);
  // The same frame at half the resolution (a depth_registered stream of another mode): resampled onto the colour's
  // pixels.
  bv::PinholeCamera half = colour;
  half.width /= 2;
  half.height /= 2;
  half.fx /= 2;
  half.fy /= 2;
  half.cx = 0.5 * (colour.cx + 0.5) - 0.5;
  half.cy = 0.5 * (colour.cy + 0.5) - 0.5;
  const br::RgbdReader resampling(colour_info, br::cameraInfo(half, header("rgb_optical")), std::nullopt, false);
  EXPECT_FALSE(resampling.depthCamera(colour.pose).has_value()) << "the same camera: its depth is the colour's view";
  ASSERT_EQ(resampling.read(image("rgb_optical", "bgr8", by_colour.bgr),
                            image("rgb_optical", "32FC1", look(half).metres), bgr, metres),
            "");
  EXPECT_EQ(metres.cols, 640);
}

TEST(RgbdReader, RawDistortedColourIsRectifiedAndAnOrthographicCameraIsOnlyDecoded) {
  sensor_msgs::CameraInfo info = br::cameraInfo(kinect(), header("rgb_optical"));
  info.D = {0.19, -0.45, 0.001, -0.002, 0.2};
  const br::RgbdReader reader(info);
  EXPECT_NE(reader.description().find("rectified from plumb_bob"), std::string::npos) << reader.description();
  cv::Mat bgr;
  const Seen seen = look(kinect());
  ASSERT_EQ(reader.readColour(image("rgb_optical", "bgr8", seen.bgr), bgr), "");
  cv::Mat difference;
  cv::absdiff(bgr, seen.bgr, difference);
  EXPECT_GT(cv::mean(difference)[0], 1.0) << "a distorted image passed unrectified";
  info.distortion_model = "fov";
  EXPECT_THROW(br::RgbdReader{info}, std::invalid_argument);
  const bv::TopDownCamera map = bv::TopDownCamera::covering(320, 240, 1.0, Eigen::Vector2d(0.55, 0.0), 1.65);
  const sensor_msgs::CameraInfo top = br::cameraInfo(map, header("top_down"));
  const br::RgbdReader orthographic(top, top, std::nullopt, false);
  cv::Mat metres;
  ASSERT_EQ(
      orthographic.read(image("top_down", "bgr8", cv::Mat(240, 320, CV_8UC3, cv::Scalar::all(9))),
                        image("top_down", "16UC1", cv::Mat(240, 320, CV_16UC1, cv::Scalar::all(1500))), bgr, metres),
      "");
  EXPECT_FLOAT_EQ(metres.at<float>(3, 4), 1.5f);
  EXPECT_THROW(br::RgbdReader(top, br::cameraInfo(kinect(), header("top_down")), std::nullopt, false),
               std::invalid_argument);
}
