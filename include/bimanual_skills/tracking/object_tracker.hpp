/// \file
/// The tracked object of the tracking experiment (thesis Sec. 4.3.2, Fig. 4.10): each RGB-D frame's measurement of
/// the object's centre (vision::ObjectLocator) filtered by a constant-velocity Kalman filter (signal::TargetTracker),
/// with the reason whenever it is not tracked: never seen, not seen for a while, a jump the gate rejected, a camera
/// that stopped sending frames, a frame that could not be used. Frames arrive on the camera's clock (their stamps):
/// a duplicate or reordered frame is dropped; a stamp more than a second before the last one (the clock went back,
/// a simulation reset) starts over. What object_tracker runs between its subscriber and its publishers.
#pragma once

#include "bimanual_skills/signal/target_tracker.hpp"
#include "bimanual_skills/vision/object_locator.hpp"

#include <Eigen/Core>

#include <string>

namespace bimanual_skills::tracking {

struct ObjectTrackerConfig {
  vision::ObjectLocatorConfig locator;
  signal::TargetTrackerConfig filter;
  /// [s] of the camera's clock without a frame after which the camera counts as stopped (the target as lost).
  double camera_timeout = 0.5;

  /// \throws std::invalid_argument naming `where` and the entry out of range.
  void validate(const char* where) const;
};

/// Why the object is or is not tracked.
enum class TrackReason {
  Tracking,       ///< Measured within the filter's gate recently.
  NeverSeen,      ///< No measurement yet (or since the clock went back).
  NotSeen,        ///< Lost: no measurement accepted for the filter's lost_after (out of view, hidden, no depth).
  Jumped,         ///< Lost: reject_limit measurements in a row outside the gate (it moved elsewhere at once).
  CameraStopped,  ///< Lost: no frame for camera_timeout.
  BadFrame,       ///< The last frame could not be used (wrong encoding or size, a camera pose that is not rigid).
};
const char* toString(TrackReason reason) noexcept;

struct TrackedState {
  double time = 0.0;  ///< The estimate's time: the last frame's stamp, or the time at() was asked for [s].
  bool tracking = false;
  TrackReason reason = TrackReason::NeverSeen;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< Filtered centre (world) [m]; the last one when lost.
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< [m/s]; zero when lost.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double last_accepted = -1.0;  ///< Stamp of the last accepted measurement (−1: none).
  double last_frame = -1.0;     ///< Stamp of the last frame (−1: none).
  vision::LocateStatus located = vision::LocateStatus::NotSeen;                   ///< What the last frame gave.
  signal::TargetTracker::Update update = signal::TargetTracker::Update::Invalid;  ///< What the filter made of it.
  vision::ObjectMeasurement measurement;  ///< The last frame's measurement (when located is Ok).
  long frames = 0, measured = 0, accepted = 0, rejected = 0, dropped = 0;  ///< Counts since the start.
};

class ObjectTracker {
 public:
  /// \throws std::invalid_argument for an invalid config.
  explicit ObjectTracker(const ObjectTrackerConfig& config);

  /// One frame stamped `t` [s]: colour (bgr8) and registered depth (32FC1, metres) seen by `camera` (its pose in
  /// the world at `t`); `depth_view`, the depth camera when its depth was registered here
  /// (vision::ObjectLocator::locate).
  const TrackedState& frame(double t, const cv::Mat& bgr, const cv::Mat& depth, const vision::PinholeCamera& camera,
                            const vision::PinholeCamera* depth_view = nullptr);
  /// The estimate predicted to `t` (≥ the last frame's stamp) without a new frame: lost with CameraStopped once the
  /// last frame is older than camera_timeout.
  TrackedState at(double t) const;
  const TrackedState& last() const noexcept { return state_; }
  /// A sentence for a person: "tracking", "lost: not seen for 0.62 s (NotSeen)", "lost: no camera frame for 0.71 s".
  static std::string describe(const TrackedState& state);

  const vision::ObjectLocator& locator() const noexcept { return locator_; }
  const ObjectTrackerConfig& config() const noexcept { return config_; }

 private:
  /// Fills the filter's estimate at `t` into `state` (tracking or the reason it is lost).
  void estimate(double t, TrackedState& state) const;

  ObjectTrackerConfig config_;
  vision::ObjectLocator locator_;
  signal::TargetTracker filter_;
  TrackedState state_;
  double last_frame_ = -1e300;
  bool jumped_ = false;  ///< The track was lost by rejections in a row.
};

}  // namespace bimanual_skills::tracking
