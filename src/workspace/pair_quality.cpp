#include "bimanual_skills/workspace/pair_quality.hpp"

#include "bimanual_skills/parallel/parallel_for.hpp"
#include "bimanual_skills/realtime/clock.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <unordered_set>

namespace bimanual_skills::workspace {

namespace {

/// A point ready for pairs: world position, unit cone axis, cone angle and its cosine, and the product of the
/// per-point factors r · m̄ / κ̄ (SDF, MF and CF are products over the two points).
struct Prepared {
  Eigen::Vector3d position;
  Eigen::Vector3d axis;
  double angle = 0.0;
  double inverse_angle = 0.0;  ///< 1/α (0 for a cone of no width, which no direction is inside).
  double cos_angle = 1.0;
  double ratio = 0.0, manipulability = 0.0, inverse_condition = 0.0;
  double weight = 0.0;  ///< r · m̄ / κ̄: the point's part of SDF · MF · CF.
};

Prepared prepare(const WorkspacePoint& p) {
  Prepared out;
  out.position = p.position;
  out.axis = p.tool.axis.normalized();
  out.angle = p.tool.angle;
  out.inverse_angle = p.tool.angle > 0.0 ? 1.0 / p.tool.angle : 0.0;
  out.cos_angle = std::cos(p.tool.angle);
  out.ratio = p.solution_ratio;
  out.manipulability = p.manipulability;
  out.inverse_condition = 1.0 / p.condition;
  out.weight = out.ratio * out.manipulability * out.inverse_condition;
  return out;
}

/// acos(x) for x in [−1, 1] within 2e-8 rad (Abramowitz & Stegun 4.4.46), several times cheaper than std::acos;
/// the pair sum calls it twice for each of tens of millions of pairs.
double fastAcos(double x) {
  const double y = std::min(std::abs(x), 1.0);
  const double p =
      1.5707963050 +
      y * (-0.2145988016 +
           y * (0.0889789874 + y * (-0.0501743046 +
                                    y * (0.0308918810 + y * (-0.0170881256 + y * (0.0066700901 - y * 0.0012624911))))));
  const double a = std::sqrt(1.0 - y) * p;
  return x >= 0.0 ? a : M_PI - a;
}

/// F(P1, P2) with `d` = P2 − P1 and `distance` = |d| already known to be within L ± δ. DF's cone test compares
/// cosines (c_i > cos α_i ⇔ a_i < α_i); the angles a_i that OF needs come from fastAcos.
PairFactors evaluate(const Prepared& p1, const Prepared& p2, const Eigen::Vector3d& d, double distance,
                     const PairQualitySettings& s) {
  PairFactors f;
  const double inverse_distance = 1.0 / distance;
  const double c1 = p1.axis.dot(d) * inverse_distance, c2 = -p2.axis.dot(d) * inverse_distance;
  if (!(c1 > p1.cos_angle && c2 > p2.cos_angle)) return f;
  f.a1 = fastAcos(c1);
  f.a2 = fastAcos(c2);
  f.df = 1.0;
  f.sdf = p1.ratio * p2.ratio;
  const double room =
      std::max(0.0, (p1.angle - f.a1) * p1.inverse_angle) * std::max(0.0, (p2.angle - f.a2) * p2.inverse_angle);
  f.of = room > 0.0 ? std::max(s.of_min, 1.0 + std::log(room) / s.k) : s.of_min;
  f.mf = p1.manipulability * p2.manipulability;
  f.cf = p1.inverse_condition * p2.inverse_condition;
  return f;
}

/// The second arm's points in cell order, one array per field, for the vectorised pair loop.
struct Columns {
  std::vector<double> x, y, z, ax, ay, az, cos_angle, angle, inverse_angle, weight;

  /// `points` in the order of the indices `order`.
  Columns(const std::vector<Prepared>& points, const std::vector<std::size_t>& order) {
    for (const std::size_t i : order) {
      const Prepared& p = points[i];
      x.push_back(p.position.x());
      y.push_back(p.position.y());
      z.push_back(p.position.z());
      ax.push_back(p.axis.x());
      ay.push_back(p.axis.y());
      az.push_back(p.axis.z());
      cos_angle.push_back(p.cos_angle);
      angle.push_back(p.angle);
      inverse_angle.push_back(p.inverse_angle);
      weight.push_back(p.weight);
    }
  }
};

/// ln x for x > 0 without branches, so that the pair loop vectorises: x = 2^e · m with m in [√½, √2), and
/// ln m = 2 atanh(s), s = (m − 1)/(m + 1), |s| ≤ 0.172, by its series to s¹⁹ (relative error below 1e-15).
inline double branchFreeLog(double x) {
  std::uint64_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  // The biased exponent as a double, exactly: its bits in the mantissa of 2^52.
  const std::uint64_t exponent_bits = (bits >> 52) | 0x4330000000000000ULL;
  double exponent;
  std::memcpy(&exponent, &exponent_bits, sizeof exponent);
  exponent -= 4503599627370496.0 + 1023.0;
  const std::uint64_t mantissa_bits = (bits & 0x000FFFFFFFFFFFFFULL) | 0x3FF0000000000000ULL;
  double m;
  std::memcpy(&m, &mantissa_bits, sizeof m);
  const bool high = m > M_SQRT2;
  m = high ? 0.5 * m : m;
  exponent = high ? exponent + 1.0 : exponent;
  const double s = (m - 1.0) / (m + 1.0), s2 = s * s;
  const double series =
      1.0 +
      s2 *
          (1.0 / 3 +
           s2 * (1.0 / 5 +
                 s2 * (1.0 / 7 +
                       s2 * (1.0 / 9 + s2 * (1.0 / 11 +
                                             s2 * (1.0 / 13 + s2 * (1.0 / 15 + s2 * (1.0 / 17 + s2 * (1.0 / 19)))))))));
  return exponent * M_LN2 + 2.0 * s * series;
}

/// What the pairs of one first-arm point with a run of second-arm points add up to.
struct RunSum {
  double sum = 0.0;
  std::size_t pairs = 0, distance_pairs = 0;
};

/// F(P1, P2) (3.42–3.45) of `p1` with the second arm's points [from, to) of `c`, summed: evaluate() without its
/// branches, over a chunk at a time, in a form the compiler vectorises (an AVX2 clone where the CPU has it). The
/// terms are added in index order, so the sum does not depend on the clone.
__attribute__((target_clones("avx2", "default"))) RunSum sumRun(const Prepared& p1, const Columns& c, std::size_t from,
                                                                std::size_t to, const PairQualitySettings& s) {
  constexpr std::size_t kChunk = 128;
  const double lo = s.length - s.tolerance, hi = s.length + s.tolerance, lo2 = lo * lo, hi2 = hi * hi;
  const double inverse_k = 1.0 / s.k, of_min = s.of_min;
  const double x1 = p1.position.x(), y1 = p1.position.y(), z1 = p1.position.z();
  const double ax1 = p1.axis.x(), ay1 = p1.axis.y(), az1 = p1.axis.z();
  const double cos1 = p1.cos_angle, angle1 = p1.angle, inverse_angle1 = p1.inverse_angle;
  const double weight1 = p1.weight;
  RunSum out;
  double term[kChunk];
  std::int64_t in_shell[kChunk], in_cones[kChunk];
  for (std::size_t begin = from; begin < to; begin += kChunk) {
    const std::size_t n = std::min(kChunk, to - begin);
    const double *x = c.x.data() + begin, *y = c.y.data() + begin, *z = c.z.data() + begin;
    const double *ax = c.ax.data() + begin, *ay = c.ay.data() + begin, *az = c.az.data() + begin;
    const double *cos2 = c.cos_angle.data() + begin, *angle2 = c.angle.data() + begin;
    const double *inverse_angle2 = c.inverse_angle.data() + begin, *weight2 = c.weight.data() + begin;
    for (std::size_t k = 0; k < n; ++k) {
      const double dx = x[k] - x1, dy = y[k] - y1, dz = z[k] - z1;
      const double d2 = dx * dx + dy * dy + dz * dz;
      const double distance = std::sqrt(d2);
      const bool shell = (d2 > lo2) & (d2 < hi2) & (distance > lo) & (distance < hi);
      const double inverse_distance = 1.0 / std::max(distance, 1e-300);
      const double c1 = (ax1 * dx + ay1 * dy + az1 * dz) * inverse_distance;
      const double c2 = -(ax[k] * dx + ay[k] * dy + az[k] * dz) * inverse_distance;
      const bool cones = shell & (c1 > cos1) & (c2 > cos2[k]);
      const double room = std::max(0.0, (angle1 - fastAcos(c1)) * inverse_angle1) *
                          std::max(0.0, (angle2[k] - fastAcos(c2)) * inverse_angle2[k]);
      const double of = std::max(of_min, 1.0 + branchFreeLog(std::max(room, 1e-300)) * inverse_k);
      term[k] = cones ? of * weight2[k] : 0.0;
      in_shell[k] = shell ? 1 : 0;
      in_cones[k] = cones ? 1 : 0;
    }
    std::int64_t shell_count = 0, cone_count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      shell_count += in_shell[k];
      cone_count += in_cones[k];
    }
    double chunk_sum = 0.0;
    for (std::size_t k = 0; k < n; ++k) chunk_sum += term[k];
    out.sum += weight1 * chunk_sum;
    out.distance_pairs += static_cast<std::size_t>(shell_count);
    out.pairs += static_cast<std::size_t>(cone_count);
  }
  return out;
}

void checkPoints(const WorkspacePoints& w, const char* which) {
  const std::string where = std::string("placement quality: the ") + which + " arm's points";
  if (!(w.voxel_volume > 0.0) || !(w.resolution > 0.0) || !std::isfinite(w.voxel_volume) ||
      !std::isfinite(w.resolution)) {
    throw std::invalid_argument(where + " need a voxel volume and resolution > 0");
  }
  for (const WorkspacePoint& p : w.points) {
    if (!p.position.allFinite() || !p.tool.axis.allFinite() || p.tool.axis.norm() < 1e-12 ||
        !(p.tool.angle >= 0.0 && p.tool.angle <= M_PI) || !(p.condition >= 1.0) || !std::isfinite(p.condition) ||
        !(p.solution_ratio >= 0.0 && p.solution_ratio <= 1.0) || !(p.manipulability >= 0.0) ||
        !std::isfinite(p.manipulability)) {
      throw std::invalid_argument(where + ": a point with a non-finite or out-of-range value");
    }
  }
}

void checkInputs(const WorkspacePoints& first, const WorkspacePoints& second, const PairQualitySettings& settings) {
  settings.validate();
  checkPoints(first, "first");
  checkPoints(second, "second");
}

std::vector<Prepared> inWorld(const WorkspacePoints& w, const Eigen::Isometry3d& base) {
  std::vector<Prepared> out;
  out.reserve(w.points.size());
  for (const WorkspacePoint& p : w.points) out.push_back(prepare(p.transformed(base)));
  return out;
}

/// The volume of the union of both arms' voxels: the second arm's voxel centres that fall into a voxel of the
/// first count once.
double unionVolume(const WorkspacePoints& first, const Eigen::Isometry3d& first_base, const WorkspacePoints& second,
                   const Eigen::Isometry3d& second_base) {
  if (first.points.empty()) return second.voxel_volume * static_cast<double>(second.points.size());
  const Eigen::Vector3d origin = first.points.front().position;
  const auto key = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d g = ((p - origin) / first.resolution).array().round();
    return (static_cast<std::int64_t>(g.x()) + (1 << 20)) | ((static_cast<std::int64_t>(g.y()) + (1 << 20)) << 21) |
           ((static_cast<std::int64_t>(g.z()) + (1 << 20)) << 42);
  };
  std::unordered_set<std::int64_t> occupied;
  for (const WorkspacePoint& p : first.points) occupied.insert(key(p.position));
  const Eigen::Isometry3d second_in_first = first_base.inverse() * second_base;
  std::size_t shared = 0;
  for (const WorkspacePoint& p : second.points) shared += occupied.count(key(second_in_first * p.position));
  return first.voxel_volume * static_cast<double>(first.points.size()) +
         second.voxel_volume * static_cast<double>(second.points.size() - shared);
}

}  // namespace

void PairQualitySettings::validate() const {
  if (!(length > 0.0) || !std::isfinite(length)) throw std::invalid_argument("placement quality: length L > 0");
  if (!(tolerance > 0.0 && tolerance < length)) throw std::invalid_argument("placement quality: 0 < tolerance < L");
  if (!(k > 0.0) || !std::isfinite(k)) throw std::invalid_argument("placement quality: K > 0");
  if (!(of_min > 0.0 && of_min <= 1.0)) throw std::invalid_argument("placement quality: 0 < OF_min <= 1");
  if (threads < 0) throw std::invalid_argument("placement quality: threads >= 0 (0: one per core)");
}

WorkspacePoint WorkspacePoint::transformed(const Eigen::Isometry3d& pose) const {
  WorkspacePoint out = *this;
  out.position = pose * position;
  out.tool.axis = pose.linear() * tool.axis;
  return out;
}

PairFactors pairFactors(const WorkspacePoint& p1, const WorkspacePoint& p2, const PairQualitySettings& settings) {
  settings.validate();
  const Eigen::Vector3d d = p2.position - p1.position;
  const double distance = d.norm();
  if (!(distance > settings.length - settings.tolerance && distance < settings.length + settings.tolerance)) return {};
  return evaluate(prepare(p1), prepare(p2), d, distance, settings);
}

WorkspacePoints WorkspacePoints::of(const WorkspaceMap& map) {
  WorkspacePoints out;
  out.resolution = map.settings().resolution;
  out.voxel_volume = std::pow(out.resolution, 3);
  for (const WorkspaceVoxel& v : map.voxels()) {
    if (v.solved == 0) continue;
    WorkspacePoint p;
    p.position = v.centre;
    p.tool = v.tool;
    p.solution_ratio = v.solution_ratio;
    p.manipulability = v.manipulability;
    p.condition = std::max(1.0, v.condition);
    out.points.push_back(p);
  }
  return out;
}

PlacementQuality placementQuality(const WorkspacePoints& first, const Eigen::Isometry3d& first_base,
                                  const WorkspacePoints& second, const Eigen::Isometry3d& second_base,
                                  const PairQualitySettings& settings) {
  checkInputs(first, second, settings);
  const auto start = realtime::Clock::now();
  const std::vector<Prepared> a = inWorld(first, first_base), b = inWorld(second, second_base);
  const double lo = settings.length - settings.tolerance, hi = settings.length + settings.tolerance;
  PlacementQuality out;
  out.volume = unionVolume(first, first_base, second, second_base);

  // The index: the second arm's points sorted into cubic cells of edge h over their bounding box.
  const double h = hi / 5.0;
  Eigen::Vector3d low = Eigen::Vector3d::Constant(0.0), high = low;
  if (!b.empty()) low = high = b.front().position;
  for (const Prepared& p : b) {
    low = low.cwiseMin(p.position);
    high = high.cwiseMax(p.position);
  }
  int cells[3];
  for (int axis = 0; axis < 3; ++axis) cells[axis] = static_cast<int>(std::floor((high[axis] - low[axis]) / h)) + 1;
  /// The cell index along `axis` of coordinate `v`, clamped to the grid.
  const auto cellAlong = [&](int axis, double v) {
    return std::clamp(static_cast<int>(std::floor((v - low[axis]) / h)), 0, cells[axis] - 1);
  };
  const auto flat = [&](int x, int y, int z) {
    return static_cast<std::size_t>(x) +
           static_cast<std::size_t>(cells[0]) *
               (static_cast<std::size_t>(y) + static_cast<std::size_t>(cells[1]) * static_cast<std::size_t>(z));
  };
  const auto cellOf = [&](const Eigen::Vector3d& p) {
    return flat(cellAlong(0, p.x()), cellAlong(1, p.y()), cellAlong(2, p.z()));
  };
  std::vector<std::size_t> begin(
      static_cast<std::size_t>(cells[0]) * static_cast<std::size_t>(cells[1]) * static_cast<std::size_t>(cells[2]) + 1,
      0);
  for (const Prepared& p : b) ++begin[cellOf(p.position) + 1];
  for (std::size_t i = 1; i < begin.size(); ++i) begin[i] += begin[i - 1];
  std::vector<std::size_t> order(b.size()), fill(begin.begin(), begin.end() - 1);
  for (std::size_t i = 0; i < b.size(); ++i) order[fill[cellOf(b[i].position)]++] = i;
  // The second arm's points in cell order, so that a cell's points, and a row's cells, are contiguous in memory.
  const Columns columns(b, order);

  // Blocks of the first arm's points on threads; each block's sums are added in block order, so the result does not
  // depend on the number of threads.
  constexpr std::size_t kBlock = 64;
  constexpr double kCellMargin = 1e-9;  ///< [m] A cell is skipped only when clearly outside the shell.
  const std::size_t blocks = (a.size() + kBlock - 1) / kBlock;
  struct Partial {
    double sum = 0.0;
    std::size_t pairs = 0, distance_pairs = 0, visited = 0;
  };
  const double outer2 = (hi + kCellMargin) * (hi + kCellMargin), inner2 = (lo - kCellMargin) * (lo - kCellMargin);
  std::vector<Partial> partials(blocks);
  parallel::parallelFor(blocks, settings.threads, [&](int, std::size_t block) {
    Partial& part = partials[block];
    std::array<std::vector<double>, 3> near2, far2;
    for (int axis = 0; axis < 3; ++axis) {
      near2[axis].resize(static_cast<std::size_t>(cells[axis]));
      far2[axis].resize(static_cast<std::size_t>(cells[axis]));
    }
    for (std::size_t i = block * kBlock; i < std::min(a.size(), (block + 1) * kBlock); ++i) {
      const Prepared& p1 = a[i];
      int from[3], to[3];
      for (int axis = 0; axis < 3; ++axis) {
        from[axis] = cellAlong(axis, p1.position[axis] - hi);
        to[axis] = cellAlong(axis, p1.position[axis] + hi);
      }
      // The points of a run of neighbouring cells of one row are contiguous: each run is summed in one call.
      std::size_t run_from = 0, run_to = 0;
      const auto flush = [&] {
        if (run_to == run_from) return;
        const RunSum r = sumRun(p1, columns, run_from, run_to, settings);
        part.sum += r.sum;
        part.pairs += r.pairs;
        part.distance_pairs += r.distance_pairs;
        part.visited += run_to - run_from;
        run_from = run_to = 0;
      };
      // Per axis, the squared distances from P1 to the nearest and the farthest coordinate of each cell: a cell's
      // squared distances to P1 are their sums over the axes.
      for (int axis = 0; axis < 3; ++axis) {
        for (int cell = from[axis]; cell <= to[axis]; ++cell) {
          const double cell_low = low[axis] + h * cell, v = p1.position[axis];
          const double nearest = std::clamp(v, cell_low, cell_low + h) - v;
          const double farthest = std::max(std::abs(v - cell_low), std::abs(v - cell_low - h));
          near2[axis][cell - from[axis]] = nearest * nearest;
          far2[axis][cell - from[axis]] = farthest * farthest;
        }
      }
      for (int z = from[2]; z <= to[2]; ++z) {
        for (int y = from[1]; y <= to[1]; ++y) {
          const double near_yz = near2[1][y - from[1]] + near2[2][z - from[2]];
          const double far_yz = far2[1][y - from[1]] + far2[2][z - from[2]];
          for (int x = from[0]; x <= to[0]; ++x) {
            // Skip a cell that lies wholly outside the shell L ± δ around P1.
            if (near_yz + near2[0][x - from[0]] > outer2 || far_yz + far2[0][x - from[0]] < inner2) continue;
            const std::size_t c = flat(x, y, z);
            if (begin[c] != run_to) flush();
            if (run_to == run_from) run_from = begin[c];
            run_to = begin[c + 1];
          }
        }
      }
      flush();
    }
  });
  for (const Partial& part : partials) {
    out.pair_sum += part.sum;
    out.pairs += part.pairs;
    out.distance_pairs += part.distance_pairs;
    out.visited += part.visited;
  }
  out.quality = out.volume * out.pair_sum;
  out.seconds = realtime::secondsSince(start);
  return out;
}

PlacementQuality bruteForcePlacementQuality(const WorkspacePoints& first, const Eigen::Isometry3d& first_base,
                                            const WorkspacePoints& second, const Eigen::Isometry3d& second_base,
                                            const PairQualitySettings& settings) {
  checkInputs(first, second, settings);
  const auto start = realtime::Clock::now();
  PlacementQuality out;
  out.volume = unionVolume(first, first_base, second, second_base);
  for (const WorkspacePoint& p : first.points) {
    const WorkspacePoint p1 = p.transformed(first_base);
    for (const WorkspacePoint& q : second.points) {
      const WorkspacePoint p2 = q.transformed(second_base);
      ++out.visited;
      const double distance = (p2.position - p1.position).norm();
      if (distance > settings.length - settings.tolerance && distance < settings.length + settings.tolerance) {
        ++out.distance_pairs;
      }
      const PairFactors f = pairFactors(p1, p2, settings);
      if (f.df == 0.0) continue;
      ++out.pairs;
      out.pair_sum += f.product();
    }
  }
  out.quality = out.volume * out.pair_sum;
  out.seconds = realtime::secondsSince(start);
  return out;
}

}  // namespace bimanual_skills::workspace
