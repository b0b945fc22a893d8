#include "bimanual_skills/tracking/object_tracker.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace bimanual_skills::tracking {

namespace {

/// A stamp this far before the last frame's is a clock that went back (a simulation reset), not a late frame [s].
constexpr double kClockJump = 1.0;

}  // namespace

const char* toString(TrackReason reason) noexcept {
  switch (reason) {
    case TrackReason::Tracking:
      return "Tracking";
    case TrackReason::NeverSeen:
      return "NeverSeen";
    case TrackReason::NotSeen:
      return "NotSeen";
    case TrackReason::Jumped:
      return "Jumped";
    case TrackReason::CameraStopped:
      return "CameraStopped";
    case TrackReason::BadFrame:
      return "BadFrame";
  }
  return "Unknown";
}

void ObjectTrackerConfig::validate(const char* where) const {
  locator.validate(where);
  if (!filter.valid()) {
    throw std::invalid_argument(std::string(where) +
                                ": the filter's acceleration_noise, initial_speed, gate and lost_after must be finite "
                                "and > 0, reject_limit >= 1");
  }
  if (!(camera_timeout > 0.0 && camera_timeout <= 60.0)) {
    throw std::invalid_argument(std::string(where) + ": camera_timeout must lie in (0, 60] s");
  }
}

ObjectTracker::ObjectTracker(const ObjectTrackerConfig& config)
    : config_((config.validate("object tracker"), config)), locator_(config.locator), filter_(config.filter) {}

const TrackedState& ObjectTracker::frame(double t, const cv::Mat& bgr, const cv::Mat& depth,
                                         const vision::PinholeCamera& camera, const vision::PinholeCamera* depth_view) {
  if (!std::isfinite(t)) {
    ++state_.dropped;
    return state_;
  }
  if (t < last_frame_ - kClockJump) {  // the clock went back: a new timeline
    const TrackedState counts = state_;
    filter_.reset();
    state_ = TrackedState{};
    state_.frames = counts.frames, state_.measured = counts.measured, state_.accepted = counts.accepted;
    state_.rejected = counts.rejected, state_.dropped = counts.dropped;
    jumped_ = false;
  } else if (t <= last_frame_) {  // a duplicate or reordered frame
    ++state_.dropped;
    return state_;
  }
  last_frame_ = t;
  state_.last_frame = t;
  ++state_.frames;
  state_.located = locator_.locate(bgr, depth, camera, state_.measurement, depth_view);
  state_.update = signal::TargetTracker::Update::Invalid;
  if (state_.located == vision::LocateStatus::Ok) {
    ++state_.measured;
    state_.update = filter_.update(t, state_.measurement.position, state_.measurement.covariance);
    switch (state_.update) {
      case signal::TargetTracker::Update::Started:
      case signal::TargetTracker::Update::Accepted:
        ++state_.accepted;
        state_.last_accepted = t;
        jumped_ = false;
        break;
      case signal::TargetTracker::Update::Rejected:
        ++state_.rejected;
        jumped_ = !filter_.tracking(t);
        break;
      case signal::TargetTracker::Update::Invalid:
        break;
    }
  }
  estimate(t, state_);
  return state_;
}

void ObjectTracker::estimate(double t, TrackedState& state) const {
  state.time = t;
  Eigen::Vector3d position, velocity;
  Eigen::Matrix3d covariance;
  state.tracking = t - last_frame_ <= config_.camera_timeout && filter_.predict(t, position, velocity, covariance);
  if (state.tracking) {
    state.reason = TrackReason::Tracking;
    state.position = position;
    state.velocity = velocity;
    state.covariance = covariance;
    return;
  }
  state.velocity.setZero();
  if (state.last_accepted < 0.0) {
    state.reason = TrackReason::NeverSeen;
  } else if (t - last_frame_ > config_.camera_timeout) {
    state.reason = TrackReason::CameraStopped;
  } else if (state.located == vision::LocateStatus::WrongImage || state.located == vision::LocateStatus::BadCamera) {
    state.reason = TrackReason::BadFrame;
  } else {
    state.reason = jumped_ ? TrackReason::Jumped : TrackReason::NotSeen;
  }
}

TrackedState ObjectTracker::at(double t) const {
  TrackedState state = state_;
  estimate(std::max(t, last_frame_), state);
  return state;
}

std::string ObjectTracker::describe(const TrackedState& state) {
  char text[200];
  const double since = state.time - state.last_accepted;
  switch (state.reason) {
    case TrackReason::Tracking:
      return "tracking";
    case TrackReason::NeverSeen:
      std::snprintf(text, sizeof text, "not tracking: the object was never seen (last frame: %s)",
                    vision::toString(state.located));
      return text;
    case TrackReason::NotSeen:
      std::snprintf(text, sizeof text, "lost: not seen for %.2f s (last frame: %s)", since,
                    vision::toString(state.located));
      return text;
    case TrackReason::Jumped:
      return "lost: it jumped (its measurements fell outside the filter's gate, reject_limit in a row)";
    case TrackReason::CameraStopped:
      std::snprintf(text, sizeof text, "lost: no camera frame for %.2f s", state.time - state.last_frame);
      return text;
    case TrackReason::BadFrame:
      std::snprintf(text, sizeof text, "lost: the last frame could not be used (%s)", vision::toString(state.located));
      return text;
  }
  return "unknown";
}

}  // namespace bimanual_skills::tracking
