// workspace_benchmark: the workspace analysis of thesis Sec. 3.2 on the WAM.
//   map:    the one-arm map by inverse sampling (Sec. 3.2.1, Fig. 3.7): a voxel grid over the reach, M tool
//           orientations per voxel through the global IK (a fixed number of restarts, so the map does not depend on
//           the machine's load), solution ratio, mean manipulability and condition number, forearm and tool cones.
//           Default 5 cm and M = 50 (the target: at most 2 minutes on this machine); --quick: 20 cm, M = 10.
//   quality: one evaluation of F (3.41) on the 5 cm map (the target: at most 1 s), fig39's setting at the
//           thesis' dx = dz = 0.8 m, timed --runs times (default 10; --quick: 2 on the 20 cm map), beside the
//           brute-force sum over every pair, which it must equal.
//   fig39:  the quality F (3.41) of placing a second WAM with its base perpendicular to the first's (its z axis along
//           −x), over a grid of offsets dx, dz (Fig. 3.9); the best, the best with both offsets negative (the DARPA
//           robot's quadrant) and a humanoid-like placement (z axes collinear, pointing away from a torso).
//   fig310: the same with the second base upside down above the first (z axes parallel and facing, Fig. 3.10).
//           Both on a map of 10 cm voxels by default (--resolution), grid step 0.1 m (--step); --quick: 20 cm, 0.4 m.
//   placement: the search for fig39's best (dx, dz) by the thesis' genetic algorithm (10 generations of 20) and by
//           NLopt's ESCH, CRS2, ISRES and DIRECT-L with the same budget, over --runs seeds (default 5; --quick: 2 runs
//           of 40 evaluations): the best quality found and the evaluations each needed to reach the GA's.
// Maps are kept in a cache directory (--cache, default ~/.cache/bimanual_skills/workspace; --no-cache), one file per
// arm and settings: map always builds and times its map and writes it there; fig39, fig310 and placement read theirs
// from it when it is there.
// Writes DIR/summary.json (rows with experiment, resolution_m, orientations, seconds, ...; best_dx, best_dz,
// quality for the placements), DIR/map.csv (one row per voxel), DIR/<fig>.csv (one row per placement) and, with
// scripts/plot_workspace_benchmark.py, DIR/map_slices.png, DIR/<fig>.png heat maps and tables.md.
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/workspace/pair_quality.hpp"
#include "bimanual_skills/workspace/placement_search.hpp"
#include "bimanual_skills/workspace/workspace_map.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;
namespace bw = bimanual_skills::workspace;

namespace {

using bimanual_skills::realtime::Clock;
using bimanual_skills::realtime::secondsSince;

/// The WAM's map with progress lines: built (and saved into `cache` unless it is empty) when `rebuild` or when the
/// cache does not hold it, else loaded from the cache; `seconds` gets the time it took.
bw::WorkspaceMap buildMap(const bs::kinematics::ChainModel& model, const bw::WorkspaceMapSettings& settings,
                          const std::string& cache, bool rebuild, double& seconds) {
  std::printf(
      "workspace_benchmark: map of the WAM, %.3f m voxels, %d orientations each, %d IK restarts, seed %u, "
      "%d threads\n",
      settings.resolution, settings.orientations, settings.ik_attempts, settings.seed, settings.threads);
  std::fflush(stdout);
  const auto start = Clock::now();
  const auto progress = [&](std::size_t done, std::size_t total) {
    const double s = secondsSince(start);
    std::printf("  %zu/%zu voxels, %.0f s%s\n", done, total, s,
                done > 0 && done < total
                    ? (", ETA " + std::to_string(static_cast<int>(s / done * (total - done))) + " s").c_str()
                    : "");
    std::fflush(stdout);
  };
  bool from_cache = false;
  bw::WorkspaceMap map = rebuild ? bw::WorkspaceMap::build(model, settings, progress)
                                 : bw::WorkspaceMap::cached(model, settings, cache, progress, &from_cache);
  if (rebuild && !cache.empty()) {
    std::filesystem::create_directories(cache);
    map.save(bw::WorkspaceMap::cachePath(cache, model, settings), bw::WorkspaceMap::key(model, settings));
  }
  seconds = secondsSince(start);
  if (from_cache) {
    std::printf("workspace_benchmark: the map from %s (%.2f s)\n",
                bw::WorkspaceMap::cachePath(cache, model, settings).c_str(), seconds);
  }
  return map;
}

void mapExperiment(const bs::bench::ExperimentOptions& options, const bw::WorkspaceMap& map, double seconds,
                   std::vector<bs::bench::JsonRow>& rows) {
  const bw::WorkspaceMapSettings& settings = map.settings();
  std::ofstream csv(options.out + "/map.csv");
  csv << "x,y,z,solved,pruned,solution_ratio,manipulability,condition,forearm_x,forearm_y,forearm_z,forearm_angle,"
         "tool_angle\n";
  long attempts_total = 0, pruned_total = 0;
  for (const bw::WorkspaceVoxel& v : map.voxels()) {
    attempts_total += settings.orientations;
    pruned_total += v.pruned;
    csv << v.centre.x() << ',' << v.centre.y() << ',' << v.centre.z() << ',' << v.solved << ',' << v.pruned << ','
        << v.solution_ratio << ',' << v.manipulability << ',' << v.condition << ',' << v.forearm.axis.x() << ','
        << v.forearm.axis.y() << ',' << v.forearm.axis.z() << ',' << v.forearm.angle << ',' << v.tool.angle << '\n';
  }
  rows.emplace_back()
      .add("experiment", "map")
      .add("robot", "wam")
      .add("resolution_m", settings.resolution)
      .add("orientations", settings.orientations)
      .add("ik_attempts", settings.ik_attempts)
      .add("threads", settings.threads)
      .add("seconds", seconds)
      .add("voxels", static_cast<long>(map.voxels().size()))
      .add("reachable_voxels", static_cast<long>(map.reachable()))
      .add("pruned_fraction", attempts_total > 0 ? static_cast<double>(pruned_total) / attempts_total : 0.0)
      .add("wrist_test", settings.wrist_test)
      .add("spherical_wrist", map.sphericalWrist())
      .add("reach_m", map.reach());
  std::printf(
      "workspace_benchmark: %zu voxels (%zu reachable) in %.1f s; %.1f %% of the orientations ruled out by "
      "the wrist-centre test\n",
      map.voxels().size(), map.reachable(), seconds, attempts_total > 0 ? 100.0 * pruned_total / attempts_total : 0.0);
}

Eigen::Isometry3d basePose(double x, double y, double z, double angle, const Eigen::Vector3d& axis) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translate(Eigen::Vector3d(x, y, z));
  t.rotate(Eigen::AngleAxisd(angle, axis));
  return t;
}

/// The second base of fig39's setting: perpendicular to the first (its z axis along −x), at (dx, 0, dz).
Eigen::Isometry3d perpendicularBase(double dx, double dz) {
  return basePose(dx, 0.0, dz, -M_PI / 2, Eigen::Vector3d::UnitY());
}

/// The second base of fig310's setting: upside down above the first (z axes parallel, facing), at (dx, 0, dz).
Eigen::Isometry3d facingBase(double dx, double dz) {
  return basePose(dx, 0.0, dz, M_PI, Eigen::Vector3d::UnitX());
}

/// One evaluation of F on `map`, fig39's setting at the thesis' optimum dx = dz = 0.8 m, timed `runs` times, beside
/// the brute-force sum over every pair (once): the values must agree.
void qualityExperiment(const bs::bench::ExperimentOptions& options, const bw::WorkspaceMap& map, int runs,
                       std::vector<bs::bench::JsonRow>& rows) {
  bw::PairQualitySettings quality;
  quality.threads = options.jobs;
  const bw::WorkspacePoints points = bw::WorkspacePoints::of(map);
  const Eigen::Isometry3d first = Eigen::Isometry3d::Identity(), second = perpendicularBase(0.8, 0.8);
  std::printf(
      "workspace_benchmark: quality: F at fig39's dx = dz = 0.8 m on the %.3f m map (%zu reachable voxels "
      "per arm), %d times on %d threads, then by brute force\n",
      map.settings().resolution, points.points.size(), runs, options.jobs);
  std::fflush(stdout);
  std::vector<double> times;
  bw::PlacementQuality q;
  for (int run = 0; run < runs; ++run) {
    q = bw::placementQuality(points, first, points, second, quality);
    times.push_back(q.seconds);
    std::printf("  run %d: F = %.6g, %.3f s (%zu pairs visited, %zu at a distance within L +- delta, %zu counted)\n",
                run + 1, q.quality, q.seconds, q.visited, q.distance_pairs, q.pairs);
    std::fflush(stdout);
  }
  std::sort(times.begin(), times.end());
  const double median = times[times.size() / 2];
  const bw::PlacementQuality brute = bw::bruteForcePlacementQuality(points, first, points, second, quality);
  const double difference = std::abs(brute.quality - q.quality) / std::max(1e-300, std::abs(brute.quality));
  std::printf(
      "workspace_benchmark: quality: median %.3f s (min %.3f, max %.3f) against %.1f s by brute force "
      "(%.0fx; F %.6g vs %.6g, relative difference %.1e)\n",
      median, times.front(), times.back(), brute.seconds, brute.seconds / median, q.quality, brute.quality, difference);
  rows.emplace_back()
      .add("experiment", "quality")
      .add("resolution_m", map.settings().resolution)
      .add("reachable_voxels", static_cast<long>(points.points.size()))
      .add("threads", options.jobs)
      .add("runs", runs)
      .add("quality", q.quality)
      .add("pairs", static_cast<long>(q.pairs))
      .add("pairs_visited", static_cast<long>(q.visited))
      .add("distance_pairs", static_cast<long>(q.distance_pairs))
      .add("median_seconds", median)
      .add("min_seconds", times.front())
      .add("max_seconds", times.back())
      .add("brute_force_seconds", brute.seconds)
      .add("brute_force_quality", brute.quality)
      .add("relative_difference", difference);
}

/// One of the thesis' two placement settings: the second base's pose for offsets (dx, dz) from the first's, and the
/// grid of offsets.
struct Setting {
  std::string name, description;
  std::function<Eigen::Isometry3d(double dx, double dz)> second_base;
  double dx_min, dx_max, dz_min, dz_max;
};

/// The quality F of every placement of the grid, written to DIR/<setting>.csv as it goes; the best placements and
/// the comparisons in `rows`.
void placementExperiment(const bs::bench::ExperimentOptions& options, const Setting& setting,
                         const bw::WorkspaceMap& map, double step, std::vector<bs::bench::JsonRow>& rows) {
  const bw::WorkspacePoints points = bw::WorkspacePoints::of(map);
  bw::PairQualitySettings quality;
  quality.threads = options.jobs;
  const auto count = [&](double lo, double hi) { return static_cast<int>(std::floor((hi - lo) / step + 1e-9)) + 1; };
  const int nx = count(setting.dx_min, setting.dx_max), nz = count(setting.dz_min, setting.dz_max);
  std::printf("workspace_benchmark: %s: %s; %d x %d placements, %zu reachable voxels per arm, L = %.2f +- %.2f m\n",
              setting.name.c_str(), setting.description.c_str(), nx, nz, points.points.size(), quality.length,
              quality.tolerance);
  std::fflush(stdout);
  std::ofstream csv(options.out + "/" + setting.name + ".csv");
  csv << "dx,dz,quality,pair_sum,volume_m3,pairs,visited,seconds\n";
  struct Best {
    double dx = 0.0, dz = 0.0;
    bw::PlacementQuality q;
    bool found = false;
  } best, negative;
  double total_seconds = 0.0, worst_seconds = 0.0;
  const auto start = Clock::now();
  for (int iz = 0; iz < nz; ++iz) {
    for (int ix = 0; ix < nx; ++ix) {
      const double dx = setting.dx_min + ix * step, dz = setting.dz_min + iz * step;
      const bw::PlacementQuality q =
          bw::placementQuality(points, Eigen::Isometry3d::Identity(), points, setting.second_base(dx, dz), quality);
      csv << dx << ',' << dz << ',' << q.quality << ',' << q.pair_sum << ',' << q.volume << ',' << q.pairs << ','
          << q.visited << ',' << q.seconds << '\n';
      total_seconds += q.seconds;
      worst_seconds = std::max(worst_seconds, q.seconds);
      if (!best.found || q.quality > best.q.quality) best = {dx, dz, q, true};
      if (dx < -1e-9 && dz < -1e-9 && (!negative.found || q.quality > negative.q.quality)) {
        negative = {dx, dz, q, true};
      }
    }
    csv.flush();
    const double s = secondsSince(start);
    std::printf("  %s: %d/%d rows of placements, %.0f s, ETA %.0f s; best so far F = %.4g at dx = %.2f, dz = %.2f\n",
                setting.name.c_str(), iz + 1, nz, s, s / (iz + 1) * (nz - iz - 1), best.q.quality, best.dx, best.dz);
    std::fflush(stdout);
  }
  const int evaluations = nx * nz;
  bs::bench::JsonRow& row = rows.emplace_back();
  row.add("experiment", setting.name)
      .add("resolution_m", map.settings().resolution)
      .add("orientations", map.settings().orientations)
      .add("step_m", step)
      .add("evaluations", evaluations)
      .add("seconds_per_evaluation", total_seconds / evaluations)
      .add("max_seconds_per_evaluation", worst_seconds)
      .add("best_dx", best.dx)
      .add("best_dz", best.dz)
      .add("quality", best.q.quality)
      .add("pair_sum", best.q.pair_sum)
      .add("volume_m3", best.q.volume)
      .add("pairs", static_cast<long>(best.q.pairs));
  std::printf("workspace_benchmark: %s: best F = %.4g at dx = %.2f m, dz = %.2f m (%.3f s per evaluation)\n",
              setting.name.c_str(), best.q.quality, best.dx, best.dz, total_seconds / evaluations);
  if (negative.found) {
    row.add("best_negative_dx", negative.dx)
        .add("best_negative_dz", negative.dz)
        .add("negative_quality", negative.q.quality);
    std::printf(
        "workspace_benchmark: %s: best with dx, dz < 0 (the DARPA robot's quadrant): F = %.4g at dx = %.2f, "
        "dz = %.2f\n",
        setting.name.c_str(), negative.q.quality, negative.dx, negative.dz);
  }
  // Humanoid-like: the bases back to back, z axes collinear and pointing away from a torso of width w (ARMAR).
  double humanoid = 0.0, humanoid_width = 0.0;
  for (double w = 0.2; w <= 0.8 + 1e-9; w += 0.1) {
    const bw::PlacementQuality q =
        bw::placementQuality(points, basePose(0.0, -w / 2, 0.0, M_PI / 2, Eigen::Vector3d::UnitX()), points,
                             basePose(0.0, w / 2, 0.0, -M_PI / 2, Eigen::Vector3d::UnitX()), quality);
    if (q.quality > humanoid) {
      humanoid = q.quality;
      humanoid_width = w;
    }
  }
  row.add("humanoid_quality", humanoid).add("humanoid_width_m", humanoid_width);
  std::printf("workspace_benchmark: %s: humanoid-like (bases back to back, best torso width %.1f m): F = %.4g\n",
              setting.name.c_str(), humanoid_width, humanoid);
  std::fflush(stdout);
}

/// Writes a bimanual configuration (the format of config/robots/wam/placement.yaml, which
/// scripts/generate_bimanual_urdf.py turns into a URDF) with the first arm at the world's origin and the second at
/// `second_base`.
void writeBimanualConfig(const std::string& path, const Eigen::Isometry3d& second_base, const std::string& why) {
  // URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll).
  const Eigen::Vector3d ypr = second_base.linear().eulerAngles(2, 1, 0);
  const Eigen::Vector3d t = second_base.translation();
  std::ofstream out(path);
  out.precision(6);
  out << "# Bimanual setup written by workspace_benchmark: " << why << "\n"
      << "# Units: m and rad (roll, pitch, yaw about fixed x, y, z, as in URDF). Generate its URDF with\n"
      << "#   scripts/generate_bimanual_urdf.py --config " << path << " --out FILE\n"
      << "world_frame: world\narms:\n"
      << "  - name: left\n    prefix: left_\n    xyz: [0.0, 0.0, 0.0]\n    rpy: [0.0, 0.0, 0.0]\n"
      << "  - name: right\n    prefix: right_\n    xyz: [" << t.x() << ", " << t.y() << ", " << t.z() << "]\n"
      << "    rpy: [" << ypr[2] << ", " << ypr[1] << ", " << ypr[0] << "]\n";
  if (!out.flush()) throw std::runtime_error("cannot write " + path);
  std::printf("workspace_benchmark: wrote %s (%s)\n", path.c_str(), why.c_str());
}

/// The searches for the best placement of `setting` (its two offsets) on `runs` seeds: the thesis' genetic algorithm
/// and NLopt's, each with `budget` evaluations; DIR/placement.csv holds every search's best-so-far curve.
void searchExperiment(const bs::bench::ExperimentOptions& options, const Setting& setting, const bw::WorkspaceMap& map,
                      int runs, int budget, const std::string& config, std::vector<bs::bench::JsonRow>& rows) {
  const bw::WorkspacePoints points = bw::WorkspacePoints::of(map);
  bw::PairQualitySettings quality;
  quality.threads = options.jobs;
  const bw::PlacementObjective objective = [&](const Eigen::VectorXd& x) {
    return bw::placementQuality(points, Eigen::Isometry3d::Identity(), points, setting.second_base(x[0], x[1]), quality)
        .quality;
  };
  bw::SearchBounds bounds;
  bounds.lower = Eigen::Vector2d(setting.dx_min, setting.dz_min);
  bounds.upper = Eigen::Vector2d(setting.dx_max, setting.dz_max);
  std::printf("workspace_benchmark: placement: %s, dx in [%.1f, %.1f], dz in [%.1f, %.1f]; %d runs of %d evaluations\n",
              setting.description.c_str(), setting.dx_min, setting.dx_max, setting.dz_min, setting.dz_max, runs,
              budget);
  std::fflush(stdout);
  std::ofstream csv(options.out + "/placement.csv");
  csv << "method,run,evaluation,best_quality\n";
  std::vector<std::string> methods = {"GA"};
  for (const std::string& name : bw::nloptPlacementAlgorithms()) methods.push_back(name);
  struct Tally {
    double quality = 0.0, seconds = 0.0, to_ga = 0.0, best = -1.0, dx = 0.0, dz = 0.0;
    int reached_ga = 0, evaluations = 0;
  };
  std::vector<Tally> tally(methods.size());
  for (int run = 0; run < runs; ++run) {
    const std::uint32_t seed = options.seed + static_cast<std::uint32_t>(run);
    bw::GeneticSettings genetic;
    genetic.population = 20;
    genetic.generations = budget / genetic.population;
    genetic.seed = seed;
    std::vector<bw::SearchResult> results = {bw::geneticSearch(bounds, objective, genetic)};
    for (std::size_t m = 1; m < methods.size(); ++m) {
      results.push_back(bw::nloptSearch(methods[m], bounds, objective, budget, seed));
    }
    const double ga = results.front().quality;
    for (std::size_t m = 0; m < methods.size(); ++m) {
      const bw::SearchResult& r = results[m];
      for (std::size_t k = 0; k < r.best_after.size(); ++k) {
        csv << methods[m] << ',' << run << ',' << k + 1 << ',' << r.best_after[k] << '\n';
      }
      Tally& t = tally[m];
      t.quality += r.quality / runs;
      t.seconds += r.seconds / runs;
      t.evaluations += r.evaluations;
      if (r.quality > t.best) {
        t.best = r.quality;
        t.dx = r.best[0];
        t.dz = r.best[1];
      }
      const int reach = r.evaluationsToReach(ga);
      if (reach > 0) {
        ++t.reached_ga;
        t.to_ga += reach;
      }
      std::printf(
          "  run %d (seed %u) %-5s: F = %.4g at dx = %.2f, dz = %.2f after %d evaluations (%.1f s); the GA's "
          "best reached after %d\n",
          run + 1, seed, methods[m].c_str(), r.quality, r.best[0], r.best[1], r.evaluations, r.seconds, reach);
    }
    csv.flush();
    std::fflush(stdout);
  }
  for (std::size_t m = 0; m < methods.size(); ++m) {
    const Tally& t = tally[m];
    rows.emplace_back()
        .add("experiment", "placement")
        .add("method", methods[m])
        .add("runs", runs)
        .add("budget", budget)
        .add("resolution_m", map.settings().resolution)
        .add("mean_quality", t.quality)
        .add("best_quality", t.best)
        .add("best_dx", t.dx)
        .add("best_dz", t.dz)
        .add("mean_evaluations", static_cast<double>(t.evaluations) / runs)
        .add("runs_reaching_ga_best", t.reached_ga)
        .add("mean_evaluations_to_ga_best", t.reached_ga > 0 ? t.to_ga / t.reached_ga : -1.0)
        .add("mean_seconds", t.seconds);
  }
  if (!config.empty()) {
    const auto best =
        std::max_element(tally.begin(), tally.end(), [](const Tally& a, const Tally& b) { return a.best < b.best; });
    char why[160];
    std::snprintf(why, sizeof why, "the best %s placement found, dx = %.3f m, dz = %.3f m, F = %.4g (%s)",
                  setting.name.c_str(), best->dx, best->dz, best->best,
                  methods[static_cast<std::size_t>(best - tally.begin())].c_str());
    writeBimanualConfig(config, setting.second_base(best->dx, best->dz), why);
  }
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  double resolution = 0.0, step = 0.0;
  std::string cache = bw::WorkspaceMap::defaultCacheDirectory();
  bool no_cache = false;
  std::string write_config;
  long orientations = 0, attempts = 20;
  bool no_wrist_test = false;
  bs::bench::ExperimentProgram program;
  program.name = "workspace_benchmark";
  program.description =
      "The workspace analysis of thesis Sec. 3.2 on the WAM: map = the one-arm workspace map by inverse sampling\n"
      "(Fig. 3.7), timed, with the solution ratio, manipulability, condition number and bounding cones per voxel;\n"
      "quality = one evaluation of the placement quality (3.41) on the 5 cm map, timed, beside the brute-force sum;\n"
      "fig39, fig310 = the quality (3.41) of the relative placement of two WAMs over a grid of offsets (Figs. 3.9,\n"
      "3.10: bases perpendicular; bases parallel and facing); placement = the search for fig39's best placement by\n"
      "the thesis' genetic algorithm and by NLopt's ESCH, CRS2, ISRES and DIRECT-L with the same budget.";
  program.experiments = {"map", "quality", "fig39", "fig310", "placement", "all"};
  program.with_runs = true;
  program.with_jobs = true;
  program.extra = [&](bs::cli::CommandLine& line) {
    line.option("--resolution", "M", "voxel edge [m] (default 0.05 for map, 0.1 for fig39/fig310; 0.2 with --quick)",
                &resolution);
    line.option("--orientations", "N", "tool orientations per voxel (default 50; 10 with --quick)", &orientations, 1,
                100000);
    line.option("--ik-attempts", "N", "IK restarts per orientation (default 20)", &attempts, 1, 100000);
    line.flag("--no-wrist-test", "IK calls only, without the wrist-centre test (the baseline)", &no_wrist_test);
    line.option("--step", "M", "grid step of the placement offsets [m] (default 0.1; 0.4 with --quick)", &step);
    line.option("--cache", "DIR",
                "maps are kept in DIR, one file per arm and settings (default ~/.cache/bimanual_skills/workspace); "
                "map always builds and times the map and writes it there, the placement experiments read it",
                &cache);
    line.flag("--no-cache", "neither read nor write map files", &no_cache);
    line.option(
        "--write-config", "FILE",
        "placement: write the best placement found as a bimanual configuration (config/robots/wam/placement.yaml's "
        "format) for scripts/generate_bimanual_urdf.py",
        &write_config);
  };
  const bs::bench::ExperimentOptions options = bs::bench::parseExperimentOptions(argc, argv, program);
  if (resolution < 0.0 || (resolution > 0.0 && resolution < 0.005) || step < 0.0 || (step > 0.0 && step < 0.01)) {
    std::fprintf(stderr, "workspace_benchmark: --resolution must be >= 0.005 m and --step >= 0.01 m (see --help)\n");
    return 2;
  }
  if (no_cache) cache.clear();
  try {
    std::filesystem::create_directories(options.out);
    const bs::kinematics::ChainModel model = bs::kinematics::ChainModel::fromUrdfFile(
        bimanual_skills::cli::packageFile("urdf/wam.urdf"), "wam_base", "wam_tool");
    bw::WorkspaceMapSettings settings;
    settings.orientations = orientations > 0 ? static_cast<int>(orientations) : (options.quick ? 10 : 50);
    settings.ik_attempts = static_cast<int>(attempts);
    settings.seed = options.seed;
    settings.threads = options.jobs;
    settings.wrist_test = !no_wrist_test;
    const auto wants = [&](const char* name) { return options.experiment == "all" || options.experiment == name; };
    std::vector<bs::bench::JsonRow> rows;
    if (wants("map")) {
      settings.resolution = resolution > 0.0 ? resolution : (options.quick ? 0.2 : 0.05);
      double seconds = 0.0;
      const bw::WorkspaceMap map = buildMap(model, settings, cache, true, seconds);
      mapExperiment(options, map, seconds, rows);
    }
    if (wants("quality")) {
      settings.resolution = resolution > 0.0 ? resolution : (options.quick ? 0.2 : 0.05);
      double seconds = 0.0;
      const bw::WorkspaceMap map = buildMap(model, settings, cache, false, seconds);
      qualityExperiment(options, map, options.runs > 0 ? options.runs : (options.quick ? 2 : 10), rows);
    }
    if (wants("fig39") || wants("fig310") || wants("placement")) {
      settings.resolution = resolution > 0.0 ? resolution : (options.quick ? 0.2 : 0.1);
      const double grid = step > 0.0 ? step : (options.quick ? 0.4 : 0.1);
      double seconds = 0.0;
      const bw::WorkspaceMap map = buildMap(model, settings, cache, false, seconds);
      const Setting perpendicular{"fig39",
                                  "the second base perpendicular (its z axis along -x) at (dx, 0, dz)",
                                  perpendicularBase,
                                  -1.2,
                                  1.2,
                                  -1.2,
                                  1.2};
      const Setting facing{
          "fig310", "the second base upside down (z axes parallel, facing) at (dx, 0, dz)", facingBase, -1.2, 1.2, 0.2,
          2.6};
      if (wants("fig39")) placementExperiment(options, perpendicular, map, grid, rows);
      if (wants("fig310")) placementExperiment(options, facing, map, grid, rows);
      if (wants("placement")) {
        const int runs = options.runs > 0 ? options.runs : (options.quick ? 2 : 5);
        searchExperiment(options, perpendicular, map, runs, options.quick ? 40 : 200, write_config, rows);
      }
    }
    bs::bench::writeSummaryJson(options, "workspace_benchmark", rows);
    bs::bench::runPlotScript("workspace_benchmark", "plot_workspace_benchmark.py", options.out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "workspace_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
