// The vision module: the renderer against exact geometry (depth of planes, projected areas, occlusion), the reward's
// image terms against synthetic images whose answers are known in closed form, bad input, allocation freedom.
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/image_reward.hpp"
#include "bimanual_skills/vision/synthetic_cloth.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

namespace bv = bimanual_skills::vision;
using bimanual_skills::testing::NoAllocGuard;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Default scene; noise off unless a test turns it on.
bv::ClothRendererParameters scene(int columns = 320, int rows = 240) {
  bv::ClothRendererParameters p;
  p.camera = bv::TopDownCamera::covering(columns, rows, 1.0, Eigen::Vector2d(0.5, 0.0), 1.5);
  return p;
}

/// Pixels whose centre lies in the world rectangle [x0, x1] × [y0, y1]: the projected area in whole pixels.
int pixelsInside(const bv::TopDownCamera& camera, double x0, double x1, double y0, double y1) {
  int count = 0;
  for (int v = 0; v < camera.rows; ++v) {
    for (int u = 0; u < camera.columns; ++u) {
      const Eigen::Vector2d c = camera.pixelCentre(u, v);
      if (c.x() >= x0 && c.x() <= x1 && c.y() >= y0 && c.y() <= y1) ++count;
    }
  }
  return count;
}

/// A synthetic camera image: table colour everywhere, the given polygon filled with the cloth colour, as the
/// renderer's shading would give them.
cv::Mat paint(const bv::TopDownCamera& camera, const std::vector<cv::Point>& polygon) {
  cv::Mat image(camera.rows, camera.columns, CV_8UC3, cv::Scalar(143, 184, 209));              // Table (BGR).
  cv::fillPoly(image, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(184, 60, 26));  // Blue cloth.
  return image;
}

std::vector<cv::Point> rotatedRectangle(cv::Point2f centre, cv::Size2f size, float angle) {
  cv::Point2f corners[4];
  cv::RotatedRect(centre, size, angle).points(corners);
  std::vector<cv::Point> polygon;
  for (const cv::Point2f& c : corners) polygon.emplace_back(cvRound(c.x), cvRound(c.y));
  return polygon;
}

}  // namespace

// ---- Renderer ----

TEST(ClothRenderer, FlatSquareHasExactDepthAndItsProjectedArea) {
  const bv::ClothRendererParameters p = scene();
  bv::ClothRenderer renderer(p);
  const double z = p.table.height + 0.004, side = 0.3;
  const Eigen::Vector3d centre(0.47, 0.05, z);
  const bv::ClothMesh cloth = bv::flatCloth(side, side, 20, 20, centre);
  ASSERT_EQ(renderer.render(cloth.vertices, cloth.triangles), bv::VisionStatus::Ok);

  const double s = p.camera.pixel_size;
  const double x0 = centre.x() - side / 2, x1 = centre.x() + side / 2;
  const double y0 = centre.y() - side / 2, y1 = centre.y() + side / 2;
  const int expected = pixelsInside(p.camera, x0, x1, y0, y1);
  // The projected area in pixels, and the pixel-centre count of the exact square: within one border of pixels.
  EXPECT_NEAR(renderer.clothPixelCount(), side * side / (s * s), 4.0 * side / s);
  EXPECT_NEAR(renderer.clothPixelCount(), expected, 4.0 * side / s * 0.05 + 1);

  const float cloth_depth = static_cast<float>(p.camera.height - z);
  const float table_depth = static_cast<float>(p.camera.height - p.table.height);
  const float floor_depth = static_cast<float>(p.camera.height - p.floor_height);
  int checked = 0;
  for (int v = 0; v < p.camera.rows; ++v) {
    for (int u = 0; u < p.camera.columns; ++u) {
      const Eigen::Vector2d c = p.camera.pixelCentre(u, v);
      const bool cloth_pixel = renderer.clothMask().at<unsigned char>(v, u) != 0;
      if (cloth_pixel) {
        ++checked;
        EXPECT_NEAR(renderer.depth().at<float>(v, u), cloth_depth, 1e-6);
        ASSERT_TRUE(c.x() >= x0 - s && c.x() <= x1 + s && c.y() >= y0 - s && c.y() <= y1 + s) << u << "," << v;
        const cv::Vec3b bgr = renderer.bgr().at<cv::Vec3b>(v, u);
        EXPECT_GT(bgr[0], bgr[2]);  // Blue cloth.
      } else {
        const bool on_table = std::abs(c.x() - p.table.centre.x()) <= p.table.size.x() / 2 &&
                              std::abs(c.y() - p.table.centre.y()) <= p.table.size.y() / 2;
        EXPECT_FLOAT_EQ(renderer.depth().at<float>(v, u), on_table ? table_depth : floor_depth);
        // Strictly inside the square (half a pixel from its border) every pixel is cloth.
        ASSERT_FALSE(c.x() > x0 + s && c.x() < x1 - s && c.y() > y0 + s && c.y() < y1 - s) << u << "," << v;
      }
    }
  }
  EXPECT_EQ(checked, renderer.clothPixelCount());
}

TEST(ClothRenderer, DepthOfATiltedPlaneIsExactAtEveryPixel) {
  const bv::ClothRendererParameters p = scene();
  bv::ClothRenderer renderer(p);
  bv::ClothMesh cloth = bv::flatCloth(0.4, 0.5, 7, 9, Eigen::Vector3d(0.5, 0.0, 0.0));
  const double a = 0.2, b = -0.1, c = 0.3;  // z = a x + b y + c
  for (Eigen::Index k = 0; k < cloth.vertices.cols(); ++k) {
    cloth.vertices(2, k) = a * cloth.vertices(0, k) + b * cloth.vertices(1, k) + c;
  }
  ASSERT_EQ(renderer.render(cloth.vertices, cloth.triangles), bv::VisionStatus::Ok);
  ASSERT_GT(renderer.clothPixelCount(), 10000);
  for (int v = 0; v < p.camera.rows; ++v) {
    for (int u = 0; u < p.camera.columns; ++u) {
      if (!renderer.clothMask().at<unsigned char>(v, u)) continue;
      const Eigen::Vector2d xy = p.camera.pixelCentre(u, v);
      ASSERT_NEAR(renderer.depth().at<float>(v, u), p.camera.height - (a * xy.x() + b * xy.y() + c), 2e-6);
    }
  }
}

TEST(ClothRenderer, UpperLayerWinsWhateverTheDrawingOrder) {
  const bv::ClothRendererParameters p = scene();
  bv::ClothRenderer renderer(p);
  const double low = p.table.height + 0.004, high = low + 0.01;
  const bv::ClothMesh lower = bv::flatCloth(0.3, 0.3, 5, 5, Eigen::Vector3d(0.45, 0.0, low));
  const bv::ClothMesh upper = bv::flatCloth(0.3, 0.3, 5, 5, Eigen::Vector3d(0.55, 0.0, high));
  const int n = static_cast<int>(lower.vertices.cols());
  Eigen::Matrix3Xd vertices(3, 2 * n);
  vertices << lower.vertices, upper.vertices;
  const Eigen::Index m = lower.triangles.cols();
  Eigen::Matrix3Xi lower_first(3, 2 * m), upper_first(3, 2 * m);
  lower_first << lower.triangles, (upper.triangles.array() + n).matrix();
  upper_first << (upper.triangles.array() + n).matrix(), lower.triangles;
  const int u = p.camera.columns / 2, v = p.camera.rows / 2;  // World (0.5, 0): inside both squares.
  for (const Eigen::Matrix3Xi* triangles : {&lower_first, &upper_first}) {
    ASSERT_EQ(renderer.render(vertices, *triangles), bv::VisionStatus::Ok);
    EXPECT_NEAR(renderer.depth().at<float>(v, u), p.camera.height - high, 1e-6);
    EXPECT_NEAR(renderer.depth().at<float>(v, p.camera.columns / 2 - 40), p.camera.height - low, 1e-6);  // x≈0.375
  }
}

TEST(ClothRenderer, HalfFoldHalvesTheAreaAndShowsTheTopLayer) {
  const bv::ClothRendererParameters p = scene();
  bv::ClothRenderer renderer(p);
  const double z = p.table.height + 0.004, r = 0.004;
  const bv::ClothMesh flat = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.5, 0.0, z));
  ASSERT_EQ(renderer.render(flat.vertices, flat.triangles), bv::VisionStatus::Ok);
  const int flat_pixels = renderer.clothPixelCount();
  const bv::ClothMesh folded = bv::foldCloth(flat, 0.5, r);
  ASSERT_EQ(renderer.render(folded.vertices, folded.triangles), bv::VisionStatus::Ok);
  EXPECT_NEAR(double(renderer.clothPixelCount()) / flat_pixels, 0.5, 0.02);
  // Over the lower half, the upper layer (2 r higher) is what the camera sees.
  const Eigen::Vector2d centre_of_lower_half = p.camera.project(Eigen::Vector3d(0.375, 0.0, 0.0));
  EXPECT_NEAR(renderer.depth().at<float>(int(centre_of_lower_half.y()), int(centre_of_lower_half.x())),
              p.camera.height - (z + 2 * r), 1e-6);
}

TEST(ClothRenderer, BadMeshesGiveAStatusAndTheEmptyScene) {
  const bv::ClothRendererParameters p = scene(64, 48);
  bv::ClothRenderer renderer(p);
  bv::ClothMesh cloth = bv::flatCloth(0.3, 0.3, 4, 4, Eigen::Vector3d(0.5, 0.0, 0.2));
  ASSERT_EQ(renderer.render(cloth.vertices, cloth.triangles), bv::VisionStatus::Ok);
  ASSERT_GT(renderer.clothPixelCount(), 0);

  EXPECT_EQ(renderer.render(Eigen::Matrix3Xd(3, 0), cloth.triangles), bv::VisionStatus::EmptyMesh);
  EXPECT_EQ(renderer.clothPixelCount(), 0);
  EXPECT_EQ(renderer.render(cloth.vertices, Eigen::Matrix3Xi(3, 0)), bv::VisionStatus::EmptyMesh);

  bv::ClothMesh nan = cloth;
  nan.vertices(1, 5) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(renderer.render(nan.vertices, nan.triangles), bv::VisionStatus::NonFiniteVertex);
  EXPECT_EQ(renderer.clothPixelCount(), 0);
  EXPECT_EQ(cv::countNonZero(renderer.clothMask()), 0);
  nan.vertices(1, 5) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(renderer.render(nan.vertices, nan.triangles), bv::VisionStatus::NonFiniteVertex);

  bv::ClothMesh bad = cloth;
  bad.triangles(2, 3) = static_cast<int>(cloth.vertices.cols());
  EXPECT_EQ(renderer.render(bad.vertices, bad.triangles), bv::VisionStatus::BadTriangle);
  bad.triangles(2, 3) = -1;
  EXPECT_EQ(renderer.render(bad.vertices, bad.triangles), bv::VisionStatus::BadTriangle);
  EXPECT_EQ(renderer.clothPixelCount(), 0);

  // Huge but finite coordinates, a degenerate triangle, a vertical one and one above the camera: drawn or skipped,
  // never a crash.
  bv::ClothMesh wild = cloth;
  wild.vertices.col(0) << 1e300, -1e300, 0.2;
  wild.vertices.col(1) = wild.vertices.col(2);
  wild.vertices(2, 7) = 5.0;
  EXPECT_EQ(renderer.render(wild.vertices, wild.triangles), bv::VisionStatus::Ok);
  Eigen::Matrix3Xd vertical(3, 3);
  vertical << 0.5, 0.5, 0.5, 0.0, 0.1, 0.0, 0.2, 0.2, 0.4;
  EXPECT_EQ(renderer.render(vertical, Eigen::Matrix3Xi(Eigen::Vector3i(0, 1, 2))), bv::VisionStatus::Ok);
  EXPECT_EQ(renderer.clothPixelCount(), 0);
}

TEST(ClothRenderer, InvalidParametersThrow) {
  bv::ClothRendererParameters p = scene(64, 48);
  p.camera.columns = 2;
  EXPECT_THROW(bv::ClothRenderer{p}, std::invalid_argument);
  p = scene(64, 48);
  p.camera.pixel_size = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(bv::ClothRenderer{p}, std::invalid_argument);
  p = scene(64, 48);
  p.table.height = 2.0;  // Above the camera.
  EXPECT_THROW(bv::ClothRenderer{p}, std::invalid_argument);
  p = scene(64, 48);
  p.cloth_colour.x() = 1.5;
  EXPECT_THROW(bv::ClothRenderer{p}, std::invalid_argument);
  p = scene(64, 48);
  p.noise.depth_stddev = -1.0;
  EXPECT_THROW(bv::ClothRenderer{p}, std::invalid_argument);
  EXPECT_THROW(bv::flatCloth(0.3, 0.3, 1, 4, Eigen::Vector3d::Zero()), std::invalid_argument);
  EXPECT_THROW(bv::foldCloth(bv::flatCloth(0.3, 0.3, 4, 4, Eigen::Vector3d::Zero()), 0.0, 0.0), std::invalid_argument);
}

TEST(ClothRenderer, NoiseIsSeededGaussianAndOfTheGivenSpread) {
  bv::ClothRendererParameters p = scene(640, 480);
  p.noise.depth_stddev = 0.002;
  p.noise.colour_stddev = 3.0;
  bv::ClothRenderer renderer(p), twin(p);
  const bv::ClothMesh cloth = bv::flatCloth(0.3, 0.3, 5, 5, Eigen::Vector3d(0.5, 0.0, 0.2));
  ASSERT_EQ(renderer.render(cloth.vertices, cloth.triangles), bv::VisionStatus::Ok);
  const cv::Mat clean_depth = renderer.depth().clone(), clean_bgr = renderer.bgr().clone();
  const cv::Mat clean_mask = renderer.clothMask().clone();

  std::mt19937 rng(11), same(11), other(12);
  ASSERT_EQ(renderer.render(cloth.vertices, cloth.triangles, rng), bv::VisionStatus::Ok);
  ASSERT_EQ(twin.render(cloth.vertices, cloth.triangles, same), bv::VisionStatus::Ok);
  EXPECT_EQ(cv::norm(renderer.depth(), twin.depth(), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(renderer.bgr(), twin.bgr(), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(renderer.clothMask(), clean_mask, cv::NORM_INF), 0.0);
  ASSERT_EQ(twin.render(cloth.vertices, cloth.triangles, other), bv::VisionStatus::Ok);
  EXPECT_GT(cv::norm(renderer.depth(), twin.depth(), cv::NORM_INF), 0.0);

  cv::Mat depth_error = renderer.depth() - clean_depth;
  cv::Scalar mean, stddev;
  cv::meanStdDev(depth_error, mean, stddev);
  EXPECT_NEAR(mean[0], 0.0, 0.05 * p.noise.depth_stddev);
  EXPECT_NEAR(stddev[0], p.noise.depth_stddev, 0.01 * p.noise.depth_stddev);
  // Gaussian tails: P(|e| > 2σ) = 4.55 % (a sum of four uniforms would give 4.25 %); 307 200 draws, σ of 0.04 %.
  const double beyond =
      cv::countNonZero(cv::abs(depth_error) > 2.0 * p.noise.depth_stddev) / double(depth_error.total());
  EXPECT_NEAR(beyond, 0.0455, 0.0015);
  cv::Mat colour_error;
  cv::subtract(renderer.bgr(), clean_bgr, colour_error, cv::noArray(), CV_32FC3);
  cv::meanStdDev(colour_error.reshape(1), mean, stddev);
  EXPECT_NEAR(mean[0], 0.0, 0.05 * p.noise.colour_stddev);
  EXPECT_NEAR(stddev[0], p.noise.colour_stddev, 0.05 * p.noise.colour_stddev);  // Rounding to integers adds 1/12.
}

TEST(ClothRenderer, RenderingAtProductionSizesDoesNotAllocate) {
  const bv::ClothRendererParameters p = scene(640, 480);
  bv::ClothRenderer renderer(p);
  const bv::ClothMesh flat = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.5, 0.0, p.table.height + 0.004));
  const bv::ClothMesh folded = bv::foldCloth(flat, 0.5, 0.004);
  bv::ClothMesh nan = flat;
  nan.vertices(0, 3) = std::numeric_limits<double>::quiet_NaN();
  std::mt19937 rng(3);
  NoAllocGuard guard;
  EXPECT_EQ(renderer.render(flat.vertices, flat.triangles), bv::VisionStatus::Ok);
  EXPECT_EQ(renderer.render(folded.vertices, folded.triangles, rng), bv::VisionStatus::Ok);
  EXPECT_EQ(renderer.render(nan.vertices, nan.triangles, rng), bv::VisionStatus::NonFiniteVertex);
}

// ---- Colour term (rectangularity) ----

TEST(ImageReward, PerfectRectangleFillsItsRectangle) {
  const bv::TopDownCamera camera = scene().camera;
  bv::ImageReward reward(camera, {});
  const cv::Mat image = paint(camera, {{60, 50}, {219, 50}, {219, 169}, {60, 169}});  // 160 × 120 pixels.
  ASSERT_EQ(reward.segment(image), bv::VisionStatus::Ok);
  const bv::ColourTerm term = reward.colourTerm(reward.mask());
  ASSERT_EQ(term.status, bv::VisionStatus::Ok);
  EXPECT_EQ(term.cloth_pixels, 160 * 120);
  EXPECT_NEAR(term.fill_ratio, 1.0, 1e-9);

  // Turned by 30°: still a rectangle, up to the staircase of its edges.
  const cv::Mat turned = paint(camera, rotatedRectangle({160, 120}, {150, 90}, 30.0f));
  ASSERT_EQ(reward.segment(turned), bv::VisionStatus::Ok);
  EXPECT_NEAR(reward.colourTerm(reward.mask()).fill_ratio, 1.0, 0.03);
}

TEST(ImageReward, StrayPixelsAreRemovedBeforeTheRectangleIsFitted) {
  const bv::TopDownCamera camera = scene().camera;
  cv::Mat image = paint(camera, {{60, 50}, {219, 50}, {219, 169}, {60, 169}});
  image.at<cv::Vec3b>(220, 300) = cv::Vec3b(184, 60, 26);  // One misclassified pixel far from the cloth.
  bv::ImageReward reward(camera, {});
  ASSERT_EQ(reward.segment(image), bv::VisionStatus::Ok);
  EXPECT_NEAR(reward.colourTerm(reward.mask()).fill_ratio, 1.0, 1e-9);
  bv::ImageRewardParameters raw;
  raw.segmentation.remove_speckles = false;
  bv::ImageReward unfiltered(camera, raw);
  ASSERT_EQ(unfiltered.segment(image), bv::VisionStatus::Ok);
  EXPECT_LT(unfiltered.colourTerm(unfiltered.mask()).fill_ratio, 0.9);
}

TEST(ImageReward, CrumpledShapesFillLess) {
  const bv::TopDownCamera camera = scene().camera;
  bv::ImageReward reward(camera, {});
  // An L of three squares out of a 2 × 2 block: ρ = 3/4.
  const cv::Mat l_shape = paint(camera, {{60, 40}, {139, 40}, {139, 119}, {219, 119}, {219, 199}, {60, 199}});
  ASSERT_EQ(reward.segment(l_shape), bv::VisionStatus::Ok);
  EXPECT_NEAR(reward.colourTerm(reward.mask()).fill_ratio, 0.75, 0.01);

  // A five-pointed star (inner radius 0.4 of the outer): area 5 R r sin 36° over its minimum rectangle ≈ 0.36.
  std::vector<cv::Point> star;
  for (int k = 0; k < 10; ++k) {
    const double radius = (k % 2 == 0) ? 100.0 : 40.0, angle = kPi / 5.0 * k - kPi / 2.0;
    star.emplace_back(cvRound(160 + radius * std::cos(angle)), cvRound(120 + radius * std::sin(angle)));
  }
  ASSERT_EQ(reward.segment(paint(camera, star)), bv::VisionStatus::Ok);
  const double star_ratio = reward.colourTerm(reward.mask()).fill_ratio;
  EXPECT_GT(star_ratio, 0.25);
  EXPECT_LT(star_ratio, 0.45);
}

TEST(ImageReward, FoldFactsOfARectangle) {
  const bv::TopDownCamera camera = scene().camera;  // 1 m over 320 pixels.
  bv::ImageReward reward(camera, {});
  cv::Mat mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  mask(cv::Rect(100, 40, 80, 160)).setTo(255);  // 0.25 m × 0.5 m.
  const bv::FoldFacts facts = reward.foldFacts(mask, 0.5 * 0.5);
  ASSERT_EQ(facts.status, bv::VisionStatus::Ok);
  EXPECT_EQ(facts.cloth_pixels, 80 * 160);
  EXPECT_NEAR(facts.cloth_area, 0.125, 1e-12);
  EXPECT_NEAR(facts.area_ratio, 0.5, 1e-12);
  EXPECT_NEAR(facts.rectangle_length, 0.5, 1e-6);
  EXPECT_NEAR(facts.rectangle_width, 0.25, 1e-6);
  EXPECT_NEAR(facts.aspect, 2.0, 1e-6);
  EXPECT_NEAR(facts.fill_ratio, 1.0, 1e-9);
  EXPECT_THROW(reward.foldFacts(mask, 0.0), std::invalid_argument);
}

// ---- Depth term (wrinkledness) ----

TEST(ImageReward, FlatAndTiltedDepthGiveTheirSlope) {
  const bv::TopDownCamera camera = scene().camera;
  bv::ImageRewardParameters parameters;
  parameters.depth_smoothing = 0.0;
  bv::ImageReward reward(camera, parameters);
  cv::Mat mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  mask(cv::Rect(40, 30, 240, 180)).setTo(255);
  cv::Mat depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(1.346));
  bv::DepthTerm term = reward.depthTerm(depth, mask);
  ASSERT_EQ(term.status, bv::VisionStatus::Ok);
  EXPECT_EQ(term.pixels, 238 * 178);  // One pixel eroded from each side.
  EXPECT_NEAR(term.mean_gradient, 0.0, 1e-9);

  // d = 1.3 + 0.3 x − 0.4 y (world metres): ‖∇d‖ = 0.5 everywhere (Sobel is exact on planes).
  for (int v = 0; v < camera.rows; ++v) {
    for (int u = 0; u < camera.columns; ++u) {
      const Eigen::Vector2d xy = camera.pixelCentre(u, v);
      depth.at<float>(v, u) = static_cast<float>(1.3 + 0.3 * xy.x() - 0.4 * xy.y());
    }
  }
  term = reward.depthTerm(depth, mask);
  EXPECT_NEAR(term.mean_gradient, 0.5, 1e-3);
}

TEST(ImageReward, SinusoidalDepthGivesTheAnalyticMeanGradient) {
  const bv::TopDownCamera camera = scene().camera;
  bv::ImageRewardParameters parameters;
  parameters.border_erosion = 0;
  parameters.depth_smoothing = 0.0;
  bv::ImageReward reward(camera, parameters);
  // d = d0 + A sin(2π x / λ) with λ = 40 pixels: mean |∂d/∂x| = (2π A / λ)(2/π) = 4 A / λ over whole periods.
  const double amplitude = 0.01, wavelength = 40 * camera.pixel_size;
  cv::Mat depth(camera.rows, camera.columns, CV_32FC1);
  for (int v = 0; v < camera.rows; ++v) {
    for (int u = 0; u < camera.columns; ++u) {
      depth.at<float>(v, u) =
          static_cast<float>(1.3 + amplitude * std::sin(2 * kPi * (u + 0.5) * camera.pixel_size / wavelength));
    }
  }
  cv::Mat mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  mask(cv::Rect(20, 20, 280, 200)).setTo(255);  // Seven whole periods across.
  const bv::DepthTerm term = reward.depthTerm(depth, mask);
  ASSERT_EQ(term.status, bv::VisionStatus::Ok);
  EXPECT_NEAR(term.mean_gradient, 4.0 * amplitude / wavelength, 0.01 * 4.0 * amplitude / wavelength);
  // Wrinkles of half the wavelength are twice as steep.
  for (int v = 0; v < camera.rows; ++v) {
    for (int u = 0; u < camera.columns; ++u) {
      depth.at<float>(v, u) =
          static_cast<float>(1.3 + amplitude * std::sin(2 * kPi * (v + 0.5) * camera.pixel_size / (0.5 * wavelength)));
    }
  }
  EXPECT_NEAR(reward.depthTerm(depth, mask).mean_gradient, 8.0 * amplitude / wavelength,
              0.02 * 8.0 * amplitude / wavelength);
}

TEST(ImageReward, SmoothingRemovesSensorNoiseAndKeepsWrinkles) {
  const bv::TopDownCamera camera = scene(640, 480).camera;
  bv::ImageRewardParameters raw_parameters;
  raw_parameters.depth_smoothing = 0.0;
  bv::ImageReward raw(camera, raw_parameters);
  bv::ImageReward smoothed(camera, {});  // σ = 5 mm.
  cv::Mat mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  mask(cv::Rect(40, 40, 560, 400)).setTo(255);  // Seven periods of 80 pixels across.
  // White noise of 1 mm on a flat cloth: ḡ ≈ 1.25 · √12 σ_d / (8 s) raw (Rayleigh mean of the Sobel noise).
  cv::Mat depth(camera.rows, camera.columns, CV_32FC1);
  cv::RNG rng(9);
  rng.fill(depth, cv::RNG::NORMAL, 1.3, 0.001);
  const double raw_noise = raw.depthTerm(depth, mask).mean_gradient;
  EXPECT_NEAR(raw_noise, std::sqrt(kPi / 2.0) * std::sqrt(12.0) * 0.001 / (8.0 * camera.pixel_size), 0.02);
  EXPECT_LT(smoothed.depthTerm(depth, mask).mean_gradient, 0.15 * raw_noise);
  // A wrinkle of wavelength λ survives the smoothing attenuated by exp(−(2π σ / λ)² / 2).
  const double amplitude = 0.01, wavelength = 80 * camera.pixel_size, sigma = 0.005;
  for (int v = 0; v < camera.rows; ++v) {
    for (int u = 0; u < camera.columns; ++u) {
      depth.at<float>(v, u) =
          static_cast<float>(1.3 + amplitude * std::sin(2 * kPi * (u + 0.5) * camera.pixel_size / wavelength));
    }
  }
  const double k = 2 * kPi / wavelength;
  EXPECT_NEAR(smoothed.depthTerm(depth, mask).mean_gradient,
              4.0 * amplitude / wavelength * std::exp(-0.5 * k * k * sigma * sigma),
              0.03 * 4.0 * amplitude / wavelength);
}

TEST(ImageReward, NonFiniteDepthPixelsAreSkipped) {
  const bv::TopDownCamera camera = scene(64, 48).camera;
  bv::ImageRewardParameters parameters;
  parameters.border_erosion = 0;
  parameters.depth_smoothing = 0.0;
  bv::ImageReward reward(camera, parameters);
  cv::Mat depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(1.3));
  depth.at<float>(10, 10) = std::numeric_limits<float>::quiet_NaN();
  const cv::Mat mask(camera.rows, camera.columns, CV_8UC1, cv::Scalar(255));
  const bv::DepthTerm term = reward.depthTerm(depth, mask);
  EXPECT_EQ(term.status, bv::VisionStatus::Ok);
  EXPECT_EQ(term.pixels, 64 * 48 - 9);  // The NaN pixel and its 8 neighbours, which it reaches through Sobel.
  EXPECT_NEAR(term.mean_gradient, 0.0, 1e-9);
  depth.setTo(std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(reward.depthTerm(depth, mask).status, bv::VisionStatus::NoCloth);
}

// ---- The whole evaluation, and bad input ----

TEST(ImageReward, RenderedFlatFoldedAndCrumpledCloth) {
  bv::ClothRendererParameters p = scene();
  bv::ClothRenderer renderer(p);
  bv::ImageReward reward(p.camera, {});
  const double z = p.table.height + 0.004;
  const bv::ClothMesh flat = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.5, 0.0, z));
  std::mt19937 rng(5);

  ASSERT_EQ(renderer.render(flat.vertices, flat.triangles, rng), bv::VisionStatus::Ok);
  const bv::ImageRewardTerms flat_terms = reward.evaluate(renderer.bgr(), renderer.depth());
  ASSERT_EQ(flat_terms.status, bv::VisionStatus::Ok);
  // The segmentation finds the renderer's own cloth mask under noise.
  EXPECT_EQ(cv::norm(reward.mask(), renderer.clothMask(), cv::NORM_L1) / 255.0, 0.0);
  EXPECT_GT(flat_terms.colour.fill_ratio, 0.99);
  EXPECT_NEAR(flat_terms.r_color, 1.0 - flat_terms.colour.fill_ratio, 1e-12);
  EXPECT_NEAR(flat_terms.reward(), -flat_terms.r_color - flat_terms.r_depth, 1e-12);
  const bv::FoldFacts flat_facts = reward.foldFacts(reward.mask(), 0.5 * 0.6);
  EXPECT_NEAR(flat_facts.area_ratio, 1.0, 0.02);
  EXPECT_NEAR(flat_facts.aspect, 1.2, 0.02);

  const bv::ClothMesh folded = bv::foldCloth(flat, 0.5, 0.004);
  ASSERT_EQ(renderer.render(folded.vertices, folded.triangles, rng), bv::VisionStatus::Ok);
  const bv::ImageRewardTerms folded_terms = reward.evaluate(renderer.bgr(), renderer.depth());
  ASSERT_EQ(folded_terms.status, bv::VisionStatus::Ok);
  EXPECT_GT(folded_terms.colour.fill_ratio, 0.97);
  const bv::FoldFacts folded_facts = reward.foldFacts(reward.mask(), 0.5 * 0.6);
  EXPECT_NEAR(folded_facts.area_ratio, 0.5, 0.03);
  EXPECT_NEAR(folded_facts.aspect, 0.6 / 0.25, 0.1);

  // Crumpled: pulled together and wrinkled, it fills its rectangle less and its depth varies more.
  const bv::ClothMesh crumpled = bv::crumpleCloth(flat, rng);
  ASSERT_EQ(renderer.render(crumpled.vertices, crumpled.triangles, rng), bv::VisionStatus::Ok);
  const bv::ImageRewardTerms crumpled_terms = reward.evaluate(renderer.bgr(), renderer.depth());
  ASSERT_EQ(crumpled_terms.status, bv::VisionStatus::Ok);
  EXPECT_LT(crumpled_terms.colour.fill_ratio, flat_terms.colour.fill_ratio - 0.1);
  EXPECT_GT(crumpled_terms.depth.mean_gradient, 3.0 * flat_terms.depth.mean_gradient);
  EXPECT_LT(crumpled_terms.reward(), flat_terms.reward());
  EXPECT_LT(crumpled_terms.reward(), folded_terms.reward());
}

TEST(ImageReward, WrongImagesAndNoClothGiveAStatusAndTheWorstTerms) {
  const bv::TopDownCamera camera = scene(64, 48).camera;
  bv::ImageRewardParameters parameters;
  parameters.colour_weight = 2.0;
  parameters.depth_weight = 3.0;
  parameters.no_cloth_gradient = 0.7;
  bv::ImageReward reward(camera, parameters);
  const cv::Mat bgr(camera.rows, camera.columns, CV_8UC3, cv::Scalar(143, 184, 209));  // Table only.
  const cv::Mat depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(1.3));

  bv::ImageRewardTerms terms = reward.evaluate(bgr, depth);
  EXPECT_EQ(terms.status, bv::VisionStatus::NoCloth);
  EXPECT_DOUBLE_EQ(terms.r_color, 2.0);
  EXPECT_DOUBLE_EQ(terms.r_depth, 3.0 * 0.7);
  EXPECT_DOUBLE_EQ(terms.reward(), -2.0 - 2.1);

  const cv::Mat small(camera.rows - 1, camera.columns, CV_8UC3, cv::Scalar(0, 0, 0));
  EXPECT_EQ(reward.evaluate(small, depth).status, bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.evaluate(bgr, cv::Mat(camera.rows, camera.columns, CV_64FC1)).status,
            bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.evaluate(cv::Mat(), depth).status, bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.evaluate(bgr, depth.t()).status, bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.segment(cv::Mat(camera.rows, camera.columns, CV_8UC1)), bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.colourTerm(cv::Mat(camera.rows, camera.columns, CV_8UC3)).status, bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.depthTerm(depth, cv::Mat()).status, bv::VisionStatus::WrongImageSize);
  EXPECT_EQ(reward.colourTerm(cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1)).status, bv::VisionStatus::NoCloth);

  bv::ImageRewardParameters bad;
  bad.segmentation.hue_min = 150;
  bad.segmentation.hue_max = 100;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.depth_weight = -1.0;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bv::TopDownCamera bad_camera = camera;
  bad_camera.rows = 0;
  EXPECT_THROW(bv::ImageReward(bad_camera, {}), std::invalid_argument);
}

// ---- Goal term ----

// Against a goal of two stacked layers on the left half of a rectangle: the goal itself matches, the flat
// rectangle's IoU is ½ with its shared half one layer low, cloth heaped above the goal costs by its excess height,
// and a brute-force count gives the shifted goal's IoU.
TEST(ImageReward, GoalTermCountsMissingPixelsAndHeightErrors) {
  const bv::TopDownCamera camera = scene(64, 48).camera;
  bv::ImageRewardParameters parameters;
  parameters.goal_weight = 2.0;
  parameters.goal_missing_height = 0.008;
  parameters.goal_excess_height = 0.05;
  bv::ImageReward reward(camera, parameters);
  const float table = 1.35f, layer = 0.004f;
  const cv::Rect left(10, 10, 20, 24), whole(10, 10, 40, 24);
  cv::Mat goal_mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  goal_mask(left).setTo(255);
  cv::Mat goal_depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(table));
  goal_depth(left).setTo(table - 2.0f * layer);

  EXPECT_EQ(reward.goalTerm(goal_depth, goal_mask).status, bv::VisionStatus::NoCloth);  // no goal yet
  reward.setGoal(goal_mask, goal_depth);
  ASSERT_TRUE(reward.hasGoal());
  bv::GoalTerm term = reward.goalTerm(goal_depth, goal_mask);
  ASSERT_EQ(term.status, bv::VisionStatus::Ok);
  EXPECT_DOUBLE_EQ(term.iou, 1.0);
  EXPECT_DOUBLE_EQ(term.mismatch, 0.0);

  // The flat cloth: half its pixels outside the goal (e = 1), the other half 4 mm too low (e = ½).
  cv::Mat flat_mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  flat_mask(whole).setTo(255);
  cv::Mat flat_depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(table));
  flat_depth(whole).setTo(table - layer);
  term = reward.goalTerm(flat_depth, flat_mask);
  EXPECT_NEAR(term.iou, 0.5, 1e-12);
  EXPECT_NEAR(term.mismatch, 0.5 * 1.0 + 0.5 * 0.5, 1e-5);

  // Heaped 25 mm above the goal: e = 25 / 50.
  term = reward.goalTerm(goal_depth - 0.025f, goal_mask);
  EXPECT_NEAR(term.iou, 1.0, 1e-12);
  EXPECT_NEAR(term.mismatch, 0.5, 1e-5);

  // The goal shifted by (7, 5) pixels at the goal's height: e = 1 off the intersection, 0 on it.
  const cv::Rect shifted = left + cv::Point(7, 5);
  cv::Mat shifted_mask = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  shifted_mask(shifted).setTo(255);
  int both = 0, either = 0;
  for (int v = 0; v < camera.rows; ++v) {
    for (int u = 0; u < camera.columns; ++u) {
      const bool a = left.contains({u, v}), b = shifted.contains({u, v});
      both += a && b;
      either += a || b;
    }
  }
  cv::Mat shifted_depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(table));
  shifted_depth(shifted).setTo(table - 2.0f * layer);
  term = reward.goalTerm(shifted_depth, shifted_mask);
  EXPECT_NEAR(term.iou, double(both) / either, 1e-12);
  EXPECT_NEAR(term.mismatch, 1.0 - double(both) / either, 1e-12);

  // A non-finite depth on shared cloth counts as a mismatch; evaluate() weighs the term by w_g.
  cv::Mat holes = goal_depth.clone();
  holes(cv::Rect(10, 10, 20, 12)).setTo(std::numeric_limits<float>::quiet_NaN());
  EXPECT_NEAR(reward.goalTerm(holes, goal_mask).mismatch, 0.5, 1e-12);
  const cv::Mat no_cloth = cv::Mat::zeros(camera.rows, camera.columns, CV_8UC1);
  EXPECT_EQ(reward.goalTerm(goal_depth, no_cloth).status, bv::VisionStatus::NoCloth);
  const cv::Mat table_only(camera.rows, camera.columns, CV_8UC3, cv::Scalar(143, 184, 209));
  const bv::ImageRewardTerms seen_nothing = reward.evaluate(table_only, goal_depth);
  EXPECT_DOUBLE_EQ(seen_nothing.r_goal, 2.0);

  EXPECT_EQ(reward.goalTerm(cv::Mat(), goal_mask).status, bv::VisionStatus::WrongImageSize);
  EXPECT_THROW(reward.setGoal(no_cloth, goal_depth), std::invalid_argument);
  EXPECT_THROW(reward.setGoal(goal_mask, cv::Mat(camera.rows, camera.columns, CV_64FC1)), std::invalid_argument);
  EXPECT_THROW(reward.setGoal(goal_mask.t(), goal_depth), std::invalid_argument);
  EXPECT_THROW(reward.setGoal(goal_mask, holes), std::invalid_argument);
  bv::ImageRewardParameters bad;
  bad.goal_missing_height = 0.0;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.goal_weight = std::numeric_limits<double>::infinity();
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
}

// ---- Fold term ----

// Against a flat cloth of 40 × 24 pixels one layer thick, drawn by hand: the flat cloth's edges, fold line, table
// depth and thickness are found; the ideal fold (the near 20 columns, two layers) scores 0, the flat cloth 1, and a
// fold dragged 3 pixels over its near edge or 4 away from it, one whose top layer stops 6 pixels short, and one
// missing half its rows score their widths by the term's weights exactly; cloth piled 8 layers high on the near
// 4 columns is a heap of 4 pixels, across κ's end 2, at the crease (beyond κ of the staying half) none.
TEST(ImageReward, FoldTermMeasuresTheFoldAgainstTheFlatCloth) {
  const bv::TopDownCamera camera = scene(64, 48).camera;
  const double s = camera.pixel_size;
  bv::ImageRewardParameters parameters;
  parameters.fold_weight = 2.0;
  parameters.fold_heap_weight = 3.0;
  parameters.heap_threshold = 3.0;
  parameters.heap_reach = 0.5;
  parameters.fold_smoothing = 0.0;
  bv::ImageReward reward(camera, parameters);
  const float table = 1.35f, layer = 0.004f;
  // Cloth drawn as columns [u0, u1) of rows [10, 34), each column `layers` thick.
  const auto image = [&](int u0, int u1, int thin_until, int rows = 24) {
    cv::Mat bgr(camera.rows, camera.columns, CV_8UC3, cv::Scalar(143, 184, 209));
    cv::Mat depth(camera.rows, camera.columns, CV_32FC1, cv::Scalar(table));
    const cv::Rect cloth(u0, 10, u1 - u0, rows);
    bgr(cloth).setTo(cv::Scalar(184, 60, 26));
    depth(cloth).setTo(table - 2.0f * layer);
    if (thin_until > u0) depth(cv::Rect(u0, 10, thin_until - u0, rows)).setTo(table - layer);
    return std::make_pair(bgr, depth);
  };
  EXPECT_THROW(reward.setFlat(cv::Mat(camera.rows, camera.columns, CV_8UC3, cv::Scalar(143, 184, 209)),
                              cv::Mat(camera.rows, camera.columns, CV_32FC1, cv::Scalar(table))),
               std::invalid_argument);  // no cloth
  const auto [flat_bgr, flat_depth] = image(10, 50, 50);
  EXPECT_THROW(reward.setFlat(flat_bgr, cv::Mat(camera.rows, camera.columns, CV_32FC1, cv::Scalar(table + 0.01f))),
               std::invalid_argument);  // the cloth below the table
  EXPECT_THROW(reward.setFlat(flat_bgr.t(), flat_depth), std::invalid_argument);
  EXPECT_FALSE(reward.hasFlat());
  EXPECT_EQ(reward.foldTerm(flat_depth, reward.mask()).status, bv::VisionStatus::NoCloth);
  reward.setFlat(flat_bgr, flat_depth);
  ASSERT_TRUE(reward.hasFlat());
  const bv::FlatCloth& flat = reward.flat();
  EXPECT_EQ(flat.near_column, 10);
  EXPECT_EQ(flat.far_column, 50);
  EXPECT_EQ(flat.first_row, 10);
  EXPECT_EQ(flat.last_row, 33);
  EXPECT_DOUBLE_EQ(flat.fold_column(), 30.0);
  EXPECT_NEAR(flat.table_depth, table, 1e-6);
  EXPECT_NEAR(flat.thickness, layer, 1e-6);

  const double flat_error = parameters.fold_single_weight * 20 * s + parameters.fold_length_weight * 20 * s;
  const auto term = [&](const std::pair<cv::Mat, cv::Mat>& images) {
    EXPECT_EQ(reward.segment(images.first), bv::VisionStatus::Ok);
    return reward.foldTerm(images.second, reward.mask());
  };
  bv::FoldTerm t = term(image(10, 30, 0));  // the ideal fold
  ASSERT_EQ(t.status, bv::VisionStatus::Ok);
  EXPECT_NEAR(t.mismatch, 0.0, 1e-12);
  t = term(image(10, 50, 50));  // still flat
  EXPECT_NEAR(t.single, 20 * s, 1e-12);
  EXPECT_NEAR(t.length, 20 * s, 1e-12);
  EXPECT_NEAR(t.mismatch, 1.0, 1e-12);
  t = term(image(7, 27, 0));  // dragged over the near edge
  EXPECT_NEAR(t.edge, 3 * s, 1e-12);
  EXPECT_NEAR(t.single, 0.0, 1e-12);
  EXPECT_NEAR(t.length, 0.0, 1e-12);
  EXPECT_NEAR(t.error, parameters.fold_edge_weight * 3 * s, 1e-12);
  t = term(image(14, 34, 0));  // dragged away from the near edge: the same
  EXPECT_NEAR(t.edge, 4 * s, 1e-12);
  EXPECT_NEAR(t.error, parameters.fold_edge_weight * 4 * s, 1e-12);
  t = term(image(10, 30, 16));  // the top layer 6 columns short
  EXPECT_NEAR(t.single, 6 * s, 1e-12);
  EXPECT_NEAR(t.mismatch, parameters.fold_single_weight * 6 * s / flat_error, 1e-12);
  t = term(image(10, 30, 0, 12));  // half the rows bare: each counts twice the flat cloth's error
  EXPECT_NEAR(t.mismatch, 1.0, 1e-12);
  // The far edge heaped on the near one; a pile across κ's end (u_0 + κ (u_c − u_0) = 20); a high crease.
  for (const auto& [heap_at, heaped] : {std::pair{10, 4}, std::pair{18, 2}, std::pair{26, 0}}) {
    auto [bgr, depth] = image(10, 30, 0);
    depth(cv::Rect(heap_at, 10, 4, 24)).setTo(table - 8.0f * layer);
    t = term({bgr, depth});
    EXPECT_NEAR(t.heap, heaped * s, 1e-12) << heap_at;
    EXPECT_NEAR(t.error, parameters.fold_heap_weight * t.heap, 1e-12) << heap_at;
  }
  // evaluate() weighs it by w_f; without cloth in view it is twice the flat cloth's, without a flat cloth unknown (1).
  const auto [ideal_bgr, ideal_depth] = image(10, 30, 0);
  EXPECT_NEAR(reward.evaluate(ideal_bgr, ideal_depth).r_fold, 0.0, 1e-12);
  const cv::Mat table_only(camera.rows, camera.columns, CV_8UC3, cv::Scalar(143, 184, 209));
  EXPECT_DOUBLE_EQ(reward.evaluate(table_only, ideal_depth).r_fold, 4.0);
  reward.clearFlat();
  EXPECT_DOUBLE_EQ(reward.evaluate(ideal_bgr, ideal_depth).r_fold, 2.0);
  EXPECT_EQ(reward.foldTerm(cv::Mat(), reward.mask()).status, bv::VisionStatus::WrongImageSize);

  bv::ImageRewardParameters bad;
  bad.layer_threshold = 1.0;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.fold_single_weight = bad.fold_length_weight = 0.0;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.fold_edge_weight = std::nan("");
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.heap_threshold = bad.layer_threshold;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.heap_reach = 0.0;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
  bad = {};
  bad.fold_heap_weight = -1.0;
  EXPECT_THROW(bv::ImageReward(camera, bad), std::invalid_argument);
}
