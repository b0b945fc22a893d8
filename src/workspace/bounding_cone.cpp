#include "bimanual_skills/workspace/bounding_cone.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace bimanual_skills::workspace {

namespace {

/// Containment tolerance on cosines inside the algorithms (the directions are unit vectors).
constexpr double kCosineTolerance = 1e-12;

std::vector<Eigen::Vector3d> normalised(const std::vector<Eigen::Vector3d>& directions) {
  if (directions.empty()) throw std::invalid_argument("bounding cone: no directions");
  std::vector<Eigen::Vector3d> out;
  out.reserve(directions.size());
  for (const Eigen::Vector3d& d : directions) {
    const double n = d.norm();
    if (!std::isfinite(n) || n == 0.0) throw std::invalid_argument("bounding cone: a zero or non-finite direction");
    out.push_back(d / n);
  }
  return out;
}

/// A cone given by its axis and the cosine of its half-angle.
struct Cap {
  Eigen::Vector3d axis;
  double cosine;
  bool holds(const Eigen::Vector3d& p) const { return axis.dot(p) >= cosine - kCosineTolerance; }
};

Cap through(const Eigen::Vector3d& p) {
  return {p, 1.0};
}

/// The smallest cone with p and q on its boundary.
Cap through(const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
  Eigen::Vector3d m = p + q;
  if (m.norm() < 1e-12) {  // opposite: any axis perpendicular to them, a half-space
    m = p.unitOrthogonal();
    return {m, 0.0};
  }
  m.normalize();
  return {m, std::min(1.0, m.dot(p))};
}

/// The cone with a, b and c on its boundary around the normal of their plane that points to them (the smaller of
/// the two; `opposite`: the larger, around the other normal).
Cap through(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, bool opposite = false) {
  Eigen::Vector3d n = (b - a).cross(c - a);
  if (n.norm() < 1e-15) {  // collinear on the sphere: the same great or small circle through two of them
    Cap best = through(a, b);
    for (const Cap& cap : {through(a, c), through(b, c)}) {
      if (cap.cosine < best.cosine) best = cap;
    }
    return best;
  }
  n.normalize();
  if (n.dot(a) < 0.0) n = -n;
  if (opposite) n = -n;
  return {n, std::clamp(n.dot(a), -1.0, 1.0)};
}

BoundingCone toCone(const Cap& cap) {
  BoundingCone cone;
  cone.axis = cap.axis;
  cone.angle = std::acos(std::clamp(cap.cosine, -1.0, 1.0));
  return cone;
}

bool holdsAll(const Cap& cap, const std::vector<Eigen::Vector3d>& p) {
  return std::all_of(p.begin(), p.end(), [&](const Eigen::Vector3d& v) { return cap.holds(v); });
}

}  // namespace

bool BoundingCone::contains(const Eigen::Vector3d& v, double tolerance) const {
  const double n = v.norm();
  if (!(n > 0.0)) return false;
  return std::acos(std::clamp(axis.dot(v) / n, -1.0, 1.0)) <= angle + tolerance;
}

namespace {

Cap welzl(std::vector<Eigen::Vector3d> p, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::shuffle(p.begin(), p.end(), rng);
  // Welzl's algorithm, iterative form: each direction outside the current cone is on the boundary of the cone of
  // the directions seen so far.
  Cap cap = through(p[0]);
  for (std::size_t i = 1; i < p.size(); ++i) {
    if (cap.holds(p[i])) continue;
    cap = through(p[i]);
    for (std::size_t j = 0; j < i; ++j) {
      if (cap.holds(p[j])) continue;
      cap = through(p[i], p[j]);
      for (std::size_t k = 0; k < j; ++k) {
        if (!cap.holds(p[k])) cap = through(p[i], p[j], p[k]);
      }
    }
  }
  return cap;
}

}  // namespace

BoundingCone welzlBoundingCone(const std::vector<Eigen::Vector3d>& directions, std::uint32_t seed) {
  return toCone(welzl(normalised(directions), seed));
}

BoundingCone minimalBoundingCone(const std::vector<Eigen::Vector3d>& directions, std::uint32_t seed) {
  const std::vector<Eigen::Vector3d> p = normalised(directions);
  const Cap cap = welzl(p, seed);
  // Valid when the directions lie in an open hemisphere; otherwise (a cone of 90° or more) try every cone.
  if (cap.cosine > kCosineTolerance && holdsAll(cap, p)) return toCone(cap);
  return bruteForceBoundingCone(p);
}

BoundingCone bruteForceBoundingCone(const std::vector<Eigen::Vector3d>& directions) {
  const std::vector<Eigen::Vector3d> p = normalised(directions);
  Cap best{Eigen::Vector3d::UnitZ(), -1.0};  // the whole sphere
  const auto consider = [&](const Cap& cap) {
    if (cap.cosine > best.cosine && holdsAll(cap, p)) best = cap;
  };
  const std::size_t n = p.size();
  for (std::size_t i = 0; i < n; ++i) {
    consider(through(p[i]));
    for (std::size_t j = i + 1; j < n; ++j) {
      consider(through(p[i], p[j]));
      for (std::size_t k = j + 1; k < n; ++k) {
        consider(through(p[i], p[j], p[k]));
        consider(through(p[i], p[j], p[k], true));
      }
    }
  }
  return toCone(best);
}

}  // namespace bimanual_skills::workspace
