// fold_learner: the two simulated WAMs learn to fold the cloth (rollout::FoldLearner) while rviz watches. A thin
// shell: it runs the library's learning, publishes each rollout (cloth, tool paths, camera images, robot), prints
// the progress, and writes the results, the top-down images and a rosbag of the best rollout.
#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/robot/fold_on_robot.hpp"
#include "bimanual_skills/tasks/fold_quality.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/summary_json.hpp"
#include "learner_shell.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <cv_bridge/cv_bridge.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/JointState.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;
namespace vision = bimanual_skills::vision;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills fold_learner [_config:=FILE] [_out:=DIR] [_reward:=fold|thesis|goal] [_jobs:=N]\n"
    "                                          [_policy:=goals|weights] [_covariance_memory:=L]\n"
    "                                          [_replay_best:=true|false]\n"
    "                                          [_worker_namespace:=NS | _workers:=NAME,NAME,...] [_worker_timeout:=S]\n"
    "                                          [_backend:=sim|ros [robot interface parameters]]\n"
    "\n"
    "Two simulated WAMs learn to fold a cloth (thesis Sec. 7.2.3, Table 7.5): DR-DMP policies over both tools,\n"
    "executed by CLIK and computed-torque control on the Bullet simulation, scored on rendered top-down colour and\n"
    "depth images (the fold reward against the flat cloth the camera saw, or eq. 7.52), improved by REPS with\n"
    "reward-oriented dimensionality reduction. Rollouts run in parallel, are written to DIR as they finish, and a\n"
    "restarted run resumes where it stopped.\n"
    "\n"
    "Parameters (private):\n"
    "  ~config       learning file (default: the package's config/fold_demo.yaml; config/fold_table75.yaml is\n"
    "                the full Table 7.5 setting)\n"
    "  ~out          results directory (default: fold_learning in the working directory)\n"
    "  ~reward       the reward's named setting instead of the learning file's: fold (the final images against\n"
    "                the flat cloth the camera saw after the reset), thesis (eq. 7.52) or goal (against the ideal\n"
    "                fold's image, simulation only; docs/RESULTS.md compares them), with that setting's weights\n"
    "                (the file's reward weights are not used). Not with workers, which read the learning file\n"
    "  ~policy       goals or weights (the thesis' DR-DMP: its folds end where the demonstration ends) instead of\n"
    "                the learning file's task policy; ~covariance_memory in [0, 1) instead of its (0: the thesis'\n"
    "                REPS update). Not with workers either\n"
    "  ~robot        robot file (config/robots/*.yaml) instead of the one the learning file's simulation names:\n"
    "                the arms, their URDF, plant, gains and friction models (fold.launch robot:=FILE sets it)\n"
    "  ~write_fold_start FILE  write the fold's start configuration on the robot (~config, ~robot) as bullet_sim\n"
    "                overrides and exit: ROBOT_fold_start.yaml beside ROBOT.yaml for fold.launch start_at_grasp\n"
    "  ~jobs         rollouts in parallel (default: the learning file's, 0 = one per core)\n"
    "  ~replay_best  after learning, replay the best rollout on the topics in a loop until shut down (default\n"
    "                false: exit when done)\n"
    "  ~worker_namespace  run the rollouts on the rollout workers under this namespace instead of threads here\n"
    "                (roslaunch bimanual_skills rollout_workers.launch starts them under /rollout_workers); the\n"
    "                workers read ~config on their host, so give a path valid there. Same results as threads.\n"
    "  ~workers      the same with worker node names instead of a namespace: a list, or _workers:=a,b\n"
    "  ~worker_timeout  [s] a worker with a share that finishes no rollout for this long is left out and its\n"
    "                rollouts go to the others (default 60; must exceed one rollout)\n"
    "  ~share        rollouts per share sent to a worker (default 0: adaptive)\n"
    "  ~backend      sim (default): the rollouts run in this process's own simulation (or on rollout workers);\n"
    "                ros: one at a time on a robot through its ROS interfaces only (bullet_sim's simulated pair\n"
    "                from sim.launch, or real arms), roslaunch bimanual_skills fold.launch backend:=ros. Each\n"
    "                rollout: ~reset_service, both arms to the start and the policy through "
    "ARM/follow_joint_trajectory\n"
    "                (one goal per arm, common start), ~grasp_service closes and opens the grippers, the cloth\n"
    "                settles, the reward scores the images of ~camera. Any failure is a failed rollout with its "
    "reason.\n"
    "  ~reset_service   std_srvs/Trigger that lays the cloth flat (default bullet_sim/reset; on hardware\n"
    "                operator_prompt's ~reset)\n"
    "  ~grasp_service   bimanual_skills/ClothGrasp of the grippers (default bullet_sim/grasp)\n"
    "  ~arms         the arms' namespaces, left first (default [left, right])\n"
    "  ~camera       namespace of image_raw and camera_info (raw images are rectified with their D, R, P) and of\n"
    "                the depth camera (default camera)\n"
    "  ~camera_depth  depth (default: CAMERA/depth/image_raw and camera_info) or depth_registered (registered to\n"
    "                the colour camera by the driver); 32FC1 metres or 16UC1 millimetres\n"
    "  ~register_depth  depth on a frame of its own is registered into the colour camera from tf (default false:\n"
    "                refused, with where to get registered depth)\n"
    "  ~cloth_topic  sensor_msgs/PointCloud2 of the cloth's nodes for the fold quality q (default bullet_sim/cloth;\n"
    "                \"\": the robot has none, q is not measured)\n"
    "  ~move_time    [s] to the start configuration (default 2), the tools coming down onto the cloth from\n"
    "                ~approach_height [m] above it (default 0.05); ~trajectory_rate points per second of the fold's\n"
    "                goals (default 100); ~robot_timeout [s] longest wall-clock wait for any interface, service calls\n"
    "                included (default 30); ~reset_timeout [s] for the reset service, the one longer wait: on\n"
    "                hardware a person lays the cloth flat (default 660, beyond operator_prompt's 600)\n"
    "  ~start_delay  [s] of the robot's clock from sending the fold's goals to their start (default 0.5)\n"
    "  ~clear_view   a camera that sees the arms: before the reset and before the scored images they go to their\n"
    "                rest posture (the robot file's start), out of its view (default false); the images at the\n"
    "                learning file's task image_delay after the settle time, as in-process\n"
    "  ~pause_service  std_srvs/SetBool holding a simulator's clock while the fold's goals travel (default\n"
    "                bullet_sim/pause; \"\" on a robot)\n"
    "  ~step_service   bimanual_skills/SimStep: with a pause service, the simulator steps from the grasp to the\n"
    "                settled cloth and the images are of that moment exactly (default bullet_sim/step; \"\" on a "
    "robot)\n"
    "  ~camera_model  orthographic (default: the camera is the reward's own top-down map, bullet_sim's camera/)\n"
    "                or perspective (an RGB-D camera, a pinhole, any pose on tf, e.g. _camera:=bullet_sim's\n"
    "                rgbd or a Kinect: its depth is re-projected into the reward's map); CameraInfo and frame are\n"
    "                checked against it and a camera that does not fit is refused with the reason\n"
    "  ~world_frame   the reward map's frame on tf (default world); ~min_coverage least share of the map a\n"
    "                perspective camera must see (0.8)\n"
    "  ~world_digest_param  where a simulator gives its world's digest (default bullet_sim/world_digest): a\n"
    "                simulator of another world than ~config's simulation file is refused at start; absent: unchecked\n"
    "\n"
    "A rollout the robot fails (an interface that failed or did not answer) is not learned from: it runs again\n"
    "with the same parameters up to the learning file's robot_retries times (default 3), each fault logged to\n"
    "DIR/robot_faults.csv; the learning stops with the reason after robot_fault_limit faults in a row (default 5).\n"
    "\n"
    "Writes into DIR: rollouts.csv and rollout_parameters.csv (every rollout, as it finishes), epochs.csv,\n"
    "coordination.csv and initial_coordination.csv (the final and the first coordination matrices), summary.json\n"
    "(one row per algorithm and epoch), initial.png\n"
    "and final.png (top-down camera images of the initial and the best final policy, with depth_*.png),\n"
    "final_runs/ALGORITHM_run_K.png and _depth.png (every run's final policy; not with _backend:=ros), and\n"
    "best_rollout.bag (replay: roslaunch bimanual_skills fold.launch replay:=DIR/best_rollout.bag).\n"
    "\n"
    "Topics: /joint_states (sensor_msgs/JointState: the last rollout's final pose, or the replay; ~joint_states with\n"
    "~backend ros, where /joint_states are the robot's), ~cloth\n"
    "  (visualization_msgs/Marker TRIANGLE_LIST: the last rollout's cloth), ~scene (the table), ~tool_paths\n"
    "  (visualization_msgs/MarkerArray: the tool paths of the last rollouts, also of those run on workers, red =\n"
    "  worst to green = best reward),\n"
    "  ~camera/image_raw (sensor_msgs/Image bgr8) and ~camera/depth/image_raw (32FC1, metres), each with its\n"
    "  camera_info (sensor_msgs/CameraInfo of the orthographic top-down camera), in the frame top_down_camera\n"
    "  (a static transform from world on /tf_static).\n";

constexpr double kBagStart = 1.0;  ///< Bag time of the rollout's t = 0 [s] (ROS time 0 means "unset").
constexpr const char* kCameraFrame = "top_down_camera";

std::string formatSeconds(double s) {
  char text[32];
  if (s >= 3600.0) {
    std::snprintf(text, sizeof text, "%dh%02dm", static_cast<int>(s / 3600.0), static_cast<int>(s / 60.0) % 60);
  } else if (s >= 60.0) {
    std::snprintf(text, sizeof text, "%dm%02ds", static_cast<int>(s / 60.0), static_cast<int>(s) % 60);
  } else {
    std::snprintf(text, sizeof text, "%.0fs", s);
  }
  return text;
}

class FoldLearnerNode {
 public:
  FoldLearnerNode() : private_node_("~"), parameters_(private_node_, "fold_learner") {
    const std::string package = ros::package::getPath("bimanual_skills");
    config_path_ = parameters_.text("config", package + "/config/fold_demo.yaml");
    out_ = parameters_.text("out", "fold_learning");
    replay_best_ = parameters_.boolean("replay_best", false);
    config_ = br::FoldLearningConfig::fromYamlFile(config_path_);
    const std::string reward =
        parameters_.has("reward") ? parameters_.text("reward", "", {"fold", "thesis", "goal"}) : "";
    if (!reward.empty()) config_.reward = bt::rewardSetting(config_.reward, reward, "fold_learner ~reward");
    // The ablations of the learning file's setting (docs/RESULTS.md): the thesis' weights-only policy, its REPS.
    const bool ablated = parameters_.has("policy") || parameters_.has("covariance_memory");
    if (parameters_.has("policy")) {
      config_.task.policy = bt::foldPolicyFromString(parameters_.text("policy", "", {"goals", "weights"}), "~policy");
    }
    config_.covariance_memory = parameters_.number("covariance_memory", config_.covariance_memory, 0.0, 0.999);
    config_.jobs = parameters_.integer("jobs", config_.jobs, 0, 1024);
    const bool robot = parameters_.has("robot");
    if (robot) config_.task.robot = parameters_.text("robot", "");
    std::unique_ptr<br::Evaluator> evaluator = makeDispatcher();
    if (evaluator && (!reward.empty() || ablated || robot)) {
      throw std::invalid_argument(
          "~reward, ~policy, ~covariance_memory and ~robot are not for rollout workers: they read the learning "
          "file, set them there");
    }
    const bool on_robot = parameters_.text("backend", "sim", {"sim", "ros"}) == "ros";
    if (on_robot) {
      if (evaluator) throw std::invalid_argument("~backend ros runs the rollouts on the robot, not on workers");
      if (config_.task.noise.any()) {
        throw std::invalid_argument("the learning file's task noise (" + config_.task.noise.setting +
                                    ") stands in for a robot's repeatability in simulation; a robot brings its own: "
                                    "remove it for ~backend ros");
      }
      evaluator = makeRobotBackend();
    }
    parameters_.warnUnknown();

    cloth_publisher_ = private_node_.advertise<visualization_msgs::Marker>("cloth", 1, true);
    scene_publisher_ = private_node_.advertise<visualization_msgs::Marker>("scene", 1, true);
    path_publisher_ = private_node_.advertise<visualization_msgs::MarkerArray>("tool_paths", 1, true);
    camera_ = bs::ros_layer::RgbdPublisher(private_node_, true);
    // On a robot /joint_states are the robot's own (its controllers follow them): the rollouts' arms go to
    // ~joint_states instead.
    joint_publisher_ = (on_robot ? private_node_ : node_).advertise<sensor_msgs::JointState>("joint_states", 10, true);

    br::FoldLearningObserver observer;
    observer.rollout = [this](const br::FoldRolloutRecord& record, const bt::FoldRollout& rollout,
                              const bt::FoldReward& reward) { onRollout(record, rollout, reward); };
    observer.epoch = [this](const br::FoldEpochStats& s) { onEpoch(s); };
    observer.robot_fault = [](const br::FoldRolloutRecord& r, int attempt, const std::string& reason, bool retry) {
      ROS_WARN("fold_learner: the robot failed %s run %d epoch %d rollout %d (attempt %d): %s%s", r.algorithm.c_str(),
               r.run, r.epoch, r.index, attempt, reason.c_str(), retry ? "; running it again" : "");
    };
    observer.stop = [] { return !ros::ok(); };
    learner_ = std::make_unique<br::FoldLearner>(config_, out_, observer, std::move(evaluator));
    const bt::ClothFoldConfig& task = learner_->config().task;
    const bs::sim::SimConfig sim = bs::sim::SimConfig::fromYamlFile(task.sim_config, task.robot);
    for (const bs::sim::ArmConfig& arm : sim.arms) {
      const std::vector<std::string> names =
          bs::kinematics::ChainModel::fromUrdfFile(sim.urdf_path, arm.base_link, arm.tip_link).jointNames();
      joint_names_.insert(joint_names_.end(), names.begin(), names.end());
    }
    table_ = sim.table;
    cloth_ = sim.cloth;
    scene_publisher_.publish(bs::nodes::tableMarker(table_, ros::Time::now()));
    camera_frame_.sendTransform(bs::ros_layer::cameraTransform(learner_->config().reward.renderer.camera, "world",
                                                               kCameraFrame, ros::Time::now()));
    total_ = config_.repetitions + static_cast<int>(config_.algorithms.size()) * config_.runs * (config_.updates + 1) *
                                       (config_.rollouts + 1);
  }

  void run() {
    ROS_INFO("fold_learner: %s -> %s: %zu algorithm(s) x %d run(s) x %d update(s) x %d rollouts, seed %u, %s",
             config_path_.c_str(), out_.c_str(), config_.algorithms.size(), config_.runs, config_.updates,
             config_.rollouts, config_.seed,
             robot_backend_ ? "on the robot through ROS"
             : dispatching_ ? ("rollout workers under " + workers_where_).c_str()
                            : (std::to_string(learner_->config().jobs) + " thread(s)").c_str());
    start_ = std::chrono::steady_clock::now();
    const br::FoldLearningResult result = learner_->learn();
    ROS_INFO("fold_learner: %d rollouts simulated and %d read from %s in %s", result.simulated, result.resumed,
             out_.c_str(), formatSeconds(result.seconds).c_str());
    if (result.robot_faults > 0) {
      ROS_WARN("fold_learner: the robot failed %d attempt(s), each run again (%s/robot_faults.csv)",
               result.robot_faults, out_.c_str());
    }
    if (dispatching_) {
      ROS_INFO("fold_learner: %zu worker(s) lost and %zu rollout(s) re-dispatched over the learning", workers_lost_,
               redispatched_);
    }
    const br::FoldRunResult* best_run = &result.runs.front();
    for (const br::FoldRunResult& r : result.runs) {
      if (r.final_policy.terms.reward > best_run->final_policy.terms.reward) best_run = &r;
    }
    const br::FoldRolloutRecord* best = &result.runs.front().best;
    for (const br::FoldRunResult& r : result.runs) {
      if (r.best.terms.reward > best->terms.reward) best = &r.best;
    }
    bt::FoldRollout replay;
    if (robot_backend_) {
      // The robot's own pictures: what its camera sent (no simulated replay).
      for (const auto& [record, name] :
           {std::pair{&result.runs.front().initial_policy, "initial"}, std::pair{&best_run->final_policy, "final"}}) {
        if (const bt::FoldRollout* r = recordingOf(*record); r != nullptr && !r->camera_colour.empty()) {
          writeRecorded(*r, name);
        } else {
          ROS_WARN("fold_learner: no %s pictures: that rollout was read from disk or failed before its images", name);
        }
      }
      const auto found = recordings_.find("best");
      if (found != recordings_.end()) {
        replay = found->second;
        writeBag(*best, replay);
      }
    } else {
      writeImage(result.runs.front().initial_policy, "initial");
      writeImage(best_run->final_policy, "final");
      writeRunImages(result);
      writeFilmstrip(result.runs.front().initial_policy, "initial");
      writeFilmstrip(best_run->final_policy, "final");
      replay = learner_->replay(*best, 20.0);
      writeBag(*best, replay);
    }
    writeSummary(result);  // last: a finished run's mark
    std::printf(
        "fold_learner: results in %s: summary.json, epochs.csv, rollouts.csv, initial.png, final.png, "
        "initial_frames.csv, final_frames.csv (the filmstrips' data), best_rollout.bag\n"
        "fold_learner: best rollout: %s run %d epoch %d (%s %d), R = %.4f; replay it in rviz with\n"
        "  roslaunch bimanual_skills fold.launch replay:=%s/best_rollout.bag\n",
        out_.c_str(), best->algorithm.c_str(), best->run + 1, best->epoch, br::toString(best->kind), best->index,
        best->terms.reward, out_.c_str());
    // The fold's ground truth (the cloth mesh, not the camera): each run's noise-free policy before and after the
    // learning, what a user gets; and its exploring rollouts (mean ± standard error) in the first and last epoch.
    for (const br::FoldRunResult& r : result.runs) {
      if (r.epochs.empty()) continue;
      const br::FoldEpochStats &first = r.epochs.front(), &last = r.epochs.back();
      const double root = std::sqrt(static_cast<double>(config_.rollouts));
      std::printf(
          "fold_learner: %s run %d: the noise-free policy folds with fold quality %.3f → %.3f (epoch %d → %d); its "
          "exploring rollouts %.3f ± %.3f → %.3f ± %.3f\n",
          r.algorithm.c_str(), r.run + 1, r.initial_policy.terms.fold_quality, r.final_policy.terms.fold_quality,
          first.epoch, last.epoch, first.fold_quality, first.fold_quality_std / root, last.fold_quality,
          last.fold_quality_std / root);
    }
    std::fflush(stdout);
    if (replay_best_) replayLoop(*best, replay);
  }

 private:
  /// A dispatcher to the rollout workers when ~worker_namespace or ~workers is set, else null (threads here).
  std::unique_ptr<br::Evaluator> makeDispatcher() {
    std::unique_ptr<br::Evaluator> dispatcher =
        bs::nodes::workerDispatcher(parameters_, private_node_, "fold", config_path_, br::FoldRolloutTask::kTerms,
                                    "fold_learner", workers_where_, [this](const br::DispatchStats& s) { onBatch(s); });
    dispatching_ = dispatcher != nullptr;
    return dispatcher;
  }

  /// The rollouts on the robot through ROS, one at a time.
  std::unique_ptr<br::Evaluator> makeRobotBackend() {
    bs::ros_layer::FoldRobotInterfaces robot;
    bs::nodes::readRobotInterfaces(parameters_, robot);
    robot.arms = parameters_.texts("arms", robot.arms);
    robot.camera_model = parameters_.text("camera_model", robot.camera_model);
    robot.world_frame = parameters_.text("world_frame", robot.world_frame);
    robot.min_coverage = parameters_.number("min_coverage", robot.min_coverage, 0.0, 1.0);
    robot.move_time = parameters_.number("move_time", robot.move_time, 0.1, 60.0);
    robot.approach_height = parameters_.number("approach_height", robot.approach_height, 0.0, 0.5);
    robot.trajectory_rate = parameters_.number("trajectory_rate", robot.trajectory_rate, 1.0, 1000.0);
    robot.start_delay = parameters_.number("start_delay", robot.start_delay, 0.0, 10.0);
    robot.clear_view = parameters_.boolean("clear_view", robot.clear_view);
    robot.validate();
    robot_backend_ = true;
    const br::FoldLearningConfig config = config_;
    return std::make_unique<br::ParallelEvaluator>(
        [config, robot] { return std::make_unique<bs::ros_layer::FoldOnRobotTask>(config.task, config.reward, robot); },
        1);
  }

  void onBatch(const br::DispatchStats& s) {
    workers_lost_ += s.lost.size();
    redispatched_ += s.redispatched;
    const double elapsed = bs::realtime::secondsSince(start_);
    const int simulated = done_ - resumed_;
    const double eta = simulated > 0 ? elapsed / simulated * (total_ - done_) : 0.0;
    std::printf(
        "[batch] %zu rollouts in %.1f s on %zu worker(s), %zu alive, %zu lost, %zu re-dispatched: %.2f rollouts/s | "
        "%d/%d rollouts, ETA %s\n",
        s.rollouts, s.seconds, s.workers, s.alive, s.lost.size(), s.redispatched,
        s.seconds > 0.0 ? static_cast<double>(s.rollouts) / s.seconds : 0.0, done_, total_, formatSeconds(eta).c_str());
    std::fflush(stdout);
  }

  /// The colour and depth images with their camera_info, in the camera's frame.
  void publishImages(const ros::Time& stamp, const cv::Mat& bgr, const cv::Mat& depth) {
    std_msgs::Header header;
    header.stamp = stamp;
    header.frame_id = kCameraFrame;
    camera_.publish(bs::ros_layer::RgbdFrame(
        header, bgr, depth, bs::ros_layer::cameraInfo(learner_->config().reward.renderer.camera, header)));
  }

  void onRollout(const br::FoldRolloutRecord& record, const bt::FoldRollout& rollout, const bt::FoldReward& reward) {
    ++done_;
    if (record.resumed) ++resumed_;
    const double elapsed = bs::realtime::secondsSince(start_);
    const int simulated = done_ - resumed_;
    const double eta = simulated > 0 ? elapsed / simulated * (total_ - done_) : 0.0;
    std::printf(
        "[%s run %d] epoch %d/%d %s %d: R = %.4f (acc %.3f, color %.3f, depth %.3f, goal %.3f, fold %.3f), fold "
        "quality %.2f %s%s%s | %d/%d rollouts, ETA %s\n",
        record.algorithm.c_str(), record.run + 1, record.epoch, config_.updates, br::toString(record.kind),
        record.index + 1, record.terms.reward, record.terms.r_acceleration, record.terms.r_color, record.terms.r_depth,
        record.terms.r_goal, record.terms.r_fold, record.terms.fold_quality, bt::toString(record.terms.outcome),
        record.reason.empty() ? "" : ": ", record.reason.c_str(), done_, total_, formatSeconds(eta).c_str());
    std::fflush(stdout);
    if (record.resumed) return;
    const ros::Time now = ros::Time::now();
    // The cloth, images and arms of a rollout simulated here, or what a robot sent; a rollout worker's answer has
    // its tool paths only.
    const bool robot = !rollout.camera_colour.empty();
    if (robot) keepRecording(record, rollout);
    if (rollout.cloth_vertices.cols() > 0) {
      cloth_publisher_.publish(bs::nodes::clothMarker(rollout.cloth_vertices, rollout.cloth_triangles, now));
    }
    if (robot) {
      publishImages(now, rollout.camera_colour.back(), rollout.camera_depth.back());
    } else if (rollout.cloth_vertices.cols() > 0) {
      publishImages(now, reward.bgr(), reward.depth());
    }
    if ((robot || rollout.cloth_vertices.cols() > 0) && !rollout.joint_path.empty() &&
        rollout.joint_path.front().cols() > 0) {
      joint_publisher_.publish(jointState(rollout, rollout.joint_path.front().cols() - 1, now));
    }
    if (rollout.actual_path.empty()) return;
    // The paths of the last rollouts, coloured by reward from the worst (red) to the best (green) shown.
    paths_.push_back({record.terms.reward, rollout.actual_path});
    while (static_cast<int>(paths_.size()) > config_.rollouts) paths_.pop_front();
    double lo = paths_.front().reward, hi = lo;
    for (const Paths& p : paths_) {
      lo = std::min(lo, p.reward);
      hi = std::max(hi, p.reward);
    }
    visualization_msgs::MarkerArray markers;
    visualization_msgs::Marker clear;
    clear.action = visualization_msgs::Marker::DELETEALL;
    markers.markers.push_back(clear);
    int id = 0;
    for (const Paths& p : paths_) {
      const double s = hi > lo ? (p.reward - lo) / (hi - lo) : 1.0;
      for (const Eigen::Matrix3Xd& path : p.tools) {
        visualization_msgs::Marker m = bs::nodes::pathMarker("tool_paths", id++, path, 0.004, now);
        m.color.r = static_cast<float>(1.0 - s);
        m.color.g = static_cast<float>(s);
        m.color.b = 0.1f;
        markers.markers.push_back(m);
      }
    }
    path_publisher_.publish(markers);
  }

  void onEpoch(const br::FoldEpochStats& s) {
    ROS_INFO(
        "fold_learner: %s run %d epoch %d/%d: mean reward %.4f +- %.4f (acc %.3f, color %.3f, depth %.3f, "
        "goal %.3f, fold %.3f), fold quality %.3f, r = %d, %d failed",
        s.algorithm.c_str(), s.run + 1, s.epoch, config_.updates, s.mean_reward, s.std_reward, s.r_acceleration,
        s.r_color, s.r_depth, s.r_goal, s.r_fold, s.fold_quality, s.latent_dims, s.failures);
  }

  sensor_msgs::JointState jointState(const bt::FoldRollout& rollout, Eigen::Index sample,
                                     const ros::Time& stamp) const {
    sensor_msgs::JointState js;
    js.header.stamp = stamp;
    js.name = joint_names_;
    for (const Eigen::MatrixXd& arm : rollout.joint_path) {
      for (Eigen::Index j = 0; j < arm.rows(); ++j) js.position.push_back(arm(j, sample));
    }
    return js;
  }

  /// A robot's rollouts: what they sent, for the pictures and the bag of the initial policy, each final policy and the
  /// best rollout (the robot's frames are not on disk: a resumed run has none of the rollouts read back).
  static std::string recordKey(const br::FoldRolloutRecord& r) {
    return r.algorithm + '|' + std::to_string(r.run) + '|' + std::to_string(r.epoch) + '|' + br::toString(r.kind) +
           '|' + std::to_string(r.index);
  }

  void keepRecording(const br::FoldRolloutRecord& record, const bt::FoldRollout& rollout) {
    const bool policy = record.kind == br::RolloutKind::Policy;
    if (policy && (record.epoch == 0 || record.epoch == config_.updates)) recordings_[recordKey(record)] = rollout;
    if (record.terms.outcome == bt::FoldOutcome::Ok && record.terms.reward > best_recorded_reward_) {
      best_recorded_reward_ = record.terms.reward;
      recordings_["best"] = rollout;
    }
  }

  /// The recording of a record's rollout, or null (a rollout read from disk).
  const bt::FoldRollout* recordingOf(const br::FoldRolloutRecord& record) const {
    const auto found = recordings_.find(recordKey(record));
    return found == recordings_.end() ? nullptr : &found->second;
  }

  void writeDepth(const cv::Mat& depth, const std::string& name) const {
    cv::Mat shown;
    double lo = 0.0, hi = 0.0;
    cv::minMaxLoc(depth, &lo, &hi);
    depth.convertTo(shown, CV_8U, hi > lo ? -255.0 / (hi - lo) : 0.0, hi > lo ? 255.0 * hi / (hi - lo) : 0.0);
    cv::imwrite(out_ + "/depth_" + name + ".png", shown);
  }

  /// The robot's pictures of a rollout: NAME.png and depth_NAME.png (the images scored), and the filmstrip's data as
  /// writeFilmstrip() writes it (the camera's images nearest six moments; the cloth frames when the robot has them).
  void writeRecorded(const bt::FoldRollout& r, const std::string& name) {
    cv::imwrite(out_ + "/" + name + ".png", r.camera_colour.back());
    writeDepth(r.camera_depth.back(), name);
    if (!r.cloth_frames.empty()) writeFrames(r, name);
    const Eigen::VectorXd& t = r.camera_times;
    for (int moment = 0; moment < 6; ++moment) {
      const double at = t[0] + (t[t.size() - 1] - t[0]) * moment / 5.0;
      Eigen::Index nearest = 0;
      (t.array() - at).abs().minCoeff(&nearest);
      cv::imwrite(out_ + "/" + name + "_top_" + std::to_string(moment) + ".png",
                  r.camera_colour[static_cast<std::size_t>(nearest)]);
    }
  }

  /// The camera's final images of a record's rollout, replayed in this process's simulation.
  void renderFinal(const br::FoldRolloutRecord& record, cv::Mat& bgr, cv::Mat& depth) {
    learner_->score(learner_->replay(record, 0.0), record.seed, bgr, depth);
  }

  void writeImage(const br::FoldRolloutRecord& record, const std::string& name) {
    cv::Mat bgr, depth;
    renderFinal(record, bgr, depth);
    cv::imwrite(out_ + "/" + name + ".png", bgr);
    writeDepth(depth, name);
  }

  /// The camera's final images of every run's final policy, DIR/final_runs/ALGORITHM_run_K.png and
  /// ALGORITHM_run_K_depth.png (16-bit, depth in units of 0.1 mm), the algorithm's name with characters other than
  /// letters, digits, '-' and '_' as '_': what each run learned, stalls included.
  void writeRunImages(const br::FoldLearningResult& result) {
    std::filesystem::create_directories(out_ + "/final_runs");
    for (const br::FoldRunResult& run : result.runs) {
      const std::string name = bs::nodes::fileName(run.algorithm);
      cv::Mat bgr, depth;
      renderFinal(run.final_policy, bgr, depth);
      const std::string path = out_ + "/final_runs/" + name + "_run_" + std::to_string(run.run);
      cv::imwrite(path + ".png", bgr);
      cv::Mat tenths;
      depth.convertTo(tenths, CV_16U, 1e4);
      cv::imwrite(path + "_depth.png", tenths);
    }
  }

  /// What scripts/plot_fold_learning.py turns into DIR/filmstrip_NAME.png and DIR/NAME.gif: the rollout's cloth
  /// at 20 Hz with its fold quality (NAME_frames.csv: t, q, then x y z of every node; NAME_triangles.csv) and the
  /// top-down camera image at six moments evenly spread over it (NAME_top_K.png, K = 0 … 5).
  void writeFilmstrip(const br::FoldRolloutRecord& record, const std::string& name) {
    bt::FoldRollout rollout = learner_->replay(record, 20.0);
    if (rollout.cloth_frames.empty()) return;
    writeFrames(rollout, name);
    const std::size_t last = rollout.cloth_frames.size() - 1;
    for (int moment = 0; moment < 6; ++moment) {
      rollout.cloth_vertices = rollout.cloth_frames[last * static_cast<std::size_t>(moment) / 5];
      cv::Mat bgr, depth;
      learner_->score(rollout, record.seed, bgr, depth);
      cv::imwrite(out_ + "/" + name + "_top_" + std::to_string(moment) + ".png", bgr);
    }
  }

  /// NAME_frames.csv (t, q, then x y z of every node of each cloth frame) and NAME_triangles.csv.
  void writeFrames(const bt::FoldRollout& rollout, const std::string& name) const {
    const bs::sim::ClothParameters& cloth = cloth_;
    std::ofstream frames(out_ + "/" + name + "_frames.csv");
    frames.precision(6);
    frames << "t,q,xyz...\n";
    for (std::size_t k = 0; k < rollout.cloth_frames.size(); ++k) {
      const Eigen::Matrix3Xd& mesh = rollout.cloth_frames[k];
      frames << rollout.cloth_times[static_cast<Eigen::Index>(k)] << ','
             << bt::foldQuality(mesh, rollout.cloth_rest_vertices, cloth.nodes_x, cloth.nodes_y, cloth.thickness).q;
      for (Eigen::Index c = 0; c < mesh.cols(); ++c)
        frames << ',' << mesh(0, c) << ',' << mesh(1, c) << ',' << mesh(2, c);
      frames << '\n';
    }
    std::ofstream triangles(out_ + "/" + name + "_triangles.csv");
    triangles << "a,b,c\n";
    for (Eigen::Index t = 0; t < rollout.cloth_triangles.cols(); ++t) {
      triangles << rollout.cloth_triangles(0, t) << ',' << rollout.cloth_triangles(1, t) << ','
                << rollout.cloth_triangles(2, t) << '\n';
    }
  }

  /// best_rollout.bag: the rollout's joints, cloth, tool paths and camera images on the node's topics. A simulated
  /// rollout's images are rendered at its end (`best` gives the noise's seed); a robot's are the ones it sent.
  void writeBag(const br::FoldRolloutRecord& best, const bt::FoldRollout& rollout) {
    rosbag::Bag bag(out_ + "/best_rollout.bag", rosbag::bagmode::Write);
    const std::string ns = private_node_.getNamespace();
    const ros::Time begin(kBagStart);
    bag.write(ns + "/scene", begin, bs::nodes::tableMarker(table_, begin));
    for (Eigen::Index k = 0; k < rollout.path_times.size(); ++k) {
      const ros::Time t(kBagStart + rollout.path_times[k]);
      bag.write("/joint_states", t, jointState(rollout, k, t));
    }
    for (std::size_t k = 0; k < rollout.cloth_frames.size(); ++k) {
      const ros::Time t(kBagStart + rollout.cloth_times[static_cast<Eigen::Index>(k)]);
      bag.write(ns + "/cloth", t, bs::nodes::clothMarker(rollout.cloth_frames[k], rollout.cloth_triangles, t));
    }
    visualization_msgs::MarkerArray paths;
    for (std::size_t arm = 0; arm < rollout.actual_path.size(); ++arm) {
      visualization_msgs::Marker m =
          bs::nodes::pathMarker("tool_paths", static_cast<int>(arm), rollout.actual_path[arm], 0.004, begin);
      m.color.g = 1.0f;
      paths.markers.push_back(m);
    }
    bag.write(ns + "/tool_paths", begin, paths);
    const vision::TopDownCamera& camera = learner_->config().reward.renderer.camera;
    const auto image = [&](double t, const cv::Mat& bgr, const cv::Mat& depth) {
      std_msgs::Header header;
      header.stamp = ros::Time(kBagStart + std::max(0.0, t));
      header.frame_id = kCameraFrame;
      bs::ros_layer::RgbdFrame(header, bgr, depth, bs::ros_layer::cameraInfo(camera, header))
          .write(ns + "/", header.stamp, [&bag](const std::string& topic, const ros::Time& time, const auto& message) {
            bag.write(topic, time, message);
          });
    };
    if (!rollout.camera_colour.empty()) {
      for (std::size_t k = 0; k < rollout.camera_colour.size(); ++k) {
        image(rollout.camera_times[static_cast<Eigen::Index>(k)], rollout.camera_colour[k], rollout.camera_depth[k]);
      }
    } else {
      cv::Mat bgr, depth;
      learner_->score(rollout, best.seed, bgr, depth);
      image(rollout.simulated_seconds, bgr, depth);
    }
    bag.close();
  }

  void writeSummary(const br::FoldLearningResult& result) const {
    std::vector<bs::io::JsonRow> rows;
    std::map<std::string, std::vector<const br::FoldRunResult*>> by_algorithm;
    for (const br::FoldRunResult& r : result.runs) by_algorithm[r.algorithm].push_back(&r);
    for (const std::string& algorithm : config_.algorithms) {
      const std::vector<const br::FoldRunResult*>& runs = by_algorithm[algorithm];
      for (int e = 0; e <= config_.updates; ++e) {
        // Over the runs: the mean of the epoch's rollout rewards, its std across runs and the rollouts' std.
        const auto n = static_cast<double>(runs.size());
        double mean = 0.0, spread = 0.0, within = 0.0, acc = 0.0, color = 0.0, depth = 0.0, rho = 0.0, g = 0.0,
               area = 0.0, goal = 0.0, mismatch = 0.0, fold = 0.0, fold_mismatch = 0.0, dims = 0.0, failures = 0.0,
               quality = 0.0, quality_within = 0.0;
        for (const br::FoldRunResult* r : runs) {
          const br::FoldEpochStats& s = r->epochs[static_cast<std::size_t>(e)];
          mean += s.mean_reward / n;
          within += s.std_reward / n;
          acc += s.r_acceleration / n;
          color += s.r_color / n;
          depth += s.r_depth / n;
          rho += s.fill_ratio / n;
          g += s.mean_gradient / n;
          area += s.area_ratio / n;
          goal += s.r_goal / n;
          mismatch += s.goal_mismatch / n;
          fold += s.r_fold / n;
          fold_mismatch += s.fold_mismatch / n;
          quality += s.fold_quality / n;
          quality_within += s.fold_quality_std / n;
          dims += s.latent_dims / n;
          failures += s.failures;
        }
        for (const br::FoldRunResult* r : runs) {
          const double d = r->epochs[static_cast<std::size_t>(e)].mean_reward - mean;
          spread += runs.size() > 1 ? d * d / (n - 1) : 0.0;
        }
        bs::io::JsonRow& row = rows.emplace_back();
        row.add("experiment", "fold")
            .add("algorithm", algorithm)
            .add("epoch", e)
            .add("runs", static_cast<int>(runs.size()))
            .add("mean_reward", mean)
            .add("std_reward", runs.size() > 1 ? std::sqrt(spread) : within)
            .add("std_reward_within_runs", within)
            .add("r_acceleration", acc)
            .add("r_color", color)
            .add("r_depth", depth)
            .add("fill_ratio", rho)
            .add("mean_gradient", g)
            .add("area_ratio", area)
            .add("r_goal", goal)
            .add("goal_mismatch", mismatch)
            .add("r_fold", fold)
            .add("fold_mismatch", fold_mismatch)
            .add("fold_quality", quality)
            .add("fold_quality_std_within_runs", quality_within)
            .add("latent_dims", dims)
            .add("failures", failures);
      }
      double initial = 0.0, final_reward = 0.0, final_dims = 0.0, initial_quality = 0.0, final_quality = 0.0;
      for (const br::FoldRunResult* r : runs) {
        initial += r->initial_policy.terms.reward / runs.size();
        final_reward += r->final_policy.terms.reward / runs.size();
        initial_quality += r->initial_policy.terms.fold_quality / runs.size();
        final_quality += r->final_policy.terms.fold_quality / runs.size();
        final_dims += static_cast<double>(r->final.latentDims()) / runs.size();
      }
      rows.emplace_back()
          .add("experiment", "fold_policy")
          .add("algorithm", algorithm)
          .add("reward_setting", config_.reward.setting)
          .add("policy", bt::toString(config_.task.policy))
          .add("covariance_memory", config_.covariance_memory)
          .add("noise", config_.task.noise.setting)
          .add("initial_policy_reward", initial)
          .add("final_policy_reward", final_reward)
          .add("initial_policy_fold_quality", initial_quality)
          .add("final_policy_fold_quality", final_quality)
          .add("final_latent_dims", final_dims);
    }
    if (!result.repetitions.empty()) {
      const auto n = static_cast<double>(result.repetitions.size());
      double m[4] = {0, 0, 0, 0}, s[4] = {0, 0, 0, 0};
      const auto values = [](const br::FoldRolloutRecord& r) {
        return std::array<double, 4>{r.terms.reward, r.terms.fill_ratio, r.terms.mean_gradient, r.terms.r_acceleration};
      };
      for (const br::FoldRolloutRecord& r : result.repetitions) {
        for (int i = 0; i < 4; ++i) m[i] += values(r)[static_cast<std::size_t>(i)] / n;
      }
      for (const br::FoldRolloutRecord& r : result.repetitions) {
        for (int i = 0; i < 4; ++i) {
          const double d = values(r)[static_cast<std::size_t>(i)] - m[i];
          s[i] += n > 1 ? d * d / (n - 1) : 0.0;
        }
      }
      rows.emplace_back()
          .add("experiment", "repetitions")
          .add("algorithm", "demonstration")
          .add("repetitions", static_cast<int>(n))
          .add("mean_reward", m[0])
          .add("std_reward", std::sqrt(s[0]))
          .add("fill_ratio", m[1])
          .add("fill_ratio_std", std::sqrt(s[1]))
          .add("mean_gradient", m[2])
          .add("mean_gradient_std", std::sqrt(s[2]))
          .add("r_acceleration", m[3])
          .add("r_acceleration_std", std::sqrt(s[3]));
    }
    if (dispatching_) {
      rows.emplace_back()
          .add("experiment", "dispatch")
          .add("workers_lost", static_cast<int>(workers_lost_))
          .add("redispatched", static_cast<int>(redispatched_));
    }
    bs::io::writeSummaryJson(out_ + "/summary.json",
                             {"fold_learner", "fold", config_.seed, false, bs::cli::numericsState()}, rows);
  }

  /// Publishes the best rollout on the live topics in real time, in a loop: its camera images and tool paths once,
  /// the robot and the cloth as they move.
  void replayLoop(const br::FoldRolloutRecord& best, const bt::FoldRollout& rollout) {
    ROS_INFO("fold_learner: replaying the best rollout until shut down");
    cv::Mat bgr, depth;
    if (rollout.camera_colour.empty()) {
      learner_->score(rollout, best.seed, bgr, depth);
    } else {  // a robot's: the images its camera sent
      bgr = rollout.camera_colour.back();
      depth = rollout.camera_depth.back();
    }
    std_msgs::Header header;
    header.stamp = ros::Time::now();
    header.frame_id = kCameraFrame;
    publishImages(header.stamp, bgr, depth);
    visualization_msgs::MarkerArray paths;
    visualization_msgs::Marker clear;
    clear.action = visualization_msgs::Marker::DELETEALL;
    paths.markers.push_back(clear);
    for (std::size_t arm = 0; arm < rollout.actual_path.size(); ++arm) {
      visualization_msgs::Marker m =
          bs::nodes::pathMarker("tool_paths", static_cast<int>(arm), rollout.actual_path[arm], 0.004, header.stamp);
      m.color.g = 1.0f;
      paths.markers.push_back(m);
    }
    path_publisher_.publish(paths);
    while (ros::ok()) {
      const ros::WallTime start = ros::WallTime::now();
      std::size_t frame = 0;
      for (Eigen::Index k = 0; k < rollout.path_times.size() && ros::ok(); ++k) {
        ros::WallTime::sleepUntil(start + ros::WallDuration(rollout.path_times[k]));
        const ros::Time now = ros::Time::now();
        joint_publisher_.publish(jointState(rollout, k, now));
        while (frame < rollout.cloth_frames.size() &&
               rollout.cloth_times[static_cast<Eigen::Index>(frame)] <= rollout.path_times[k]) {
          cloth_publisher_.publish(bs::nodes::clothMarker(rollout.cloth_frames[frame], rollout.cloth_triangles, now));
          ++frame;
        }
      }
      ros::WallDuration(1.0).sleep();
    }
  }

  struct Paths {
    double reward;
    std::vector<Eigen::Matrix3Xd> tools;
  };

  ros::NodeHandle node_, private_node_;
  bs::ros_layer::ParameterReader parameters_;
  std::string config_path_, out_;
  bool replay_best_ = false;
  br::FoldLearningConfig config_;
  std::unique_ptr<br::FoldLearner> learner_;
  std::vector<std::string> joint_names_;
  bs::sim::Table table_;
  bs::sim::ClothParameters cloth_;
  bs::ros_layer::RgbdPublisher camera_;
  tf2_ros::StaticTransformBroadcaster camera_frame_;
  ros::Publisher cloth_publisher_, scene_publisher_, path_publisher_, joint_publisher_;
  std::deque<Paths> paths_;
  std::chrono::steady_clock::time_point start_;
  int done_ = 0, resumed_ = 0, total_ = 0;
  bool dispatching_ = false, robot_backend_ = false;
  std::map<std::string, bt::FoldRollout> recordings_;  ///< A robot's rollouts kept for the pictures (keepRecording)
  double best_recorded_reward_ = -std::numeric_limits<double>::infinity();
  std::string workers_where_;
  std::size_t workers_lost_ = 0, redispatched_ = 0;
};

}  // namespace

/// ~write_fold_start FILE: the fold's start configuration of the learning file on its robot (~config, ~robot) as
/// bullet_sim overrides (initial_positions per arm), for sim.launch sim_overrides:= and fold.launch start_at_grasp.
void writeFoldStart(const std::string& file) {
  bs::ros_layer::ParameterReader parameters(ros::NodeHandle("~"), "fold_learner");
  br::FoldLearningConfig config = br::FoldLearningConfig::fromYamlFile(
      parameters.text("config", ros::package::getPath("bimanual_skills") + "/config/fold_demo.yaml"));
  if (parameters.has("robot")) config.task.robot = parameters.text("robot", "");
  const bt::ClothFoldTask task(config.task);
  // Files of the package as the package names them.
  const auto named = [package = ros::package::getPath("bimanual_skills")](const std::string& path) {
    const std::string relative = std::filesystem::path(path).lexically_relative(package).string();
    return relative.empty() || relative.rfind("..", 0) == 0 ? path : relative;
  };
  std::ofstream out(file);
  out << "# bullet_sim overrides (sim.launch sim_overrides:=...): start and reset with the arms at the cloth fold's "
         "start\n# configuration (tools at the cloth's far corners, tasks::ClothFoldTask::startPositions()), as the "
         "in-process fold\n# task starts, instead of moving there. Written by fold_learner _write_fold_start:=FILE "
         "from\n# "
      << named(config.task.sim_config) << (config.task.robot.empty() ? "" : " on " + named(config.task.robot))
      << ".\ninitial_positions:\n";
  for (std::size_t a = 0; a < task.startPositions().size(); ++a) {
    out << "  " << task.simConfig().arms[a].name << ": [";
    const Eigen::VectorXd& q = task.startPositions()[a];
    for (Eigen::Index i = 0; i < q.size(); ++i)
      out << (i > 0 ? ", " : "") << std::fixed << std::setprecision(6) << q[i];
    out << "]\n";
  }
  if (!out.flush()) throw std::runtime_error("cannot write " + file);
  std::printf("fold_learner: wrote the fold's start to %s\n", file.c_str());
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "fold_learner");
  // Keeps the node up until main returns: the learner's handles are gone by the time an exception is caught, and
  // the last handle to go shuts the node down, which must still tell a fault from a Ctrl-C.
  const ros::NodeHandle keep_alive;
  try {
    if (std::string file; ros::param::get("~write_fold_start", file)) {
      writeFoldStart(file);
      return 0;
    }
    FoldLearnerNode node;
    node.run();
  } catch (const std::exception& e) {
    if (!ros::ok() && std::string(e.what()) == "stopped") {
      ROS_WARN("fold_learner: stopped; the finished rollouts are on disk, run again to resume");
      return 0;
    }
    ROS_FATAL("fold_learner: %s", e.what());
    return 1;
  }
  return 0;
}
