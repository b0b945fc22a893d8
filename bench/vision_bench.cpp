// The vision module per call: rendering a 20 × 24-node cloth (flat and folded in half) as a top-down colour and
// depth image at 320 × 240 and 640 × 480, without and with sensor noise; the noise of the same frame drawn with
// std::normal_distribution on a std::mt19937 (the peer); and the reward's image terms (segmentation, minimum-area
// rectangle, Sobel) on the rendered images; the perspective RGB-D camera (640 × 480, Kinect-like errors) and the
// re-projection of its depth into the 320 × 240 map; the tracking experiment's frame (the camera over a can) and
// the can located in it, beside a naive centroid; a Kinect's raw frame read (rectified, registered), beside a
// registration that turns every pixel corner per frame. Seed 7 for the noise.
//
//   vision_bench [--benchmark_format=json] [--benchmark_repetitions=N] ...
//   vision_bench --figures      writes the flat and half-folded cloth's images as PNG into the current directory
#include "bench_timing.hpp"
#include "benchmark_main.hpp"
#include "bimanual_skills/vision/camera_calibration.hpp"
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/depth_registration.hpp"
#include "bimanual_skills/vision/image_reward.hpp"
#include "bimanual_skills/vision/object_locator.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"
#include "bimanual_skills/vision/raw_rgbd_sensor.hpp"
#include "bimanual_skills/vision/synthetic_cloth.hpp"

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

namespace bv = bimanual_skills::vision;
using bimanual_skills::bench::timeBatches;

namespace {

constexpr unsigned kSeed = 7;

/// The default scene seen by a `columns` × `rows` camera covering 1 m of table across, centred on the cloth.
bv::ClothRendererParameters scene(int columns, int rows) {
  bv::ClothRendererParameters p;
  p.camera = bv::TopDownCamera::covering(columns, rows, 1.0, Eigen::Vector2d(0.5, 0.0), 1.5);
  return p;
}

/// The polo-shirt-sized cloth of config/sim.yaml (0.5 × 0.6 m, 20 × 24 nodes) lying on the table; folded: its far
/// half laid over the near half over a crease of radius 4 mm.
bv::ClothMesh cloth(const bv::ClothRendererParameters& p, bool folded) {
  const bv::ClothMesh flat = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.5, 0.0, p.table.height + 0.004));
  return folded ? bv::foldCloth(flat, 0.5, 0.004) : flat;
}

int columnsOf(const benchmark::State& state) {
  return static_cast<int>(state.range(0));
}
int rowsOf(const benchmark::State& state) {
  return columnsOf(state) * 3 / 4;
}

/// render(): args {columns, folded, noise}.
void BM_Render(benchmark::State& state) {
  const bv::ClothRendererParameters p = scene(columnsOf(state), rowsOf(state));
  bv::ClothRenderer renderer(p);
  const bv::ClothMesh mesh = cloth(p, state.range(1) != 0);
  const bool noisy = state.range(2) != 0;
  std::mt19937 rng(kSeed);
  timeBatches(
      state, 1,
      [&](int) {
        const bv::VisionStatus status = noisy ? renderer.render(mesh.vertices, mesh.triangles, rng)
                                              : renderer.render(mesh.vertices, mesh.triangles);
        benchmark::DoNotOptimize(status);
        benchmark::DoNotOptimize(renderer.depth().data);
      },
      1);
  state.counters["cloth_pixels"] = renderer.clothPixelCount();
}

/// The perspective RGB-D camera (640 × 480, the Kinect of tasks::rgbdCameraFor) over the same scene: render with
/// the sensor's errors, then re-project into the 320 × 240 map. args {folded, stage: 0 render, 1 re-project}.
void BM_PerspectiveCamera(benchmark::State& state) {
  const bv::ClothRendererParameters p = scene(320, 240);
  const bv::PinholeCamera camera = bv::PinholeCamera::lookingAt(Eigen::Vector3d(1.15, 0.0, p.table.height + 1.3),
                                                                Eigen::Vector3d(0.5, 0.0, p.table.height));
  bv::PerspectiveRenderer renderer(p, camera);
  bv::HeightMapProjector projector(p.camera);
  const bv::ClothMesh mesh = cloth(p, state.range(0) != 0);
  const bool project = state.range(1) != 0;
  std::mt19937 rng(kSeed);
  renderer.render(mesh.vertices, mesh.triangles, rng);
  timeBatches(
      state, 1,
      [&](int) {
        const bv::VisionStatus status = project ? projector.project(renderer.bgr(), renderer.depth(), camera)
                                                : renderer.render(mesh.vertices, mesh.triangles, rng);
        benchmark::DoNotOptimize(status);
      },
      1);
  state.counters["cloth_pixels"] = renderer.clothPixelCount();
  if (project) state.counters["map_cells_seen"] = projector.coverage().observed + projector.coverage().filled;
}

/// The tracking experiment's frame (thesis Sec. 4.3.2): the perspective camera over the table and a can carried
/// 0.23 m above it (a moving solid), no cloth; then the can found and measured in that frame (ObjectLocator: HSV
/// segmentation, largest component, shape fit), against the naive baseline, the centroid of the colour mask's depth
/// points (no fit: biased towards the camera by about 0.8 of the can's radius). args {stage: 0 render, 1 locate,
/// 2 baseline}.
void BM_TrackingFrame(benchmark::State& state) {
  bv::ClothRendererParameters p = scene(320, 240);
  const bv::PinholeCamera camera = bv::PinholeCamera::lookingAt(Eigen::Vector3d(1.15, 0.0, p.table.height + 1.3),
                                                                Eigen::Vector3d(0.5, 0.0, p.table.height));
  bv::PerspectiveRenderer renderer(p, camera);
  bv::SceneSolid can;
  can.shape = bv::SceneSolid::Shape::Cylinder;
  can.size = Eigen::Vector3d(0.033, 0.12, 0.0);
  can.colour = Eigen::Vector3d(0.95, 0.45, 0.08);
  const int index = renderer.addMovingSolid(can);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.5, 0.1, p.table.height + 0.23);
  renderer.setMovingPose(index, pose);
  bv::ObjectLocatorConfig config;
  config.shape = can;
  bv::ObjectLocator locator(config);
  const Eigen::Matrix3Xd none(3, 0);
  const Eigen::Matrix3Xi no_triangles(3, 0);
  std::mt19937 rng(kSeed);
  (void)renderer.render(none, no_triangles, rng);
  bv::ObjectMeasurement m;
  (void)locator.locate(renderer.bgr(), renderer.depth(), camera, m);  // its buffers, once
  const int stage = static_cast<int>(state.range(0));
  double error = 0.0;
  timeBatches(
      state, 1,
      [&](int) {
        if (stage == 0) {
          benchmark::DoNotOptimize(renderer.render(none, no_triangles, rng));
        } else if (stage == 1) {
          benchmark::DoNotOptimize(locator.locate(renderer.bgr(), renderer.depth(), camera, m));
          error = (m.position - pose.translation()).norm();
        } else {
          // The baseline: every pixel of the can's colour (the locator's mask) with a depth, averaged in the world.
          const cv::Mat& mask = locator.colourMask();
          Eigen::Vector3d sum = Eigen::Vector3d::Zero();
          int n = 0;
          for (int v = 0; v < mask.rows; ++v) {
            for (int u = 0; u < mask.cols; ++u) {
              const float z = renderer.depth().at<float>(v, u);
              if (mask.at<unsigned char>(v, u) == 0 || !std::isfinite(z)) continue;
              sum += camera.backProject(u, v, z);
              ++n;
            }
          }
          error = (sum / std::max(1, n) - pose.translation()).norm();
          benchmark::DoNotOptimize(sum);
        }
      },
      1);
  if (stage > 0) state.counters["error_mm"] = 1e3 * error;
}

/// The naive registration, DepthRegistration as it was before it kept its corners' rays: each pixel's four corners
/// back-projected through the depth intrinsics and turned by the 3 × 3 rotation, per frame.
void naiveRegistration(const cv::Mat& depth, const bv::PinholeCamera& d, const bv::PinholeCamera& c,
                       const Eigen::Isometry3d& colour_from_depth, cv::Mat& out) {
  const float far = std::numeric_limits<float>::infinity();
  out.create(c.height, c.width, CV_32FC1);
  out.setTo(far);
  const Eigen::Matrix3d r = colour_from_depth.linear();
  const Eigen::Vector3d t = colour_from_depth.translation();
  for (int v = 0; v < depth.rows; ++v) {
    const float* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const double z = row[u];
      if (!(z > 0.0) || !std::isfinite(z)) continue;
      double u_lo = std::numeric_limits<double>::infinity(), u_hi = -u_lo, v_lo = u_lo, v_hi = -u_lo, zc = 0.0;
      bool in_front = true;
      for (const double du : {-0.5, 0.5}) {
        for (const double dv : {-0.5, 0.5}) {
          const Eigen::Vector3d p = r * Eigen::Vector3d((u + du - d.cx) / d.fx * z, (v + dv - d.cy) / d.fy * z, z) + t;
          in_front = in_front && p.z() > 0.0;
          const double uc = c.fx * p.x() / p.z() + c.cx, vc = c.fy * p.y() / p.z() + c.cy;
          u_lo = std::min(u_lo, uc);
          u_hi = std::max(u_hi, uc);
          v_lo = std::min(v_lo, vc);
          v_hi = std::max(v_hi, vc);
          zc += 0.25 * p.z();
        }
      }
      if (!in_front) continue;
      const int c0 = std::max(0, static_cast<int>(std::ceil(u_lo - 1e-9))),
                c1 = std::min(c.width - 1, static_cast<int>(std::floor(u_hi + 1e-9)));
      const int r0 = std::max(0, static_cast<int>(std::ceil(v_lo - 1e-9))),
                r1 = std::min(c.height - 1, static_cast<int>(std::floor(v_hi + 1e-9)));
      if (c0 > c1 || r0 > r1) {
        const long cu = std::lround(0.5 * (u_lo + u_hi)), cv = std::lround(0.5 * (v_lo + v_hi));
        if (cu < 0 || cv < 0 || cu >= c.width || cv >= c.height) continue;
        float& cell = out.at<float>(static_cast<int>(cv), static_cast<int>(cu));
        cell = std::min(cell, static_cast<float>(zc));
        continue;
      }
      for (int rr = r0; rr <= r1; ++rr) {
        for (int cc = c0; cc <= c1; ++cc) out.at<float>(rr, cc) = std::min(out.at<float>(rr, cc), float(zc));
      }
    }
  }
  out.setTo(std::numeric_limits<float>::quiet_NaN(), out == far);
}

/// Reading a Kinect's raw frame (RawRgbdSensor at 640 × 480 over the tracking experiment's can, the arms' reading
/// in object_tracker and the learners' RgbdReader): args {stage: 0 the colour rectified, 1 the depth to metres and
/// rectified, 2 the depth registered into the colour camera, 3 its baseline (naiveRegistration)}. Counters: the
/// registered depth's largest difference from the baseline's where either has one [mm], and the pixels where only
/// one has.
void BM_RawRgbdReading(benchmark::State& state) {
  bv::ClothRendererParameters p = scene(320, 240);
  bv::RawRgbdSensorConfig config;
  config.colour = bv::PinholeCamera::lookingAt(Eigen::Vector3d(1.15, 0.0, p.table.height + 1.3),
                                               Eigen::Vector3d(0.5, 0.0, p.table.height));
  bv::RawRgbdSensor sensor(p, config);
  bv::SceneSolid can;
  can.shape = bv::SceneSolid::Shape::Cylinder;
  can.size = Eigen::Vector3d(0.033, 0.12, 0.0);
  can.colour = Eigen::Vector3d(0.95, 0.45, 0.08);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.5, 0.1, p.table.height + 0.23);
  sensor.setMovingPose(sensor.addMovingSolid(can), pose);
  std::mt19937 rng(kSeed);
  (void)sensor.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0), rng);
  const bv::Rectifier colour(sensor.colourCalibration()), depth(sensor.depthCalibration());
  const bv::PinholeCamera depth_camera = sensor.depthCalibration().rectifiedCamera(),
                          colour_camera = sensor.colourCalibration().rectifiedCamera();
  const bv::DepthRegistration registration(depth_camera, colour_camera, config.colour_from_depth);
  cv::Mat bgr, metres, rectified, registered, naive;
  (void)bv::depthToMetres(sensor.depthMillimetres(), true, metres);
  (void)depth.rectifyDepth(metres, rectified);
  const int stage = static_cast<int>(state.range(0));
  timeBatches(
      state, 1,
      [&](int) {
        if (stage == 0) {
          benchmark::DoNotOptimize(colour.rectifyColour(sensor.rawBgr(), bgr));
        } else if (stage == 1) {
          benchmark::DoNotOptimize(bv::depthToMetres(sensor.depthMillimetres(), true, metres));
          benchmark::DoNotOptimize(depth.rectifyDepth(metres, rectified));
        } else if (stage == 2) {
          benchmark::DoNotOptimize(registration.registerDepth(rectified, registered));
        } else {
          naiveRegistration(rectified, depth_camera, colour_camera, config.colour_from_depth, naive);
        }
        benchmark::DoNotOptimize(bgr.data);
      },
      1);
  if (stage >= 2) {
    (void)registration.registerDepth(rectified, registered);
    naiveRegistration(rectified, depth_camera, colour_camera, config.colour_from_depth, naive);
    double largest = 0.0;
    int one_only = 0;
    for (int v = 0; v < naive.rows; ++v) {
      for (int u = 0; u < naive.cols; ++u) {
        const float a = registered.at<float>(v, u), b = naive.at<float>(v, u);
        if (std::isfinite(a) != std::isfinite(b)) ++one_only;
        if (std::isfinite(a) && std::isfinite(b)) largest = std::max(largest, std::abs(double(a) - b));
      }
    }
    state.counters["vs_baseline_mm"] = 1e3 * largest;
    state.counters["vs_baseline_holes"] = one_only;
  }
}

/// The peer of the noise: the same per-pixel draws (depth and three colour channels) from std::normal_distribution
/// on the std::mt19937 itself.
void BM_NoiseWithStdNormal(benchmark::State& state) {
  const bv::ClothRendererParameters p = scene(columnsOf(state), rowsOf(state));
  cv::Mat depth(p.camera.rows, p.camera.columns, CV_32FC1, cv::Scalar(1.35));
  cv::Mat bgr(p.camera.rows, p.camera.columns, CV_8UC3, cv::Scalar(100, 150, 200));
  std::mt19937 rng(kSeed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  const float depth_sigma = float(p.noise.depth_stddev), colour_sigma = float(p.noise.colour_stddev);
  timeBatches(
      state, 1,
      [&](int) {
        for (int v = 0; v < depth.rows; ++v) {
          float* d = depth.ptr<float>(v);
          unsigned char* c = bgr.ptr<unsigned char>(v);
          for (int u = 0; u < depth.cols; ++u) {
            d[u] += depth_sigma * normal(rng);
            for (int k = 0; k < 3; ++k)
              c[3 * u + k] = cv::saturate_cast<unsigned char>(c[3 * u + k] + colour_sigma * normal(rng));
          }
        }
        benchmark::DoNotOptimize(depth.data);
      },
      1);
}

/// The other peer: the same noise from OpenCV's cv::RNG (Ziggurat normals) into preallocated noise images, added with
/// saturation by cv::add.
void BM_NoiseWithOpenCv(benchmark::State& state) {
  const bv::ClothRendererParameters p = scene(columnsOf(state), rowsOf(state));
  cv::Mat depth(p.camera.rows, p.camera.columns, CV_32FC1, cv::Scalar(1.35));
  cv::Mat bgr(p.camera.rows, p.camera.columns, CV_8UC3, cv::Scalar(100, 150, 200));
  cv::Mat depth_noise(depth.size(), CV_32FC1), colour_noise(bgr.size(), CV_32FC3);
  cv::RNG rng(kSeed);
  const double depth_sigma = p.noise.depth_stddev, colour_sigma = p.noise.colour_stddev;
  timeBatches(
      state, 1,
      [&](int) {
        rng.fill(depth_noise, cv::RNG::NORMAL, 0.0, depth_sigma);
        depth += depth_noise;
        rng.fill(colour_noise, cv::RNG::NORMAL, 0.0, colour_sigma);
        cv::add(bgr, colour_noise, bgr, cv::noArray(), CV_8UC3);
        benchmark::DoNotOptimize(depth.data);
        benchmark::DoNotOptimize(bgr.data);
      },
      1);
}

/// ImageReward::evaluate() on a noisy rendered frame: args {columns, folded}.
void BM_ImageReward(benchmark::State& state) {
  const bv::ClothRendererParameters p = scene(columnsOf(state), rowsOf(state));
  bv::ClothRenderer renderer(p);
  const bv::ClothMesh mesh = cloth(p, state.range(1) != 0);
  std::mt19937 rng(kSeed);
  renderer.render(mesh.vertices, mesh.triangles, rng);
  bv::ImageReward reward(p.camera, {});
  bv::ImageRewardTerms terms;
  timeBatches(
      state, 1,
      [&](int) {
        terms = reward.evaluate(renderer.bgr(), renderer.depth());
        benchmark::DoNotOptimize(terms);
      },
      1);
  state.counters["fill_ratio"] = terms.colour.fill_ratio;
  state.counters["mean_gradient"] = terms.depth.mean_gradient;
}

/// Writes flat_rgb.png, flat_depth.png, folded_rgb.png, folded_depth.png, crumpled_segmented.png (the colour image
/// with the minimum-area rectangle of the segmented cloth) and crumpled_depth.png at 320 × 240 with noise (seed 7),
/// and prints their reward terms.
int writeFigures() {
  const bv::ClothRendererParameters p = scene(320, 240);
  bv::ClothRenderer renderer(p);
  bv::ImageReward reward(p.camera, {});
  std::mt19937 rng(kSeed);
  std::printf("image,fill_ratio,mean_gradient,r_color,r_depth,vision_reward,area_ratio,aspect\n");
  for (const std::string name : {"flat", "folded", "crumpled"}) {
    const bv::ClothMesh mesh = name == "crumpled" ? bv::crumpleCloth(cloth(p, false), rng) : cloth(p, name == "folded");
    if (renderer.render(mesh.vertices, mesh.triangles, rng) != bv::VisionStatus::Ok) return 1;
    const bv::ImageRewardTerms terms = reward.evaluate(renderer.bgr(), renderer.depth());
    const bv::FoldFacts facts = reward.foldFacts(reward.mask(), 0.5 * 0.6);
    std::printf("%s,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.3f\n", name.c_str(), terms.colour.fill_ratio,
                terms.depth.mean_gradient, terms.r_color, terms.r_depth, terms.reward(), facts.area_ratio,
                facts.aspect);
    // Depth shown in a colour map from 1 cm below the table top (dark blue) to 5 cm above it (dark red).
    const double table_depth = p.camera.height - p.table.height;
    cv::Mat depth_view;
    renderer.depth().convertTo(depth_view, CV_8UC1, -255.0 / 0.06, 255.0 * (table_depth + 0.01) / 0.06);
    cv::applyColorMap(depth_view, depth_view, cv::COLORMAP_TURBO);
    bool written = cv::imwrite(name + "_depth.png", depth_view);
    if (name == "crumpled") {
      cv::Mat overlay = renderer.bgr().clone();
      cv::Point2f corners[4];
      terms.colour.rectangle.points(corners);
      for (int k = 0; k < 4; ++k) cv::line(overlay, corners[k], corners[(k + 1) % 4], cv::Scalar(0, 0, 255), 1);
      written = written && cv::imwrite(name + "_segmented.png", overlay);
    } else {
      written = written && cv::imwrite(name + "_rgb.png", renderer.bgr());
    }
    if (!written) {
      std::fprintf(stderr, "vision_bench: could not write the %s images\n", name.c_str());
      return 1;
    }
  }
  return 0;
}

}  // namespace

BENCHMARK(BM_Render)
    ->ArgsProduct({{320, 640}, {0, 1}, {0, 1}})
    ->ArgNames({"columns", "folded", "noise"})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PerspectiveCamera)
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->ArgNames({"folded", "reproject"})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_TrackingFrame)->DenseRange(0, 2)->ArgName("stage")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RawRgbdReading)->DenseRange(0, 3)->ArgName("stage")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NoiseWithStdNormal)->Arg(320)->Arg(640)->ArgName("columns")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NoiseWithOpenCv)->Arg(320)->Arg(640)->ArgName("columns")->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ImageReward)
    ->ArgsProduct({{320, 640}, {0, 1}})
    ->ArgNames({"columns", "folded"})
    ->Unit(benchmark::kMicrosecond);

int main(int argc, char** argv) {
  const std::vector<bool> given = bimanual_skills::bench::initialiseBenchmarks(
      argc, argv, "vision_bench",
      "Rendering of the 20 x 24-node cloth (flat, folded) at 320 x 240 and 640 x 480, with and without noise, its "
      "std::normal_distribution and cv::RNG peers of its noise, and the reward's image terms, per call.",
      {{"--figures", "write the flat and folded cloth's colour and depth images (PNG) into the current directory"}});
  if (given[0]) return writeFigures();
  benchmark::AddCustomContext("cloth", "0.5 x 0.6 m, 20 x 24 nodes, 874 triangles; noise seed 7");
  benchmark::AddCustomContext("camera", "top-down orthographic, 1 m of table across the image");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
