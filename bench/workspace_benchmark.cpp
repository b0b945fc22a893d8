// workspace_benchmark: the workspace analysis of thesis Sec. 3.2 on the WAM.
//   map: the one-arm map by inverse sampling (Sec. 3.2.1, Fig. 3.7): a voxel grid over the reach, M tool
//        orientations per voxel through the global IK (a fixed number of restarts, so the map does not depend on
//        the machine's load), solution ratio, mean manipulability and condition number, forearm and tool cones.
//        Default 5 cm and M = 50 (the target: at most 2 minutes on this machine); --quick: 20 cm, M = 10.
// Writes DIR/summary.json (experiment, resolution_m, orientations, seconds, voxels, reachable_voxels, ...),
// DIR/map.csv (one row per voxel) and, with scripts/plot_workspace_benchmark.py, DIR/map_slices.png and tables.md.
#include "bimanual_skills/workspace/workspace_map.hpp"
#include "experiment_cli.hpp"
#include "summary_json.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

namespace bs = bimanual_skills;
namespace bw = bimanual_skills::workspace;

namespace {

const std::string kSourceDir = BIMANUAL_SKILLS_SOURCE_DIR;

}  // namespace

int main(int argc, char** argv) {
  double resolution = 0.0;
  long orientations = 0, attempts = 20;
  bool no_wrist_test = false;
  bs::bench::ExperimentProgram program;
  program.name = "workspace_benchmark";
  program.description =
      "The workspace analysis of thesis Sec. 3.2 on the WAM: map = the one-arm workspace map by inverse sampling\n"
      "(Fig. 3.7), timed, with the solution ratio, manipulability, condition number and bounding cones per voxel.";
  program.experiments = {"map"};
  program.with_jobs = true;
  program.extra = [&](bs::cli::CommandLine& line) {
    line.option("--resolution", "M", "voxel edge [m] (default 0.05; 0.2 with --quick)", &resolution);
    line.option("--orientations", "N", "tool orientations per voxel (default 50; 10 with --quick)", &orientations, 1,
                100000);
    line.option("--ik-attempts", "N", "IK restarts per orientation (default 20)", &attempts, 1, 100000);
    line.flag("--no-wrist-test", "IK calls only, without the wrist-centre test (the baseline)", &no_wrist_test);
  };
  const bs::bench::ExperimentOptions options = bs::bench::parseExperimentOptions(argc, argv, program);
  if (resolution < 0.0 || (resolution > 0.0 && resolution < 0.005)) {
    std::fprintf(stderr, "workspace_benchmark: --resolution must be >= 0.005 m (see --help)\n");
    return 2;
  }
  try {
    std::filesystem::create_directories(options.out);
    const bs::kinematics::ChainModel model =
        bs::kinematics::ChainModel::fromUrdfFile(kSourceDir + "/urdf/wam.urdf", "wam_base", "wam_tool");
    bw::WorkspaceMapSettings settings;
    settings.resolution = resolution > 0.0 ? resolution : (options.quick ? 0.2 : 0.05);
    settings.orientations = orientations > 0 ? static_cast<int>(orientations) : (options.quick ? 10 : 50);
    settings.ik_attempts = static_cast<int>(attempts);
    settings.seed = options.seed;
    settings.threads = options.jobs;
    settings.wrist_test = !no_wrist_test;
    std::printf(
        "workspace_benchmark: map of the WAM, %.3f m voxels, %d orientations each, %d IK restarts, seed %u, "
        "%d threads\n",
        settings.resolution, settings.orientations, settings.ik_attempts, settings.seed, settings.threads);
    std::fflush(stdout);
    const auto start = std::chrono::steady_clock::now();
    const bw::WorkspaceMap map = bw::WorkspaceMap::build(model, settings, [&](std::size_t done, std::size_t total) {
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("  %zu/%zu voxels, %.0f s%s\n", done, total, s,
                  done > 0 && done < total
                      ? (", ETA " + std::to_string(static_cast<int>(s / done * (total - done))) + " s").c_str()
                      : "");
      std::fflush(stdout);
    });
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
    csv.close();
    std::vector<bs::bench::JsonRow> rows;
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
    bs::bench::writeSummaryJson(options, "workspace_benchmark", rows);
    std::printf(
        "workspace_benchmark: %zu voxels (%zu reachable) in %.1f s; %.1f %% of the orientations ruled out by "
        "the wrist-centre test\n",
        map.voxels().size(), map.reachable(), seconds,
        attempts_total > 0 ? 100.0 * pruned_total / attempts_total : 0.0);
    bs::bench::runPlotScript("workspace_benchmark", kSourceDir + "/scripts/plot_workspace_benchmark.py", options.out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "workspace_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
