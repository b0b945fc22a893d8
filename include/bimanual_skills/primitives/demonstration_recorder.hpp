/// \file
/// A kinesthetic demonstration of several tools as it is taught (a person moving arms in gravity compensation, or
/// guiding them by teleoperation): time-stamped tool poses in, one Cartesian DMP per tool out, the files a learner
/// starts from (tasks::ClothFoldConfig::demonstration_files). The still parts before the first and after the last
/// movement are trimmed, the rest resampled on a uniform grid (positions linearly, orientations by slerp) and each
/// tool's path fitted by CartesianDmp::fit (thesis Sec. 5.2, quaternion-vector encoding of Sec. 7.2.3).
/// Offline (allocates, throws std::invalid_argument).
#pragma once

#include "bimanual_skills/primitives/cartesian_dmp.hpp"

#include <vector>

namespace bimanual_skills::primitives {

class DemonstrationRecorder {
 public:
  /// \throws std::invalid_argument for tools < 1.
  explicit DemonstrationRecorder(int tools);

  int tools() const noexcept { return tools_; }
  int samples() const noexcept { return static_cast<int>(times_.size()); }
  /// Seconds from the first sample to the last (0 with fewer than two).
  double duration() const noexcept { return times_.empty() ? 0.0 : times_.back() - times_.front(); }

  /// Appends every tool's pose at time `t` [s]. False (nothing recorded) for a time not after the last sample's
  /// (a stale, duplicate or reordered message), a wrong number of poses, non-finite values or a quaternion whose norm
  /// is not 1 within 1e-3 (normalised when it is).
  bool add(double t, const std::vector<Pose>& poses);
  void clear() noexcept;

  /// The samples from the first at which any tool has moved more than `still` [m] from its first position (or
  /// turned more than 10 · `still` rad) to the last at which any tool moves that much from its final pose, resampled
  /// every `dt` [s]: one path per tool, all of the same length. \throws std::invalid_argument for dt ≤ 0, still < 0,
  /// or fewer than 10 resampled poses (nothing taught).
  std::vector<std::vector<Pose>> resampled(double dt, double still) const;

  /// One quaternion-vector Cartesian DMP per tool of `parameters`' kernels, fitted to resampled(dt, still) with the
  /// fit's low-pass at `smoothing_hz`; each DMP's duration is the taught movement's. \throws as resampled() and
  /// CartesianDmp::fit.
  std::vector<CartesianDmp> fit(const DmpParameters& parameters, double dt, double still,
                                double smoothing_hz = 20.0) const;

 private:
  int tools_;
  std::vector<double> times_;
  std::vector<std::vector<Pose>> poses_;  ///< Per sample, one pose per tool.
};

}  // namespace bimanual_skills::primitives
