#include "bimanual_skills/primitives/demonstration_recorder.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bimanual_skills::primitives {

DemonstrationRecorder::DemonstrationRecorder(int tools) : tools_(tools) {
  if (tools < 1) throw std::invalid_argument("DemonstrationRecorder: needs at least one tool");
}

bool DemonstrationRecorder::add(double t, const std::vector<Pose>& poses) {
  if (!std::isfinite(t) || (!times_.empty() && !(t > times_.back())) || static_cast<int>(poses.size()) != tools_) {
    return false;
  }
  std::vector<Pose> sample = poses;
  for (Pose& p : sample) {
    const double norm = p.orientation.norm();
    if (!p.position.allFinite() || !p.orientation.coeffs().allFinite() || std::abs(norm - 1.0) > 1e-3) return false;
    p.orientation.normalize();
  }
  times_.push_back(t);
  poses_.push_back(std::move(sample));
  return true;
}

void DemonstrationRecorder::clear() noexcept {
  times_.clear();
  poses_.clear();
}

namespace {

/// Whether `a` and `b` differ by more than `still` [m] in position or 10 · `still` [rad] in orientation.
bool moved(const Pose& a, const Pose& b, double still) {
  return (a.position - b.position).norm() > still || a.orientation.angularDistance(b.orientation) > 10.0 * still;
}

}  // namespace

std::vector<std::vector<Pose>> DemonstrationRecorder::resampled(double dt, double still) const {
  if (!(dt > 0.0) || !(still >= 0.0)) throw std::invalid_argument("DemonstrationRecorder: dt > 0 and still >= 0");
  const auto n = times_.size();
  std::size_t first = n, last = 0;
  for (std::size_t k = 0; k < n; ++k) {
    for (int tool = 0; tool < tools_; ++tool) {
      const auto i = static_cast<std::size_t>(tool);
      if (first == n && moved(poses_[k][i], poses_.front()[i], still)) first = k;
      if (moved(poses_[k][i], poses_.back()[i], still)) last = k + 1;
    }
  }
  // The movement from the last still sample before the first that moved to the first still one after it.
  const std::size_t begin = first == n ? 0 : (first > 0 ? first - 1 : 0), end = std::min(last, n - 1);
  const double t0 = n > 0 ? times_[begin] : 0.0, t1 = n > 0 ? times_[end] : 0.0;
  const int count = first == n ? 0 : static_cast<int>(std::floor((t1 - t0) / dt + 1e-9)) + 1;
  if (count < 10) {
    throw std::invalid_argument("DemonstrationRecorder: the tools moved for less than 10 samples of " +
                                std::to_string(dt) + " s: nothing was taught");
  }
  std::vector<std::vector<Pose>> out(static_cast<std::size_t>(tools_));
  std::size_t k = begin;
  for (int s = 0; s < count; ++s) {
    const double t = t0 + s * dt;
    while (k + 1 < end && times_[k + 1] <= t) ++k;
    const double span = times_[k + 1] - times_[k], a = std::clamp((t - times_[k]) / span, 0.0, 1.0);
    for (int tool = 0; tool < tools_; ++tool) {
      const auto i = static_cast<std::size_t>(tool);
      const Pose &p = poses_[k][i], &q = poses_[k + 1][i];
      Pose pose;
      pose.position = (1.0 - a) * p.position + a * q.position;
      pose.orientation = p.orientation.slerp(a, q.orientation).normalized();
      out[i].push_back(pose);
    }
  }
  return out;
}

std::vector<CartesianDmp> DemonstrationRecorder::fit(const DmpParameters& parameters, double dt, double still,
                                                     double smoothing_hz) const {
  std::vector<CartesianDmp> out;
  for (const std::vector<Pose>& path : resampled(dt, still)) {
    out.push_back(CartesianDmp::fit(parameters, OrientationEncoding::QuaternionVector, path, dt, smoothing_hz));
  }
  return out;
}

}  // namespace bimanual_skills::primitives
