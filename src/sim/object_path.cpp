#include "bimanual_skills/sim/object_path.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace bimanual_skills::sim {

namespace {

constexpr double kPeakSpeed = 1.875;          ///< max s'(τ) of the minimum-jerk profile.
constexpr double kPeakAcceleration = 5.7736;  ///< max |s''(τ)| = 10/√3 (rounded up).

/// The time a rest-to-rest move of `distance` needs at peak speed `speed` within the acceleration bound.
double moveTime(double distance, double speed, double acceleration) {
  return std::max(kPeakSpeed * distance / speed, std::sqrt(kPeakAcceleration * distance / acceleration));
}

}  // namespace

void ObjectPathConfig::validate(const std::string& where) const {
  const auto fail = [&](const std::string& what) { throw std::invalid_argument(where + ": " + what); };
  if (!centre.allFinite() || centre.cwiseAbs().maxCoeff() > 100.0) fail("'centre' must be finite, within 100 m");
  if (!size.allFinite() || (size.array() < 0.0).any() || size.maxCoeff() > 10.0) {
    fail("'size' must be three extents in [0, 10] m");
  }
  if (!(max_speed > 0.0 && max_speed <= 5.0)) fail("'max_speed' must lie in (0, 5] m/s");
  if (!(max_acceleration > 0.0 && max_acceleration <= 50.0)) fail("'max_acceleration' must lie in (0, 50] m/s^2");
  if (!(min_speed_ratio > 0.0 && min_speed_ratio <= 1.0)) fail("'min_speed_ratio' must lie in (0, 1]");
  if (!(pause_probability >= 0.0 && pause_probability <= 1.0)) fail("'pause_probability' must lie in [0, 1]");
  if (!pause.allFinite() || !(pause[0] > 0.0) || pause[1] < pause[0] || pause[1] > 600.0) {
    fail("'pause' must be a range [min, max] of seconds with 0 < min <= max <= 600");
  }
  if (!(away_probability >= 0.0 && away_probability <= 1.0)) fail("'away_probability' must lie in [0, 1]");
  if (!away.allFinite() || away.norm() > 10.0) fail("'away' must be finite, at most 10 m from the centre");
  if (!(start_pause >= 0.0 && start_pause <= 600.0)) fail("'start_pause' must lie in [0, 600] s");
  if (!(duration > 0.0 && duration <= 3600.0)) fail("'duration' must lie in (0, 3600] s");
}

ObjectPath::ObjectPath(const ObjectPathConfig& config) : config_(config) {
  config_.validate("object path");
  std::mt19937 rng(config_.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double t = 0.0;
  Eigen::Vector3d here = config_.centre;
  const auto add = [&](const Eigen::Vector3d& to, double length, bool away) {
    segments_.push_back(Segment{t, length, here, to, away});
    t += length;
    here = to;
  };
  const auto rest = [&](double length, bool away) {
    if (length > 0.0) add(here, length, away);
  };
  // A move within the region at a speed of its own; a trip out of view and back at full speed (the person walks off).
  const auto move = [&](const Eigen::Vector3d& to, bool away) {
    const double distance = (to - here).norm();
    if (distance < 1e-9) return;
    const double ratio = config_.min_speed_ratio + (1.0 - config_.min_speed_ratio) * unit(rng);
    const double speed = config_.max_speed * (away ? 1.0 : ratio);
    add(to, moveTime(distance, speed, config_.max_acceleration), away);
  };
  const auto pauseLength = [&] { return config_.pause[0] + (config_.pause[1] - config_.pause[0]) * unit(rng); };
  rest(config_.start_pause, false);
  while (t < config_.duration) {
    const double before = t;
    if (unit(rng) < config_.away_probability) {
      const Eigen::Vector3d back = here;
      move(config_.centre + config_.away, true);
      rest(pauseLength(), true);
      move(back, true);
      continue;
    }
    Eigen::Vector3d to;
    for (int i = 0; i < 3; ++i) to[i] = config_.centre[i] + config_.size[i] * (unit(rng) - 0.5);
    move(to, false);
    if (unit(rng) < config_.pause_probability) rest(pauseLength(), false);
    if (t == before) rest(1.0, false);  // a region of no extent: the object only rests
  }
}

ObjectPathSample ObjectPath::at(double t) const noexcept {
  ObjectPathSample sample;
  const Segment* segment = &segments_.front();
  if (t >= end()) {
    sample.position = segments_.back().to;
    sample.away = segments_.back().away;
    return sample;
  }
  if (t > 0.0) {
    // The last segment that starts at or before t.
    const auto next = std::upper_bound(segments_.begin(), segments_.end(), t,
                                       [](double time, const Segment& s) { return time < s.start; });
    segment = &*(next - 1);
  }
  const double length = segment->length;
  const double tau = std::clamp((t - segment->start) / length, 0.0, 1.0);
  const double tau2 = tau * tau, tau3 = tau2 * tau;
  const double s = tau3 * (10.0 - 15.0 * tau + 6.0 * tau2);
  const double ds = 30.0 * tau2 * (1.0 - 2.0 * tau + tau2) / length;
  const double dds = 60.0 * tau * (1.0 - 3.0 * tau + 2.0 * tau2) / (length * length);
  const Eigen::Vector3d d = segment->to - segment->from;
  sample.position = segment->from + s * d;
  sample.velocity = ds * d;
  sample.acceleration = dds * d;
  sample.away = segment->away;
  return sample;
}

}  // namespace bimanual_skills::sim
