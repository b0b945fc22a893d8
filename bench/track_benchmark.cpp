// track_benchmark: compliant object tracking (thesis Sec. 4.3.2, Figs. 4.10-4.11) over seeded object paths, the
// whole loop in one process on the simulated robot: the can carried along its path (sim::ObjectPath), the
// perspective RGB-D camera's frames at 30 Hz (vision::PerspectiveRenderer, Kinect-like errors), the tracker
// (tracking::ObjectTracker), its estimate handed to the left arm's controller a modelled `--latency` after the
// frame (the ROS path's is measured over ROS: docs/RESULTS.md), the follower in the 1 kHz control loop
// (control::RealtimeArmController) and the computed-torque controller with its friction model on the Bullet arms.
// Each path runs twice: following only (the tracking error against the object's pre-grasp point, by the object's
// speed; what a lost and a reacquired target do), then with grasping, the can carried for 30 s and then put down
// (success within 60 s, and whether it came while the can was carried).
//   track_benchmark --experiment tracking --seed S --out DIR [--runs PATHS] [--jobs N] [--quick]
#include "bimanual_skills/control/realtime_arm_controller.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "bimanual_skills/parallel/parallel_for.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/tracking/object_tracker.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"
#include "io/csv_records.hpp"
#include "testing/allocation_counter.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace bs = bimanual_skills;

namespace {

constexpr const char* kProgram = "track_benchmark";
constexpr double kCameraRate = 30.0;
/// Object speed bins of the error table [m/s].
const std::vector<double> kSpeedBins = {0.0, 0.05, 0.1, 0.15, 0.2, 1e9};

struct Settings {
  double latency = 0.010;     ///< Frame stamp -> the estimate in the controller [s] (over ROS: see RESULTS).
  double follow_time = 40.0;  ///< Following-only run per path [s of simulation].
  /// The grasping run: the can is carried for `carried` seconds, then put down where its last move ended; the run
  /// ends a second after a grasp, or at grasp_time.
  double carried = 30.0;
  double grasp_time = 60.0;
};

/// What one run of one path gave.
struct PathResult {
  int path = 0;
  std::uint32_t seed = 0;
  // Following.
  std::vector<double> errors;  ///< Every 10 ms while following at the pre-grasp point, in view [m].
  std::vector<double> speeds;  ///< The object's speed then [m/s].
  double reached = -1.0;       ///< First time within 2 cm of the pre-grasp point [s].
  int lost = 0, reacquired = 0, frames = 0, measured = 0, rejected = 0;
  double reacquire_time = 0.0;  ///< Sum of the times from reacquisition back to within 2 cm [s].
  int reacquire_count = 0;
  double hold_speed = 0.0;  ///< Largest joint reference speed 0.5 s after a target was lost [rad/s].
  long allocations = 0, control_cycles = 0;
  std::vector<double> latencies;  ///< Stamp of each estimate used -> its first torque [s].
  // Grasping.
  bool grasped = false;
  double grasp_at = -1.0;
  double put_down = 0.0;      ///< When the grasping run's path ends (the can put down) [s].
  double interrupted = -1.0;  ///< When the controller left tracking on its own and following ended [s] (−1: never).
  std::string interruption;   ///< Its status.
  int grasp_requests = 0;
};

std::string format(const Eigen::VectorXd& v) {
  std::ostringstream out;
  out.precision(3);
  out << v.transpose();
  return out.str();
}

class Rig {
 public:
  Rig(bs::sim::SimConfig config, const Settings& settings, bool grasp, std::uint32_t seed)
      : config_(std::move(config)),
        settings_(settings),
        simulation_(config_),
        camera_(bs::tasks::rendererFor(config_), bs::tasks::rgbdCameraFor(config_)),
        rng_(seed) {
    if (simulation_.resetToStart() != bs::sim::SimStatus::Ok) {  // where bullet_sim starts them
      throw std::invalid_argument("the robot file's start postures are refused by the simulation");
    }
    object_ = camera_.addMovingSolid(bs::tasks::sceneSolid(config_.object.body));
    bs::tracking::ObjectTrackerConfig tracker;
    // The object as the scene has it: its shape, size and colour (nothing assumed of a can).
    tracker.locator.shape = bs::tasks::sceneSolid(config_.object.body);
    tracker.locator.hue = bs::vision::hueOf(tracker.locator.shape.colour);
    tracker_ = std::make_unique<bs::tracking::ObjectTracker>(tracker);
    for (int a = 0; a < 2; ++a) {
      models_.push_back(std::make_unique<bs::kinematics::ChainModel>(simulation_.armModel(a)));
      bs::control::ArmControllerConfig c;
      c.gains.kp = config_.kp;
      c.gains.kv = config_.kv;
      c.observer = bs::control::ObserverGains::diagonal(models_.back()->nq(), 10.0, 0.0, 100.0, 0.0, 10.0);
      c.observer.rate_hz = 1.0 / simulation_.stepSize();
      controllers_.push_back(std::make_unique<bs::control::RealtimeArmController>(
          *models_.back(), bs::dynamics::loadFrictionModel(config_.arms[static_cast<std::size_t>(a)].friction_file),
          c));
    }
    bs::control::TargetFollowerConfig follow;
    follow.base = simulation_.basePose(0);
    follow.grasp_offset = config_.object.grasp_point;
    pregrasp_ = follow.pregrasp;
    controllers_[0]->enableFollowing(follow);
    bs::control::ControllerCommand start;
    start.kind = bs::control::ControllerCommand::Kind::Follow;
    start.grasp = grasp;
    controllers_[0]->command(start);
    for (int a = 0; a < 2; ++a) states_.emplace_back(simulation_.jointCount(a));
    torque_.setZero(simulation_.jointCount(0));
  }

  /// Runs until `seconds` or `done` says so.
  void run(double seconds, PathResult& result, bool grasp) {
    const long steps = std::lround(seconds / simulation_.stepSize());
    double next_frame = 0.0, last_sample = -1.0, lost_at = -1.0, reacquired_at = -1.0;
    bool was_tracking = false;
    struct Pending {
      double due;
      bs::control::FollowTarget target;
    };
    std::vector<Pending> pending;
    pending.reserve(16);
    double last_stamp = std::nan("");
    for (long k = 0; k < steps; ++k) {
      const double t = simulation_.time();
      if (t >= next_frame - 1e-9) {  // a camera frame: rendered where the object is, tracked
        camera_.setMovingPose(object_, simulation_.objectPose());
        (void)camera_.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0), rng_);
        const bs::tracking::TrackedState& s = tracker_->frame(t, camera_.bgr(), camera_.depth(), camera_.camera());
        bs::control::FollowTarget target;
        target.stamp = t;
        target.tracking = s.tracking;
        target.position = s.position;
        target.velocity = s.velocity;
        target.measured = s.last_accepted;
        pending.push_back({t + settings_.latency, target});
        next_frame += 1.0 / kCameraRate;
        if (was_tracking && !s.tracking) {
          ++result.lost;
          lost_at = t;
        }
        if (!was_tracking && s.tracking && result.frames > 0) {
          ++result.reacquired;
          reacquired_at = t;
        }
        was_tracking = s.tracking;
        ++result.frames;
      }
      while (!pending.empty() && pending.front().due <= t + 1e-9) {
        controllers_[0]->setTarget(pending.front().target);
        pending.erase(pending.begin());
      }
      for (int a = 0; a < 2; ++a) (void)simulation_.readJointState(a, states_[static_cast<std::size_t>(a)]);
      {
        // The control cycle, its allocations counted.
        const bs::testing::AllocationCounter counter;
        for (int a = 0; a < 2; ++a) {
          const bs::sim::JointState& s = states_[static_cast<std::size_t>(a)];
          (void)controllers_[static_cast<std::size_t>(a)]->update(t, s.time, s.position, s.velocity, s.effort, torque_);
          (void)simulation_.writeJointTorques(a, torque_);
        }
        result.allocations += static_cast<long>(counter.allocations());
      }
      ++result.control_cycles;
      if (simulation_.step() == bs::sim::SimStatus::ArmDiverged) break;
      const bs::control::ArmControllerState* state = controllers_[0]->latestState();
      if (!state) continue;
      if (state->follow_interrupted && result.interrupted < 0.0) {
        result.interrupted = simulation_.time();
        result.interruption = bs::control::toString(state->follow_stopped);
        std::fprintf(stderr, "path %d (%s): following ended at t = %.3f s: %s; q %s, qd %s\n", result.path,
                     grasp ? "grasping" : "following", result.interrupted, result.interruption.c_str(),
                     format(state->position).c_str(), format(state->velocity).c_str());
      }
      if (std::isfinite(state->follow_target_stamp) && state->follow_target_stamp != last_stamp &&
          std::isfinite(state->follow_latency)) {
        result.latencies.push_back(state->follow_latency);
        last_stamp = state->follow_target_stamp;
      }
      if (state->grasp_requested) {
        bool held = false;
        (void)simulation_.grasp(0, nullptr, &held);
        controllers_[0]->graspDone(held);
        ++result.grasp_requests;
        if (held) {
          result.grasped = true;
          result.grasp_at = simulation_.time();
        }
      }
      if (grasp) {
        if (result.grasped && simulation_.time() > result.grasp_at + 1.0) break;  // held on for a second
        continue;
      }
      const double now = simulation_.time();
      const bs::sim::ObjectPathSample truth = simulation_.objectPath().at(now);
      const Eigen::Vector3d goal = truth.position + config_.object.grasp_point + pregrasp_;
      const double error = (simulation_.toolPose(0).translation() - goal).norm();
      if (result.reached < 0.0 && error < 0.02) result.reached = now;
      if (reacquired_at >= 0.0 && error < 0.02) {
        result.reacquire_time += now - reacquired_at;
        ++result.reacquire_count;
        reacquired_at = -1.0;
      }
      if (lost_at >= 0.0 && now >= lost_at + 0.5) {
        result.hold_speed = std::max(result.hold_speed, state->desired_velocity.cwiseAbs().maxCoeff());
        lost_at = -1.0;
      }
      const bool following =
          state->following && state->follow_phase == bs::control::FollowPhase::Following && state->follow_offset >= 1.0;
      if (following && result.reached >= 0.0 && !truth.away && now - last_sample >= 0.01 - 1e-9) {
        result.errors.push_back(error);
        result.speeds.push_back(truth.velocity.norm());
        last_sample = now;
      }
    }
    const bs::tracking::TrackedState& last = tracker_->last();
    result.measured = static_cast<int>(last.measured);
    result.rejected = static_cast<int>(last.rejected);
  }

  double objectPathEnd() const { return simulation_.objectPath().end(); }

 private:
  bs::sim::SimConfig config_;
  Settings settings_;
  bs::sim::BimanualSimulation simulation_;
  bs::vision::PerspectiveRenderer camera_;
  std::mt19937 rng_;
  int object_ = 0;
  std::unique_ptr<bs::tracking::ObjectTracker> tracker_;
  std::vector<std::unique_ptr<bs::kinematics::ChainModel>> models_;
  std::vector<std::unique_ptr<bs::control::RealtimeArmController>> controllers_;
  std::vector<bs::sim::JointState> states_;
  Eigen::VectorXd torque_;
  Eigen::Vector3d pregrasp_;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::lround(p * static_cast<double>(v.size() - 1)))];
}

double mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return v.empty() ? std::nan("") : sum / static_cast<double>(v.size());
}

std::string number(double v) {
  return bs::io::exactNumber(v);
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  Settings settings;
  bs::bench::ExperimentProgram program;
  program.name = kProgram;
  program.description =
      "Compliant object tracking (thesis Sec. 4.3.2): the left WAM follows the scene's object (a can by default)\n"
      "carried along seeded paths, seen by a Kinect-like RGB-D camera and tracked by its colour, shape and size as\n"
      "the scene gives them, and grasps it; tracking error by object speed, lost and reacquired\n"
      "targets, grasp success. Writes paths.csv (a record per path, resumable), samples.csv, summary.json, PNGs.";
  program.experiments = {"tracking"};
  program.with_runs = true;
  program.with_jobs = true;
  std::string scene_option;
  program.extra = [&settings, &scene_option](bs::cli::CommandLine& line) {
    line.option("--scene", "FILE", "the simulation file with the object (default: the package's config/track_sim.yaml)",
                &scene_option);
    line.option("--latency", "S", "frame stamp to the estimate in the controller [s] (default 0.010)",
                &settings.latency);
  };
  const bs::bench::ExperimentOptions options = bs::bench::parseExperimentOptions(argc, argv, program);
  if (!(settings.latency >= 0.0 && settings.latency <= 1.0)) {
    std::fprintf(stderr, "%s: --latency must lie in [0, 1] s\n", kProgram);
    return 2;
  }
  const int paths = options.runs > 0 ? options.runs : (options.quick ? 2 : 20);
  if (options.quick) {
    settings.follow_time = 10.0;
    settings.carried = 8.0;
    settings.grasp_time = 12.0;
  }
  std::filesystem::create_directories(options.out);
  const std::string scene = scene_option.empty() ? bs::cli::packageFile("config/track_sim.yaml") : scene_option;
  bs::sim::SimConfig base;
  try {
    base = bs::sim::SimConfig::fromYamlFile(scene);
    if (!base.has_object) throw std::invalid_argument(scene + ": the simulation file has no object");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", kProgram, e.what());
    return 2;
  }
  const bs::vision::SceneSolid object = bs::tasks::sceneSolid(base.object.body);
  const std::string object_name = base.object.body.name.empty() ? "object" : base.object.body.name;
  std::printf(
      "%s: %d paths of the %s (%s, hue %.0f deg; %s), seed %u, camera %.0f Hz, estimate latency %.0f ms, %d "
      "jobs\n",
      kProgram, paths, object_name.c_str(),
      object.shape == bs::vision::SceneSolid::Shape::Cylinder ? "a cylinder"
      : object.shape == bs::vision::SceneSolid::Shape::Sphere ? "a sphere"
                                                              : "a box",
      bs::vision::hueOf(object.colour), scene.c_str(), options.seed, kCameraRate, 1e3 * settings.latency, options.jobs);

  // Resume: the paths already in paths.csv are not run again.
  const std::string paths_file = options.out + "/paths.csv";
  std::set<int> done;
  {
    bs::io::dropPartialRecord(paths_file);
    std::ifstream in(paths_file);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      const std::vector<std::string> f = bs::io::splitCsv(line);
      if (!f.empty()) done.insert(bs::io::parseInteger(f[0], paths_file));
    }
  }
  // Samples of a path whose record was not written (a run killed between the two) go: the path runs again.
  const std::string samples_file = options.out + "/samples.csv";
  if (std::filesystem::exists(samples_file)) {
    bs::io::dropPartialRecord(samples_file);
    std::ifstream in(samples_file);
    std::ofstream kept(samples_file + ".tmp");
    std::string line;
    if (std::getline(in, line)) kept << line << '\n';
    while (std::getline(in, line)) {
      const std::vector<std::string> f = bs::io::splitCsv(line);
      if (!f.empty() && done.count(bs::io::parseInteger(f[0], samples_file))) kept << line << '\n';
    }
    kept.close();
    std::filesystem::rename(samples_file + ".tmp", samples_file);
  }
  const std::string header =
      "path,path_seed,frames,measured,rejected,reached_s,samples,error_mean_m,error_p95_m,error_max_m,lost,reacquired,"
      "reacquire_time_s,hold_speed_rad_s,latency_median_s,latency_p99_s,allocations,control_cycles,grasped,grasp_at_s,"
      "grasp_requests,put_down_s,ended_s,ended,seed";
  bs::io::CsvAppender records(paths_file, header);
  bs::io::CsvAppender samples(samples_file, "path,error_m,speed_m_s");
  std::mutex write;
  const double start = bs::realtime::monotonicSeconds();
  bs::parallel::parallelFor(static_cast<std::size_t>(paths), options.jobs, [&](int, std::size_t i) {
    const int path = static_cast<int>(i);
    if (done.count(path)) return;
    bs::sim::SimConfig config = base;
    const std::uint32_t path_seed = options.seed * 1000u + static_cast<std::uint32_t>(path);
    config.object.path.seed = path_seed;
    config.object.path.duration = settings.follow_time;
    PathResult r;
    r.path = path;
    r.seed = path_seed;
    {
      Rig follow(config, settings, false, path_seed);
      follow.run(settings.follow_time, r, false);
    }
    {
      PathResult g;
      g.path = path;
      config.object.path.duration = settings.carried;
      Rig grasp(config, settings, true, path_seed + 7u);
      grasp.run(settings.grasp_time, g, true);
      r.put_down = grasp.objectPathEnd();
      r.grasped = g.grasped;
      r.allocations += g.allocations;
      if (r.interrupted < 0.0 && g.interrupted >= 0.0) {
        r.interrupted = g.interrupted;
        r.interruption = "grasping: " + g.interruption;
      } else if (r.interrupted >= 0.0) {
        r.interruption = "following: " + r.interruption;
      }
      r.control_cycles += g.control_cycles;
      r.grasp_at = g.grasp_at;
      r.grasp_requests = g.grasp_requests;
    }
    std::ostringstream row;
    row << path << ',' << path_seed << ',' << r.frames << ',' << r.measured << ',' << r.rejected << ','
        << number(r.reached) << ',' << r.errors.size() << ',' << number(mean(r.errors)) << ','
        << number(percentile(r.errors, 0.95)) << ',' << number(percentile(r.errors, 1.0)) << ',' << r.lost << ','
        << r.reacquired << ',' << number(r.reacquire_count ? r.reacquire_time / r.reacquire_count : std::nan("")) << ','
        << number(r.hold_speed) << ',' << number(percentile(r.latencies, 0.5)) << ','
        << number(percentile(r.latencies, 0.99)) << ',' << r.allocations << ',' << r.control_cycles << ','
        << (r.grasped ? 1 : 0) << ',' << number(r.grasp_at) << ',' << r.grasp_requests << ',' << number(r.put_down)
        << ',' << number(r.interrupted) << ',' << bs::io::quotedField(r.interruption) << ',' << options.seed;
    std::ostringstream sample_rows;
    for (std::size_t k = 0; k < r.errors.size(); ++k) {
      sample_rows << path << ',' << number(r.errors[k]) << ',' << number(r.speeds[k])
                  << (k + 1 < r.errors.size() ? "\n" : "");
    }
    const std::lock_guard<std::mutex> lock(write);
    if (!r.errors.empty()) samples.append(sample_rows.str());
    records.append(row.str());
    if (r.measured == 0) {
      std::printf(
          "%s: path %d (seed %u): the %s was never seen in %d frames (its colour, shape and size as the scene "
          "gives them were not found), so nothing was tracked; %s\n",
          kProgram, path, path_seed, object_name.c_str(), r.frames, r.grasped ? "grasped" : "not grasped");
    } else {
      std::printf("%s: path %d (seed %u): error p95 %.1f mm over %zu samples, lost %d, reacquired %d, %s%s\n", kProgram,
                  path, path_seed, 1e3 * percentile(r.errors, 0.95), r.errors.size(), r.lost, r.reacquired,
                  r.grasped ? "grasped at t = " : "not grasped",
                  r.grasped ? (std::to_string(r.grasp_at) + " s").c_str() : "");
    }
    std::fflush(stdout);
  });

  // The summary, from every record in the files (this run's and earlier ones').
  std::vector<std::vector<std::string>> rows;
  {
    std::ifstream in(paths_file);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) rows.push_back(bs::io::splitCsv(line));
  }
  std::vector<double> errors, speeds;
  {
    std::ifstream in(samples_file);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      const std::vector<std::string> f = bs::io::splitCsv(line);
      if (f.size() < 3) continue;
      errors.push_back(bs::io::parseNumber(f[1], "samples.csv"));
      speeds.push_back(bs::io::parseNumber(f[2], "samples.csv"));
    }
  }
  std::vector<bs::io::JsonRow> summary;
  int grasped = 0, never_seen = 0;
  long allocations = 0;
  for (const auto& f : rows) {
    grasped += f[18] == "1";
    allocations += bs::io::parseInteger(f[16], paths_file);
    never_seen += bs::io::parseInteger(f[3], paths_file) == 0;  // measured
  }
  for (std::size_t b = 0; b + 1 < kSpeedBins.size(); ++b) {
    std::vector<double> in_bin;
    for (std::size_t k = 0; k < errors.size(); ++k) {
      if (speeds[k] >= kSpeedBins[b] && speeds[k] < kSpeedBins[b + 1]) in_bin.push_back(errors[k]);
    }
    bs::io::JsonRow row;
    row.add("table", "error_by_speed")
        .add("speed_from", kSpeedBins[b])
        .add("speed_to", std::min(kSpeedBins[b + 1], 10.0))
        .add("samples", static_cast<long>(in_bin.size()))
        .add("error_mean_m", mean(in_bin))
        .add("error_p95_m", percentile(in_bin, 0.95))
        .add("error_max_m", percentile(in_bin, 1.0));
    summary.push_back(row);
  }
  std::vector<double> upto;
  for (std::size_t k = 0; k < errors.size(); ++k) {
    if (speeds[k] <= 0.2) upto.push_back(errors[k]);
  }
  bs::io::JsonRow total;
  total.add("table", "paths")
      .add("paths", static_cast<long>(rows.size()))
      .add("object", object_name)
      .add("paths_object_never_seen", never_seen)
      .add("grasped", grasped)
      .add("grasp_success", rows.empty() ? 0.0 : static_cast<double>(grasped) / static_cast<double>(rows.size()))
      .add("error_p95_up_to_0_2_m_s", percentile(upto, 0.95))
      .add("control_allocations", allocations)
      .add("latency_model_s", settings.latency)
      .add("wall_s", bs::realtime::monotonicSeconds() - start);
  summary.push_back(total);
  bs::bench::writeSummaryJson(options, kProgram, summary);
  if (never_seen > 0) {
    std::printf("%s: the %s was never seen on %d of %zu paths (its colour, shape and size as the scene gives them)\n",
                kProgram, object_name.c_str(), never_seen, rows.size());
  }
  std::printf(
      "%s: %zu paths, grasped %d; tracking error p95 %.1f mm at object speeds <= 0.2 m/s over %zu samples; "
      "%ld allocations in the control loop\n",
      kProgram, rows.size(), grasped, 1e3 * percentile(upto, 0.95), upto.size(), allocations);
  bs::bench::runPlotScript(kProgram, "plot_track_benchmark.py", options.out);
  return 0;
}
