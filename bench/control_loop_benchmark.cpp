// control_loop_benchmark: the control loop of the simulated robot as its ROS nodes run it, under a competing load.
//   loop:   for each design, with and without a SCHED_FIFO priority, R runs (default 5) of S s: the loop period
//           (median, p99, p99.9 and the jitter |T - 1 ms|) and the time from a trajectory message to the first
//           torque computed with it, beside the machine's noise floor (a bare 1 kHz clock_nanosleep loop under the
//           same load, measured in each run); the p99.9 jitter beyond the floor over the runs with a t interval:
//             hosted:      bullet_sim's loop thread runs both controllers (read state, update, write torque);
//             per_message: ctc_controller processes compute one step per joint-state message (the design before).
//           Allocations in the hosted loop's control part come from the node's own counter.
//   pacing: bullet_sim free-running at real time with the cloth: the real-time factor measured on /clock after
//           start, a pause, a reset and a step.
//   services: bullet_sim's ~pause, ~step, ~grasp and ~reset answer times as the robot path calls them
//           (ros_layer::ServiceCaller: persistent connections) beside plain non-persistent roscpp calls (the robot
//           path's calls before, the baseline), with a second simulator and a learner busy on the same cores (on a
//           ROS master of their own): median, p99, max and the calls that returned without an answer.
// It starts a ROS master of its own when none answers, and the nodes with roslaunch (launch/sim.launch; the loop
// experiment without the cloth: config/sim_arms.yaml). Writes DIR/summary.json, DIR/loop.csv (one row per
// configuration and run), DIR/periods_*.csv (pooled over the runs), DIR/pacing.csv and
// (scripts/plot_control_loop_benchmark.py) DIR/periods.png and DIR/tables.md.
#include "bimanual_skills/learning/student_t.hpp"
#include "bimanual_skills/realtime/loop_pacer.hpp"
#include "bimanual_skills/realtime/period_recorder.hpp"
#include "cli/package_share.hpp"
#include "experiment_cli.hpp"
#include "ros_processes.hpp"

#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>

#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"

#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;
namespace rt = bimanual_skills::realtime;

namespace {

constexpr double kPeriod = 0.001;  ///< The loop's period [s].

/// A competing load: `threads` threads (normal priority) streaming through 8 MB each and computing, until stopped.
class Load {
 public:
  explicit Load(int threads) {
    for (int t = 0; t < threads; ++t) {
      threads_.emplace_back([this] {
        std::vector<double> buffer(1 << 20, 1.0);
        double sink = 0.0;
        while (!stop_) {
          for (std::size_t i = 0; i < buffer.size(); i += 8) {
            buffer[i] = std::sqrt(buffer[i] + sink * 1e-9);
            sink += buffer[i];
          }
        }
        sink_ = sink;
      });
    }
  }
  ~Load() {
    stop_ = true;
    for (auto& t : threads_) t.join();
  }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<double> sink_{0.0};
  std::vector<std::thread> threads_;
};

/// The bare loop: clock_nanosleep to absolute 1 ms deadlines for `seconds`, at `priority` (0: normal).
std::vector<double> noiseFloor(double seconds, int priority) {
  std::vector<double> periods;
  std::thread loop([&] {
    if (priority > 0) rt::requestRealtimeScheduling(priority);
    rt::LoopPacer pacer(kPeriod);
    const double end = bimanual_skills::realtime::monotonicSeconds() + seconds;
    double last = 0.0;
    periods.reserve(static_cast<std::size_t>(seconds / kPeriod) + 100);
    while (bimanual_skills::realtime::monotonicSeconds() < end) {
      while (!pacer.waitUntilDue(0.01)) {
      }
      const double now = bimanual_skills::realtime::monotonicSeconds();
      if (last > 0.0) periods.push_back(now - last);
      last = now;
      pacer.advance();
    }
  });
  loop.join();
  return periods;
}

/// The series of a statistics file (series,value). \throws std::runtime_error when the node wrote none.
std::map<std::string, std::vector<double>> readStatistics(const std::string& path) {
  std::map<std::string, std::vector<double>> series;
  std::ifstream in(path);
  if (!in) throw std::runtime_error("the node wrote no statistics to " + path + " (see its log)");
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    const std::size_t comma = line.find(',');
    if (comma == std::string::npos) continue;
    series[line.substr(0, comma)].push_back(std::stod(line.substr(comma + 1)));
  }
  return series;
}

struct LoopFigures {
  rt::PeriodSummary period, jitter, latency;
  std::size_t commands_sent = 0, commands_matched = 0;
  double control_allocations = std::nan(""), cycles = std::nan("");
};

/// Period, jitter and latency figures; the latencies (first command taken after each one sent) also into `latencies`.
LoopFigures figures(std::vector<double> periods, const std::vector<double>& sent, std::vector<double> taken,
                    std::vector<double>* latencies = nullptr) {
  LoopFigures f;
  std::vector<double> jitter;
  for (double p : periods) jitter.push_back(std::abs(p - kPeriod));
  f.period = rt::summarize(periods);
  f.jitter = rt::summarize(jitter);
  std::sort(taken.begin(), taken.end());
  std::vector<double> latency;
  for (double t : sent) {
    const auto first = std::lower_bound(taken.begin(), taken.end(), t);
    if (first != taken.end() && *first - t < 0.5) latency.push_back(*first - t);
  }
  f.commands_sent = sent.size();
  f.commands_matched = latency.size();
  if (latencies) *latencies = latency;
  f.latency = rt::summarize(latency);
  return f;
}

/// Runs sim.launch in one design for `seconds` under the load, sending trajectories to the left arm at 5 Hz.
LoopFigures runDesign(const std::string& design, int priority, double seconds, const std::string& dir,
                      const std::string& log, int load_threads, std::vector<double>& periods,
                      std::vector<double>& latencies) {
  std::filesystem::create_directories(dir);
  std::vector<double> sent;
  {
    bs::bench::Child launch({"roslaunch", "bimanual_skills", "sim.launch",
                             "sim_config:=" + bimanual_skills::cli::packageFile("config/sim_arms.yaml"),
                             "external_controllers:=" + std::string(design == "per_message" ? "true" : "false"),
                             "loop_priority:=" + std::to_string(priority), "statistics_dir:=" + dir},
                            log);
    ros::NodeHandle node;
    ros::Publisher command = node.advertise<trajectory_msgs::JointTrajectory>("/left/command", 10);
    const auto state = ros::topic::waitForMessage<sensor_msgs::JointState>("/joint_states", node, ros::Duration(60.0));
    if (!state) throw std::runtime_error(design + ": no joint states from the simulation (see " + log + ")");
    for (int i = 0; i < 300 && command.getNumSubscribers() == 0; ++i) ros::WallDuration(0.02).sleep();
    ros::WallDuration(1.0).sleep();  // controllers started
    std::vector<double> q0(7);
    for (int i = 0; i < 7; ++i) {
      const auto it = std::find(state->name.begin(), state->name.end(), "left_wam_joint" + std::to_string(i + 1));
      q0[i] = state->position[static_cast<std::size_t>(it - state->name.begin())];
    }
    const Load load(load_threads);
    const double end = bimanual_skills::realtime::monotonicSeconds() + seconds;
    for (int k = 0; bimanual_skills::realtime::monotonicSeconds() < end; ++k) {
      trajectory_msgs::JointTrajectory t;
      for (int i = 1; i <= 7; ++i) t.joint_names.push_back("left_wam_joint" + std::to_string(i));
      trajectory_msgs::JointTrajectoryPoint p;
      p.positions = q0;
      p.positions[0] += k % 2 == 0 ? 0.1 : -0.1;
      p.time_from_start = ros::Duration(0.5);
      t.points.push_back(p);
      sent.push_back(bimanual_skills::realtime::monotonicSeconds());
      command.publish(t);
      ros::WallDuration(0.2).sleep();
    }
  }  // roslaunch stops the nodes, which write their statistics
  const auto stats = readStatistics(dir + (design == "hosted" ? "/bullet_sim.csv" : "/ctc_controller_left.csv"));
  const auto get = [&stats](const std::string& key) {
    const auto it = stats.find(key);
    return it == stats.end() ? std::vector<double>{} : it->second;
  };
  // Only the periods while the load ran (the last `seconds` of the run) count.
  periods = get("period");
  const std::size_t keep = std::min(periods.size(), static_cast<std::size_t>(seconds / kPeriod));
  periods.erase(periods.begin(), periods.end() - static_cast<std::ptrdiff_t>(keep));
  LoopFigures f = figures(periods, sent, get("command_taken"), &latencies);
  if (design == "hosted") {
    f.control_allocations = get("control_allocations").empty() ? std::nan("") : get("control_allocations")[0];
    f.cycles = get("cycles").empty() ? std::nan("") : get("cycles")[0];
  }
  return f;
}

/// The real-time factor on /clock over `seconds` of wall time.
double realtimeFactor(double seconds) {
  std::mutex mutex;
  std::vector<std::pair<double, double>> samples;
  ros::NodeHandle node;
  ros::Subscriber clock =
      node.subscribe<rosgraph_msgs::Clock>("/clock", 1000, [&](const rosgraph_msgs::Clock::ConstPtr& m) {
        const std::lock_guard<std::mutex> lock(mutex);
        samples.emplace_back(bimanual_skills::realtime::monotonicSeconds(), m->clock.toSec());
      });
  ros::WallDuration(seconds).sleep();
  clock.shutdown();
  const std::lock_guard<std::mutex> lock(mutex);
  if (samples.size() < 10) return std::nan("");
  return (samples.back().second - samples.front().second) / (samples.back().first - samples.front().first);
}

/// Median, p99 and max of `times` [s].
struct Times {
  double median = 0.0, p99 = 0.0, max = 0.0;
};
Times timesOf(std::vector<double> times) {
  Times t;
  if (times.empty()) return t;
  std::sort(times.begin(), times.end());
  t.median = times[times.size() / 2];
  t.p99 = times[std::min(times.size() - 1, times.size() * 99 / 100)];
  t.max = times.back();
  return t;
}

/// The services experiment (see the file comment).
void serviceTimes(const bs::bench::ExperimentOptions& options, const std::string& log,
                  std::vector<bs::bench::JsonRow>& rows) {
  const int rounds = options.quick ? 20 : 200;
  bs::bench::Child simulator({"roslaunch", "bimanual_skills", "sim.launch"}, log);
  // The load on the same cores: a second simulator and a learner folding in-process, on a master of their own.
  const int port = 12711 + static_cast<int>(::getpid() % 1000);
  const std::string other = "ROS_MASTER_URI=http://localhost:" + std::to_string(port);
  bs::bench::Child other_master({"rosmaster", "--core", "-p", std::to_string(port)}, log);
  for (int i = 0; i < 100 && !bs::bench::listening(port); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  bs::bench::Child other_simulator(
      {"env", other, "roslaunch", "-p", std::to_string(port), "bimanual_skills", "sim.launch", "realtime_factor:=0"},
      log);
  bs::bench::Child learner({"env", other, "roslaunch", "-p", std::to_string(port), "bimanual_skills", "fold.launch",
                            "out:=" + options.out + "/busy_learner", "jobs:=1"},
                           log);
  ros::NodeHandle node;
  if (!ros::topic::waitForMessage<sensor_msgs::JointState>("/joint_states", node, ros::Duration(60.0))) {
    throw std::runtime_error("services: no joint states from the simulation (see " + log + ")");
  }
  std::this_thread::sleep_for(std::chrono::seconds(5));  // the load has started
  bs::ros_layer::ServiceCaller caller(node);
  std::map<std::string, std::vector<double>> times;  // "method service" -> answer times [s]
  std::map<std::string, int> lost;                   // calls without an answer
  std::ofstream csv(options.out + "/services.csv");
  csv << "method,service,round,answer_s,answered\n";
  const auto timed = [&](const std::string& method, const std::string& service, int round, const auto& call) {
    const double start = rt::monotonicSeconds();
    const bool answered = call();
    const double seconds = rt::monotonicSeconds() - start;
    const std::string key = method + " " + service;
    if (answered) {
      times[key].push_back(seconds);
    } else {
      ++lost[key];
    }
    csv << method << ',' << service << ',' << round << ',' << seconds << ',' << (answered ? 1 : 0) << '\n';
  };
  // One round: pause, 20 steps, a gripper opening, resume; every 20th round a reset. Each request by the robot
  // path's caller, then by a plain non-persistent call.
  for (int round = 0; round < rounds; ++round) {
    for (const std::string method : {"persistent", "non_persistent"}) {
      const bool persistent = method == "persistent";
      const auto ask = [&](const std::string& name, auto& request) {
        if (persistent) return caller.call(name, request, 10.0) == bs::ros_layer::CallOutcome::Answered;
        ros::ServiceClient client = node.serviceClient<std::remove_reference_t<decltype(request)>>(name);
        return client.call(request);
      };
      std_srvs::SetBool pause;
      pause.request.data = true;
      timed(method, "pause", round, [&] { return ask("/bullet_sim/pause", pause); });
      bimanual_skills::SimStep step;
      step.request.steps = 20;
      timed(method, "step", round, [&] { return ask("/bullet_sim/step", step); });
      bimanual_skills::ClothGrasp grasp;
      grasp.request.arm = "left";
      grasp.request.grasp = false;
      timed(method, "grasp", round, [&] { return ask("/bullet_sim/grasp", grasp); });
      pause.request.data = false;
      timed(method, "resume", round, [&] { return ask("/bullet_sim/pause", pause); });
      if (round % 20 == 0) {
        std_srvs::Trigger reset;
        timed(method, "reset", round, [&] { return ask("/bullet_sim/reset", reset); });
      }
    }
  }
  for (const auto& [key, values] : times) {
    const Times t = timesOf(values);
    const std::size_t space = key.find(' ');
    std::printf(
        "  services: %-15s %-7s %4zu answers: median %6.2f ms, p99 %6.2f ms, max %7.2f ms; %d without an "
        "answer\n",
        key.substr(0, space).c_str(), key.substr(space + 1).c_str(), values.size(), 1e3 * t.median, 1e3 * t.p99,
        1e3 * t.max, lost[key]);
    rows.emplace_back()
        .add("experiment", "services")
        .add("method", key.substr(0, space))
        .add("service", key.substr(space + 1))
        .add("answers", static_cast<double>(values.size()))
        .add("without_answer", static_cast<double>(lost[key]))
        .add("answer_median_s", t.median)
        .add("answer_p99_s", t.p99)
        .add("answer_max_s", t.max);
  }
}

}  // namespace

int main(int argc, char** argv) {
  long load_threads = 2, runs_option = 0;
  double duration = -1.0;
  std::string priorities_text = "0,80";
  const bs::bench::ExperimentProgram program{
      "control_loop_benchmark",
      "The control loop of the simulated robot as its nodes run it: loop period, jitter beyond the machine's noise\n"
      "floor and trajectory-to-torque latency under a competing load, hosted in bullet_sim's loop against\n"
      "ctc_controller processes driven by joint-state messages; the simulator's real-time factor after pause,\n"
      "reset and step; and its services' answer times with a second simulator and a learner busy beside it.",
      {"loop", "pacing", "services", "all"},
      false,
      false,
      [&](bs::cli::CommandLine& line) {
        line.option("--load-threads", "N", "threads of competing load during the loop experiment (default 2)",
                    &load_threads, 0, 64);
        line.option("--seconds", "S",
                    "seconds per run of each configuration of the loop experiment (default 20, --quick 3)", &duration);
        line.option("--repeat", "R", "runs of each configuration of the loop experiment (default 5, --quick 1)",
                    &runs_option, 1, 1000);
        line.option("--priorities", "LIST",
                    "SCHED_FIFO priorities of the loop threads, 0 for none (default 0,80; --quick 0)",
                    &priorities_text);
      }};
  const bs::bench::ExperimentOptions options = bs::bench::parseExperimentOptions(argc, argv, program);
  try {
    std::filesystem::create_directories(options.out);
    const std::string log = options.out + "/ros.log";
    const std::unique_ptr<bs::bench::Child> master = bs::bench::ensureMaster(log, program.name);
    int ros_argc = 1;
    ros::init(ros_argc, argv, "control_loop_benchmark",
              ros::init_options::AnonymousName | ros::init_options::NoSigintHandler);
    ros::AsyncSpinner spinner(1);
    spinner.start();
    if (duration == 0.0 || duration < -1.0) throw std::invalid_argument("--seconds must be > 0");
    const double seconds = duration > 0.0 ? duration : options.quick ? 3.0 : 20.0;
    const int runs = runs_option > 0 ? static_cast<int>(runs_option) : options.quick ? 1 : 5;
    std::vector<int> priorities;
    {
      std::stringstream list(options.quick && priorities_text == "0,80" ? "0" : priorities_text);
      for (std::string item; std::getline(list, item, ',');) {
        const int p = std::atoi(item.c_str());
        if (p < 0 || p > 99 || item.empty()) throw std::invalid_argument("--priorities: " + item + " is not in 0-99");
        priorities.push_back(p);
      }
    }
    std::printf(
        "control_loop_benchmark: seed %u (nothing random), %d run(s) of %.0f s per configuration, %ld load "
        "thread(s), node logs in %s\n",
        options.seed, runs, seconds, load_threads, log.c_str());
    std::vector<bs::bench::JsonRow> rows;
    const auto runs_experiment = [&options](const char* name) {
      return options.experiment == "all" || options.experiment == name;
    };
    if (runs_experiment("loop")) {
      std::ofstream csv(options.out + "/loop.csv");
      csv << "design,priority,run,samples,period_median_s,period_p99_s,period_p999_s,period_max_s,jitter_p99_s,"
             "jitter_p999_s,jitter_p999_beyond_floor_s,latency_median_s,latency_p99_s,latency_max_s,commands,"
             "control_allocations,cycles\n";
      const std::vector<std::string> designs = {"noise_floor", "hosted", "per_message"};
      for (const int priority : priorities) {
        std::map<std::string, std::vector<double>> pooled_periods, pooled_latency, beyond, allocations;
        for (int run = 1; run <= runs; ++run) {
          double floor_jitter = 0.0;
          for (const std::string& design : designs) {
            LoopFigures f;
            std::vector<double> periods, latencies;
            if (design == "noise_floor") {
              const Load load(static_cast<int>(load_threads));
              periods = noiseFloor(seconds, priority);
              f = figures(periods, {}, {});
              floor_jitter = f.jitter.p999;
            } else {
              const std::string dir =
                  options.out + "/nodes_" + design + "_" + std::to_string(priority) + "_" + std::to_string(run);
              f = runDesign(design, priority, seconds, dir, log, static_cast<int>(load_threads), periods, latencies);
            }
            const double over = f.jitter.p999 - floor_jitter;
            pooled_periods[design].insert(pooled_periods[design].end(), periods.begin(), periods.end());
            pooled_latency[design].insert(pooled_latency[design].end(), latencies.begin(), latencies.end());
            beyond[design].push_back(over);
            if (!std::isnan(f.control_allocations)) allocations[design].push_back(f.control_allocations);
            std::printf(
                "  run %d %-12s priority %2d: period median %.1f us p99 %.1f p99.9 %.1f max %.1f; jitter "
                "p99.9 %.1f us (%+.1f beyond the floor); latency median %.0f us p99 %.0f (%zu of %zu)%s\n",
                run, design.c_str(), priority, 1e6 * f.period.median, 1e6 * f.period.p99, 1e6 * f.period.p999,
                1e6 * f.period.max, 1e6 * f.jitter.p999, 1e6 * over, 1e6 * f.latency.median, 1e6 * f.latency.p99,
                f.commands_matched, f.commands_sent,
                std::isnan(f.control_allocations)
                    ? ""
                    : (", " + std::to_string(static_cast<long>(f.control_allocations)) + " allocations in " +
                       std::to_string(static_cast<long>(f.cycles)) + " cycles")
                          .c_str());
            std::fflush(stdout);
            csv << design << ',' << priority << ',' << run << ',' << f.period.count << ',' << f.period.median << ','
                << f.period.p99 << ',' << f.period.p999 << ',' << f.period.max << ',' << f.jitter.p99 << ','
                << f.jitter.p999 << ',' << over << ',' << f.latency.median << ',' << f.latency.p99 << ','
                << f.latency.max << ',' << f.commands_matched << ',' << f.control_allocations << ',' << f.cycles << '\n'
                << std::flush;
          }
        }
        // Over the runs: the pooled periods and latencies, and the jitter beyond the floor per run (t interval).
        for (const std::string& design : designs) {
          const LoopFigures pooled = figures(pooled_periods[design], {}, {});
          std::vector<double> latency = pooled_latency[design];
          const rt::PeriodSummary l = rt::summarize(latency);
          const bs::learning::MeanInterval over = bs::learning::meanInterval95(beyond[design]);
          {
            std::ofstream f(options.out + "/periods_" + design + "_" + std::to_string(priority) + ".csv");
            f << "period_s\n";
            for (double p : pooled_periods[design]) f << p << '\n';
          }
          double allocation_total = 0.0;
          for (double a : allocations[design]) allocation_total += a;
          std::printf(
              "%-12s priority %2d, %d runs: period median %.1f us p99 %.1f p99.9 %.1f; jitter p99.9 %.1f us, "
              "beyond the floor %.1f +- %.1f us (t 95 %%); latency median %.0f us p99 %.0f\n",
              design.c_str(), priority, runs, 1e6 * pooled.period.median, 1e6 * pooled.period.p99,
              1e6 * pooled.period.p999, 1e6 * pooled.jitter.p999, 1e6 * over.mean, 1e6 * over.half_width,
              1e6 * l.median, 1e6 * l.p99);
          rows.emplace_back()
              .add("experiment", "loop")
              .add("design", design)
              .add("priority", priority)
              .add("runs", runs)
              .add("seconds_per_run", seconds)
              .add("load_threads", static_cast<int>(load_threads))
              .add("samples", static_cast<double>(pooled.period.count))
              .add("period_median_s", pooled.period.median)
              .add("period_p99_s", pooled.period.p99)
              .add("period_p999_s", pooled.period.p999)
              .add("period_max_s", pooled.period.max)
              .add("jitter_p99_s", pooled.jitter.p99)
              .add("jitter_p999_s", pooled.jitter.p999)
              .add("jitter_p999_beyond_floor_mean_s", over.mean)
              .add("jitter_p999_beyond_floor_ci95_s", over.half_width)
              .add("latency_median_s", design == "noise_floor" ? std::nan("") : l.median)
              .add("latency_p99_s", design == "noise_floor" ? std::nan("") : l.p99)
              .add("latency_samples", static_cast<double>(l.count))
              .add("control_allocations", allocations[design].empty() ? std::nan("") : allocation_total);
        }
      }
    }
    if (runs_experiment("services")) serviceTimes(options, log, rows);
    if (runs_experiment("pacing")) {
      std::ofstream csv(options.out + "/pacing.csv");
      csv << "when,realtime_factor\n";
      bs::bench::Child launch({"roslaunch", "bimanual_skills", "sim.launch"}, log);
      ros::NodeHandle node;
      if (!ros::topic::waitForMessage<sensor_msgs::JointState>("/joint_states", node, ros::Duration(60.0))) {
        throw std::runtime_error("pacing: no joint states from the simulation (see " + log + ")");
      }
      ros::ServiceClient pause = node.serviceClient<std_srvs::SetBool>("/bullet_sim/pause");
      ros::ServiceClient reset = node.serviceClient<std_srvs::Trigger>("/bullet_sim/reset");
      ros::ServiceClient step = node.serviceClient<bimanual_skills::SimStep>("/bullet_sim/step");
      if (!step.waitForExistence(ros::Duration(30.0))) throw std::runtime_error("pacing: no ~step service");
      const double window = options.quick ? 1.0 : 5.0;
      const auto measure = [&](const std::string& when) {
        ros::WallDuration(0.3).sleep();
        const double factor = realtimeFactor(window);
        std::printf("  pacing: real-time factor %-12s %.4f (target 1, over %.0f s of wall time)\n", when.c_str(),
                    factor, window);
        csv << when << ',' << factor << '\n' << std::flush;
        rows.emplace_back()
            .add("experiment", "pacing")
            .add("when", when)
            .add("realtime_factor", factor)
            .add("window_s", window);
      };
      measure("start");
      std_srvs::SetBool paused;
      paused.request.data = true;
      pause.call(paused);
      ros::WallDuration(2.0).sleep();
      paused.request.data = false;
      pause.call(paused);
      measure("after_pause");
      std_srvs::Trigger trigger;
      reset.call(trigger);
      measure("after_reset");
      paused.request.data = true;
      pause.call(paused);
      bimanual_skills::SimStep steps;
      steps.request.steps = 5000;
      step.call(steps);
      paused.request.data = false;
      pause.call(paused);
      measure("after_step");
    }
    bs::bench::writeSummaryJson(options, program.name, rows);
    bs::bench::runPlotScript(program.name, "plot_control_loop_benchmark.py", options.out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "control_loop_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
