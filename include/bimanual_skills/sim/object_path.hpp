/// \file
/// The path of an object a person carries about the table for the arm to track (thesis Sec. 4.3.2): seeded random
/// moves between points of a region, each at its own speed (slow ones and fast ones), pauses, and now and then a
/// trip out of the camera's view and back. Every move is a minimum-jerk segment from rest to rest (Flash & Hogan
/// 1985), p(t) = a + (b − a) s(τ), s = 10τ³ − 15τ⁴ + 6τ⁵, τ = t/T, whose peak speed 1.875 |b − a|/T and peak
/// acceleration (10/√3) |b − a|/T² are kept under the bounds by the choice of T: the path's speed and acceleration
/// never exceed them and are continuous. at() is real-time safe.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace bimanual_skills::sim {

struct ObjectPathConfig {
  Eigen::Vector3d centre = Eigen::Vector3d(0.55, 0.0, 0.95);  ///< Centre of the region moves go to (world) [m].
  Eigen::Vector3d size = Eigen::Vector3d(0.3, 0.5, 0.2);      ///< Its full extents [m].
  double max_speed = 0.2;                                     ///< [m/s].
  double max_acceleration = 0.5;                              ///< [m/s²].
  /// Each move's peak speed is drawn uniformly from [min_speed_ratio, 1] × max_speed (within the acceleration bound).
  double min_speed_ratio = 0.3;
  double pause_probability = 0.3;                         ///< After each move, a pause with this probability...
  Eigen::Vector2d pause = Eigen::Vector2d(0.5, 2);        ///< ...of a duration drawn from this range [s].
  double away_probability = 0.1;                          ///< Each move goes out of view with this probability...
  Eigen::Vector3d away = Eigen::Vector3d(0.0, 0.9, 0.0);  ///< ...to centre + away (stays there a pause, comes back).
  double start_pause = 2.0;                               ///< The object rests at the centre this long first [s].
  double duration = 60.0;                                 ///< Moves are drawn until this time; then it rests [s].
  std::uint32_t seed = 1;

  /// \throws std::invalid_argument naming `where` and the entry out of range.
  void validate(const std::string& where) const;
};

/// Where the object is at a time, and what it is doing.
struct ObjectPathSample {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();      ///< [m].
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      ///< [m/s].
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();  ///< [m/s²].
  bool away = false;  ///< Out of the region (gone to centre + away, or on its way there or back).
};

class ObjectPath {
 public:
  /// One segment of the path: a move from `from` to `to` over [start, start + length), a rest when they coincide.
  struct Segment {
    double start = 0.0, length = 0.0;
    Eigen::Vector3d from = Eigen::Vector3d::Zero(), to = Eigen::Vector3d::Zero();
    bool away = false;
  };

  /// Draws the path of `config` from its seed. \throws std::invalid_argument for an invalid config.
  explicit ObjectPath(const ObjectPathConfig& config);

  /// The object at time `t` [s] (before 0: at the start; after the end: resting where it ended). Real-time safe.
  ObjectPathSample at(double t) const noexcept;
  /// When the drawn moves end (≥ config.duration) [s].
  double end() const noexcept { return segments_.back().start + segments_.back().length; }
  const std::vector<Segment>& segments() const noexcept { return segments_; }
  const ObjectPathConfig& config() const noexcept { return config_; }

 private:
  ObjectPathConfig config_;
  std::vector<Segment> segments_;
};

}  // namespace bimanual_skills::sim
