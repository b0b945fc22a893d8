// bottles_learner: the simulated WAM learns to pass between two bottles (thesis Sec. 6.2) while rviz watches. A thin
// shell over rollout::DmpLearner and rollout::BottleRolloutTask: it runs the learning on threads, plays each epoch's
// noise-free policy on /joint_states with the bottles where the simulation moved them, shows the last rollouts' tool
// paths, prints the progress and writes the results.
#include "bimanual_skills/rollout/bottle_learning.hpp"
#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/summary_json.hpp"
#include "learner_shell.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills bottles_learner [_config:=FILE] [_out:=DIR] [_jobs:=N] [_runs:=N] [_updates:=N]\n"
    "                                             [_rollouts:=N] [_seed:=S] [_crossing_term:=true|false]\n"
    "                                             [_replay_best:=true|false]\n"
    "\n"
    "The simulated WAM learns to pass between two bottles (thesis Sec. 6.2, Figs. 6.8-6.12): its right arm's tool\n"
    "goes at a fixed height and orientation along a 0.6 m line with two free bottles on it; a DMP of the line's x and\n"
    "y (10 kernels each, fitted to the straight line) learns an S between them by REPS and DREPS (the thesis'\n"
    "settings: epsilon 0.5, 200 rollouts reused, 60^2 I), each rollout CLIK references tracked by the computed-torque\n"
    "controller with friction compensation among bottles that tip. Reward (6.18): -2 per bottle down, -0.15 per metre\n"
    "of the tool's path, -4 unless it passes the bottles on opposite sides; (6.17) without the last term. Rollouts\n"
    "run in parallel, are written to DIR as they finish, and a restarted run resumes where it stopped.\n"
    "\n"
    "Parameters (private):\n"
    "  ~config       learning file (default: the package's config/bottles_learning.yaml)\n"
    "  ~out          results directory (default: bottles_learning in the working directory)\n"
    "  ~jobs, ~runs, ~updates, ~rollouts, ~seed, ~algorithms  instead of the learning file's (a list of\n"
    "                algorithms, e.g. rosparam set bottles_learner/algorithms \"[REPS, DREPS]\")\n"
    "  ~crossing_term  true: reward (6.18); false: (6.17) (default: the learning file's)\n"
    "  ~replay_best  after learning, play the best final policy on the topics in a loop until shut down\n"
    "                (default false: exit when done)\n"
    "\n"
    "Writes into DIR: rollouts.csv, rollout_parameters.csv (every rollout as it finishes), epochs.csv, summary.json\n"
    "(one row per algorithm, run and epoch: the noise-free policy's reward, bottles down, crossing), final_paths.csv\n"
    "(every run's final policy's tool path in the line's frame, as ps_benchmark's wam_bottles_paths.csv).\n"
    "\n"
    "Topics: /joint_states (sensor_msgs/JointState: the latest noise-free policy's motion, played in a loop at\n"
    "  real time), ~scene (visualization_msgs/MarkerArray: the table and the line), ~bottles (MarkerArray: the\n"
    "  bottles where the played motion has them), ~tool_paths (MarkerArray: the last rollouts' measured tool paths,\n"
    "  red = worst to green = best, and the played policy's in blue).\n";

constexpr std::size_t kPathsShown = 12;

/// A rollout's motion as the player shows it.
struct Motion {
  Eigen::MatrixXd joints;                  ///< The moving arm's, joints × samples.
  std::vector<Eigen::Isometry3d> bottles;  ///< 2 per sample.
  Eigen::Matrix3Xd tool;                   ///< The tool's path.
  double period = 0.01;                    ///< [s] between samples.
};

class BottlesLearnerNode {
 public:
  BottlesLearnerNode() : private_node_("~"), parameters_(private_node_, "bottles_learner") {
    const std::string package = ros::package::getPath("bimanual_skills");
    config_path_ = parameters_.text("config", package + "/config/bottles_learning.yaml");
    out_ = parameters_.text("out", "bottles_learning");
    replay_best_ = parameters_.boolean("replay_best", false);
    config_ = br::BottleLearningConfig::fromYamlFile(config_path_);
    br::DmpLearningConfig& l = config_.learning;
    bs::nodes::readLearningParameters(parameters_, l);
    config_.task.crossing_term = parameters_.boolean("crossing_term", config_.task.crossing_term);
    parameters_.warnUnknown();
    l.validate(2);
    task_ = std::make_unique<br::BottleRolloutTask>(config_.task);
    const bt::WamBottleConfig task_config = config_.task;
    auto evaluator = std::make_unique<br::ParallelEvaluator>(
        [task_config] { return std::make_unique<br::BottleRolloutTask>(task_config); }, l.jobs);

    scene_publisher_ = private_node_.advertise<visualization_msgs::MarkerArray>("scene", 1, true);
    bottle_publisher_ = private_node_.advertise<visualization_msgs::MarkerArray>("bottles", 1, true);
    path_publisher_ = private_node_.advertise<visualization_msgs::MarkerArray>("tool_paths", 1, true);
    joint_publisher_ = node_.advertise<sensor_msgs::JointState>("joint_states", 10, true);
    publishScene();

    br::DmpLearningObserver observer;
    observer.rollout = [this](const br::DmpRolloutRecord& record, br::RolloutTask* task) { onRollout(record, task); };
    observer.epoch = [this](const br::DmpEpochStats& s) { onEpoch(s); };
    observer.stop = [] { return !ros::ok(); };
    learner_ =
        std::make_unique<br::DmpLearner>(br::bottleTaskModel(task_->task()), l, out_, std::move(evaluator), observer);
    player_ = std::thread([this] { play(); });
  }

  ~BottlesLearnerNode() {
    stop_ = true;
    if (player_.joinable()) player_.join();
  }
  BottlesLearnerNode(const BottlesLearnerNode&) = delete;
  BottlesLearnerNode& operator=(const BottlesLearnerNode&) = delete;

  void run() {
    const br::DmpLearningConfig& l = config_.learning;
    std::printf(
        "bottles_learner: %zu algorithm(s) x %d run(s) x %d updates x %d rollouts, seed %u, reward (%s), %d jobs, "
        "into %s\n",
        l.algorithms.size(), l.runs, l.updates, l.rollouts, l.seed, config_.task.crossing_term ? "6.18" : "6.17",
        l.jobs, out_.c_str());
    std::fflush(stdout);
    const br::DmpLearningResult result = learner_->learn();
    std::printf("bottles_learner: %d rollouts run, %d taken from %s, %.0f s\n", result.ran, result.resumed,
                out_.c_str(), result.seconds);
    writeSummary(result);
    const br::DmpRolloutRecord* best = writeFinalPaths(result);
    std::fflush(stdout);
    if (!replay_best_ || best == nullptr) return;
    std::printf("bottles_learner: playing %s run %d's final policy (reward %.3f) until shut down\n",
                best->algorithm.c_str(), best->run, best->result.reward);
    std::fflush(stdout);
    while (ros::ok()) ros::WallDuration(0.2).sleep();
  }

 private:
  void publishScene() {
    visualization_msgs::MarkerArray scene;
    const bs::sim::SimConfig& sim = task_->task().simConfig();
    if (sim.has_table) scene.markers.push_back(bs::nodes::tableMarker(sim.table, ros::Time()));
    visualization_msgs::Marker line =
        bs::nodes::worldMarker("line", 0, visualization_msgs::Marker::LINE_STRIP, ros::Time());
    line.scale.x = 0.004;
    line.color.r = line.color.g = line.color.b = 0.3f;
    line.color.a = 1.0f;
    line.points = {bs::nodes::toPoint(config_.task.start), bs::nodes::toPoint(config_.task.goal)};
    scene.markers.push_back(line);
    scene_publisher_.publish(scene);
    const std::vector<bs::sim::Obstacle>& obstacles = sim.obstacles;
    std::vector<Eigen::Isometry3d> standing;
    for (const bs::sim::Obstacle& o : obstacles) {
      if (o.mass > 0.0) standing.push_back(o.pose);
    }
    publishBottles(standing.data());
  }

  /// The two bottles at `poses` (bottle 1's, bottle 2's), red when tilted past the task's angle.
  void publishBottles(const Eigen::Isometry3d* poses) {
    visualization_msgs::MarkerArray array;
    int k = 0;
    for (const bs::sim::Obstacle& o : task_->task().simConfig().obstacles) {
      if (!(o.mass > 0.0) || k > 1) continue;
      bs::sim::Obstacle at = o;
      at.pose = poses[k];
      visualization_msgs::Marker m = bs::nodes::obstacleMarker(at, k, ros::Time());
      m.ns = "bottles";
      const double tilt = std::acos(std::clamp(poses[k].linear()(2, 2), -1.0, 1.0));
      if (tilt > config_.task.tilt) {
        m.color.r = 0.85f;
        m.color.g = 0.15f;
        m.color.b = 0.1f;
      }
      array.markers.push_back(m);
      ++k;
    }
    bottle_publisher_.publish(array);
  }

  void onRollout(const br::DmpRolloutRecord& record, br::RolloutTask* task) {
    if (record.result.trajectory.rows() == 3 && record.result.trajectory.cols() > 1) {
      std::lock_guard<std::mutex> lock(mutex_);
      paths_.push_back({record.result.reward, record.result.trajectory});
      if (paths_.size() > kPathsShown) paths_.erase(paths_.begin());
    }
    const auto* bottles = dynamic_cast<br::BottleRolloutTask*>(task);
    if (bottles != nullptr && record.kind == br::RolloutKind::Policy) show(bottles->lastRollout());
    publishPaths();
  }

  /// The player plays `r` from now on (a rollout that ran to its end).
  void show(const bt::WamBottleRollout& r) {
    if (r.joint_path.cols() < 2 || r.bottle_path.size() != 2 * static_cast<std::size_t>(r.joint_path.cols())) return;
    Motion motion;
    motion.joints = r.joint_path;
    motion.bottles = r.bottle_path;
    motion.tool = r.tool_path;
    motion.period = 1.0 / config_.task.path_rate;
    std::lock_guard<std::mutex> lock(mutex_);
    motion_ = std::move(motion);
    ++motion_version_;
  }

  void publishPaths() {
    std::lock_guard<std::mutex> lock(mutex_);
    visualization_msgs::MarkerArray array = bs::nodes::rankedPathMarkers(paths_, 0.003, 0.7f, ros::Time());
    if (motion_.tool.cols() > 1) {
      visualization_msgs::Marker m = bs::nodes::pathMarker("policy_path", 0, motion_.tool, 0.008, ros::Time());
      m.color.r = 0.1f;
      m.color.g = 0.3f;
      m.color.b = 0.95f;
      m.color.a = 1.0f;
      array.markers.push_back(m);
    }
    path_publisher_.publish(array);
  }

  /// Plays the latest noise-free policy's motion in a loop at real time (25 frames/s) until the node stops.
  void play() {
    const bt::WamBottleTask& task = task_->task();
    const std::vector<Eigen::VectorXd> starts = task.starts();
    Motion motion;
    long version = 0;
    Eigen::Index sample = 0;
    ros::WallRate rate(25.0);
    while (!stop_ && ros::ok()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (motion_version_ != version) {
          motion = motion_;
          version = motion_version_;
          sample = 0;
        }
      }
      if (motion.joints.cols() > 1) {
        sensor_msgs::JointState state;
        state.header.stamp = ros::Time::now();
        for (std::size_t a = 0; a < task.jointNames().size(); ++a) {
          const bool moving = static_cast<int>(a) == task.arm();
          for (std::size_t j = 0; j < task.jointNames()[a].size(); ++j) {
            state.name.push_back(task.jointNames()[a][j]);
            const auto i = static_cast<Eigen::Index>(j);
            state.position.push_back(moving ? motion.joints(i, sample) : starts[a][i]);
          }
        }
        joint_publisher_.publish(state);
        publishBottles(&motion.bottles[static_cast<std::size_t>(2 * sample)]);
        const auto step = std::max<Eigen::Index>(1, static_cast<Eigen::Index>(std::lround(0.04 / motion.period)));
        sample += step;
        if (sample >= motion.joints.cols()) sample = 0;
      }
      rate.sleep();
    }
  }

  void onEpoch(const br::DmpEpochStats& s) {
    const br::DmpLearningConfig& l = config_.learning;
    const auto term = [&](const char* name) {
      const std::vector<std::string> names = br::BottleRolloutTask::names();
      return s.term_means[std::find(names.begin(), names.end(), name) - names.begin()];
    };
    std::printf(
        "bottles_learner: %s run %d/%d epoch %d/%d: noise-free policy reward %.3f%s%s; rollouts %.3f +- %.3f, "
        "%.2f bottles down on average, %d/%d satisfactory, %d failed\n",
        s.algorithm.c_str(), s.run + 1, l.runs, s.epoch, l.updates, s.policy_reward, s.policy_failed ? " (failed)" : "",
        s.policy_success ? " (satisfactory)" : "", s.mean_reward, s.std_reward, term("bottles_down"), s.successes,
        l.rollouts, s.failures);
    std::fflush(stdout);
  }

  void writeSummary(const br::DmpLearningResult& result) const {
    const std::vector<bs::io::JsonRow> rows = bs::nodes::epochRows(
        result, br::BottleRolloutTask::names(), {"reward", "policy_satisfactory", "rollout_satisfactory"});
    bs::io::writeSummaryJson(out_ + "/summary.json",
                             {"bottles_learner", config_.task.crossing_term ? "wam_bottles" : "wam_bottles617",
                              config_.learning.seed, false, bs::cli::numericsState()},
                             rows);
  }

  /// Every run's final policy's measured tool path in the line's frame (DIR/final_paths.csv, the columns of
  /// ps_benchmark's wam_bottles_paths.csv from `algorithm`), the final policies' satisfactory count printed; returns
  /// the best final policy.
  const br::DmpRolloutRecord* writeFinalPaths(const br::DmpLearningResult& result) {
    if (result.runs.empty()) return nullptr;
    std::ofstream csv(out_ + "/final_paths.csv");
    csv << "algorithm,run,outcome,reward,bottles_down,crossed,satisfactory,sample,time,along,left\n";
    br::BottleRolloutTask task(config_.task);
    const double length = task.task().lineLength();
    const br::DmpRunResult* best = nullptr;
    bt::WamBottleRollout best_rollout;
    std::vector<std::pair<std::string, int>> satisfactory;
    for (const br::DmpRunResult& run : result.runs) {
      const br::DmpRolloutRecord& final = run.final_policy;
      task.run(bs::rollout::encodeCoordinatedPolicy(final.coordination, final.weights), final.seed);
      const bt::WamBottleRollout& r = task.lastRollout();
      for (Eigen::Index i = 0; i < r.tool_path.cols(); ++i) {
        const Eigen::Vector2d p = task.task().toLine(r.tool_path.col(i)) * length;
        csv << run.algorithm << ',' << run.run << ',' << bt::toString(r.outcome) << ',' << r.reward << ',' << r.down
            << ',' << (r.crossed ? 1 : 0) << ',' << (r.satisfactory ? 1 : 0) << ',' << i << ',' << r.path_times[i]
            << ',' << p.x() << ',' << p.y() << '\n';
      }
      if (satisfactory.empty() || satisfactory.back().first != run.algorithm)
        satisfactory.push_back({run.algorithm, 0});
      satisfactory.back().second += r.satisfactory ? 1 : 0;
      if (best == nullptr || final.result.reward > best->final_policy.result.reward) {
        best = &run;
        best_rollout = r;
      }
    }
    for (const auto& [algorithm, count] : satisfactory) {
      std::printf("bottles_learner: %s: %d of %d final policies satisfactory (between the bottles, none down)\n",
                  algorithm.c_str(), count, config_.learning.runs);
    }
    show(best_rollout);  // the player shows the best final policy from now on
    std::printf("bottles_learner: results in %s (summary.json, epochs.csv, rollouts.csv, final_paths.csv)\n",
                out_.c_str());
    return best != nullptr ? &best->final_policy : nullptr;
  }

  ros::NodeHandle node_, private_node_;
  bs::ros_layer::ParameterReader parameters_;
  std::string config_path_, out_;
  bool replay_best_ = false;
  br::BottleLearningConfig config_;
  std::unique_ptr<br::BottleRolloutTask> task_;
  std::unique_ptr<br::DmpLearner> learner_;
  ros::Publisher scene_publisher_, bottle_publisher_, path_publisher_, joint_publisher_;
  std::mutex mutex_;  ///< paths_, motion_ between the learning's thread and the player.
  std::vector<std::pair<double, Eigen::Matrix3Xd>> paths_;
  Motion motion_;
  long motion_version_ = 0;
  std::atomic<bool> stop_{false};
  std::thread player_;
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "bottles_learner");
  const ros::NodeHandle keep_alive;
  try {
    BottlesLearnerNode node;
    node.run();
  } catch (const std::exception& e) {
    if (!ros::ok() && std::string(e.what()) == "stopped") {
      ROS_WARN("bottles_learner: stopped; the finished rollouts are on disk, run again to resume");
      return 0;
    }
    ROS_FATAL("bottles_learner: %s", e.what());
    return 1;
  }
  return 0;
}
