// bottles_guidance: the robot's side of human-guided learning of the bottle task over ROS (thesis Sec. 6.2,
// Figs. 6.9, 6.13). A thin shell: tasks::GuidanceFollower turns the tracked hand into the arm's reference, the
// arm's hosted controller follows it (follow mode, its target this node's ~target), and after the runs
// tasks::averageGuidedRuns aligns them and fits the DMP.
#include "bimanual_skills/FollowerState.h"
#include "bimanual_skills/GuidancePhase.h"
#include "bimanual_skills/SetControlMode.h"
#include "bimanual_skills/TrackedObject.h"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/tasks/human_guidance.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/summary_json.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <geometry_msgs/PoseArray.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Geometry>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace bs = bimanual_skills;
namespace bt = bimanual_skills::tasks;

namespace {

const char* kUsage =
    "usage: rosrun bimanual_skills bottles_guidance [_task:=FILE] [_out:=DIR] [_runs:=N] [_gesture_height:=M]\n"
    "\n"
    "The robot's side of human-guided learning of the bottle task (thesis Sec. 6.2, Figs. 6.9, 6.13): the arm's tool\n"
    "goes along the task file's line at its height; a hand the camera tracks (object_tracker) raised above\n"
    "~gesture_height takes it: the tool follows the hand's x, y; lowered, it lets go: the tool goes back to the\n"
    "nearest point of the line and on to the goal (tasks::GuidanceFollower). The arm's controller follows ~target in\n"
    "its follow mode (guided.launch sets it up). Each run is recorded; after ~runs runs the runs are time-aligned by\n"
    "gradient descent, averaged weighted by their rewards and the task's DMP fitted to the average.\n"
    "\n"
    "Parameters (private):\n"
    "  ~task            the bottle task file (default: the package's config/bottles_wam.yaml): the line, the arm\n"
    "  ~out             directory of the records (default $PWD/bottles_guidance)\n"
    "  ~runs            guided runs to record, 1-1000 (default 20); the simulation is reset between them\n"
    "  ~gesture_height  a hand above this [m, world z] is raised (default: the line's height + 0.275)\n"
    "  ~rate            reference updates per second of the robot's clock (default 100)\n"
    "  ~move_time       [s] the arm's joint trajectory to the task's start posture (its tool at the line's start)\n"
    "                   before each run (ARM/command), then ARM/set_mode follow (default 3)\n"
    "  ~approach        [s] the tool then holds at the line's start before the run (default 1)\n"
    "  ~settle          [s] recorded after the reference arrives, while a pushed bottle falls (default 0.5)\n"
    "  ~seed            the learned DMP's run on the simulated WAM and summary.json's seed, an integer in\n"
    "                   [0, 2^32) (default 1; guided.launch passes its seed:=, the scripted person's)\n"
    "  ~max_run         [s] a run whose reference has not arrived by then ends as failed (default 30)\n"
    "  ~hand_max_age    [s] a hand estimate older than this (robot clock) counts as lowered (default 0.3)\n"
    "  ~controller_max_age [s] no follow_state from the arm's controller for this long (robot clock; more than\n"
    "                   its 1 / publish_rate), or one saying it no longer follows, ends the run as failed\n"
    "                   (default 0.5)\n"
    "  ~lag, ~max_speed the follower's time constant [s] (0.15) and speed cap [line lengths/s] (0.6)\n"
    "  ~hand_topic      bimanual_skills/TrackedObject of the hand (default /object_tracker/object)\n"
    "  ~tool_topic      bimanual_skills/FollowerState of the arm's controller (default /ARM/follow_state)\n"
    "  ~obstacles_topic geometry_msgs/PoseArray of the scene's obstacles (default /bullet_sim/obstacle_poses)\n"
    "  ~reset_service   std_srvs/Trigger run between runs (default /bullet_sim/reset; \"\": none)\n"
    "\n"
    "Topics: ~target (bimanual_skills/TrackedObject: the reference for the controller's follow/target_topic),\n"
    "  ~phase (bimanual_skills/GuidancePhase, latched: the run, approach|line|guided|back|arrived, done after the\n"
    "  last run, the outcome of a run that ended), ~markers (MarkerArray: the line, the reference, the hand, this\n"
    "  run's tool path).\n"
    "Writes into ~out: run_K.csv (time, phase, reference, hand, tool), runs.csv (a row per run as it ends: outcome,\n"
    "take, release, bottles down, sides, length, reward), and after the last run guided_policy.csv (the learned\n"
    "DMP's 20 weights) and summary.json. Outcomes: Ok; HandLost (the hand's estimate went stale or the tracker lost\n"
    "it while guiding: the tool went back to the line, but the person did not let go); NotGuided (never taken or\n"
    "never let go); Failed (not arrived within ~max_run, or the arm's controller stopped following or went silent, or\n"
    "did not take follow mode within ~max_run). Only Ok runs are learned from. Exits 1 when the runs give\n"
    "nothing to learn (fewer than 2 Ok runs, or an alignment that fails), with the reason.\n";

/// Before each run the arm goes to the start (MoveToStart) and the scene is reset with it there (a robot's reset
/// leaves the arm where it is, and the move back from the goal would sweep through the bottles laid anew; the first
/// run has no reset); half a second after a reset for the new scene's states, the controller is switched to follow
/// mode (Follow, retried until it takes, up to ~max_run) and the tool holds at the line's start (Approach).
enum class Stage { MoveToStart, Follow, Approach, Run, Settle, Done };

const char* phaseName(Stage stage, bt::GuidanceFollower::Phase phase) {
  if (stage == Stage::MoveToStart || stage == Stage::Follow || stage == Stage::Approach) {
    return "approach";
  }
  switch (phase) {
    case bt::GuidanceFollower::Phase::Line:
      return "line";
    case bt::GuidanceFollower::Phase::Guided:
      return "guided";
    case bt::GuidanceFollower::Phase::Back:
      return "back";
    case bt::GuidanceFollower::Phase::Arrived:
      return "arrived";
  }
  return "?";
}

/// ARM/set_mode calls on threads of their own, one at a time: a controller process that is stopped (SIGSTOP) still
/// has its connection accepted by the kernel and never answers, and roscpp's service calls have no timeout; the
/// timer polls for the answer instead of waiting in it.
class ModeCalls {
 public:
  struct Answer {
    int id = 0;
    std::string mode, message;
    bool success = false;
  };
  explicit ModeCalls(std::string service) : service_(std::move(service)) {}
  const std::string& service() const { return service_; }
  /// Whether the last call is still unanswered.
  bool busy() const { return in_flight_ && !in_flight_->done.load(std::memory_order_acquire); }
  /// Starts a call of `mode`: its id, or 0 (nothing started) while the last one is unanswered.
  int start(const std::string& mode) {
    if (busy()) return 0;
    auto call = std::make_shared<Call>();
    call->answer.id = ++ids_;
    call->answer.mode = mode;
    in_flight_ = call;
    std::thread([call, service = service_] {
      bimanual_skills::SetControlMode request;
      request.request.mode = call->answer.mode;
      const bool answered = ros::service::call(service, request);
      call->answer.success = answered && request.response.success;
      call->answer.message = answered ? request.response.message : "no answer from " + service;
      call->done.store(true, std::memory_order_release);
    }).detach();
    return call->answer.id;
  }
  /// The last call's answer, once it came (id 0 before any).
  Answer last() const { return in_flight_ && !busy() ? in_flight_->answer : Answer{}; }

 private:
  struct Call {
    Answer answer;
    std::atomic<bool> done{false};
  };
  std::string service_;
  std::shared_ptr<Call> in_flight_;
  int ids_ = 0;
};

class Guidance {
 public:
  Guidance(ros::NodeHandle& node, ros::NodeHandle& private_node) {
    bs::ros_layer::ParameterReader p(private_node, "bottles_guidance");
    bt::WamBottleConfig config = bt::WamBottleConfig::fromYamlFile(
        p.text("task", ros::package::getPath("bimanual_skills") + "/config/bottles_wam.yaml"));
    task_ = std::make_unique<bt::WamBottleTask>(config);
    out_ = p.text("out", (std::filesystem::current_path() / "bottles_guidance").string());
    runs_ = p.integer("runs", 20, 1, 1000);
    gesture_height_ = p.number("gesture_height", config.start.z() + 0.275, -10.0, 10.0);
    period_ = 1.0 / p.number("rate", 100.0, 1.0, 1000.0);
    move_time_ = p.number("move_time", 3.0, 0.1, 600.0);
    approach_ = p.number("approach", 1.0, 0.0, 600.0);
    settle_ = p.number("settle", 0.5, 0.0, 60.0);
    max_run_ = p.number("max_run", 30.0, 1.0, 600.0);
    const double seed = p.number("seed", 1.0, 0.0, 4294967295.0);
    if (seed != std::floor(seed)) throw std::invalid_argument("~seed must be an integer in [0, 2^32)");
    seed_ = static_cast<std::uint32_t>(seed);
    hand_max_age_ = p.number("hand_max_age", 0.3, 1e-3, 10.0);
    controller_max_age_ = p.number("controller_max_age", 0.5, 1e-3, 10.0);
    guidance_.line_speed = 1.0 / config.duration;
    guidance_.lag = p.number("lag", guidance_.lag, 1e-3, 10.0);
    guidance_.max_speed = p.number("max_speed", guidance_.max_speed, 1e-3, 100.0);
    follower_.emplace(guidance_);
    const std::string hand_topic = p.text("hand_topic", "/object_tracker/object");
    const std::string tool_topic = p.text("tool_topic", "/" + config.arm + "/follow_state");
    const std::string obstacles_topic = p.text("obstacles_topic", "/bullet_sim/obstacle_poses");
    const std::string reset = p.text("reset_service", "/bullet_sim/reset");
    p.warnUnknown();
    std::filesystem::create_directories(out_);
    runs_csv_.open(out_ + "/runs.csv");
    runs_csv_ << "run,outcome,take,release,end,bottles_down,side_1,side_2,crossed,satisfactory,length,reward\n";
    if (!reset.empty()) reset_ = node.serviceClient<std_srvs::Trigger>(reset);
    target_ = private_node.advertise<bimanual_skills::TrackedObject>("target", 10);
    command_ = node.advertise<trajectory_msgs::JointTrajectory>("/" + config.arm + "/command", 1);
    set_mode_.emplace("/" + config.arm + "/set_mode");
    phase_ = private_node.advertise<bimanual_skills::GuidancePhase>("phase", 1, true);
    markers_ = private_node.advertise<visualization_msgs::MarkerArray>("markers", 1);
    hand_ = node.subscribe(hand_topic, 10, &Guidance::onHand, this);
    tool_ = node.subscribe(tool_topic, 10, &Guidance::onTool, this);
    obstacles_ = node.subscribe(obstacles_topic, 2, &Guidance::onObstacles, this);
    timer_ = node.createTimer(ros::Duration(period_), &Guidance::onTick, this);
    ROS_INFO(
        "bottles_guidance: %d guided runs of the %s arm along %s, a hand above z = %.3f m takes it; hand %s, "
        "tool %s, records in %s",
        runs_, config.arm.c_str(), config.sim_config.c_str(), gesture_height_, hand_topic.c_str(), tool_topic.c_str(),
        out_.c_str());
  }

  bool done() const { return stage_ == Stage::Done; }
  /// Whether a policy was learned after the last run.
  bool learned() const { return learned_; }

 private:
  struct Row {
    double time;
    const char* phase;  ///< phaseName()'s
    Eigen::Vector2d reference;
    Eigen::Vector3d hand;
    bool raised;
    Eigen::Vector3d tool;
  };

  void onHand(const bimanual_skills::TrackedObject& m) {
    const auto& q = m.pose.pose.position;
    const Eigen::Vector3d p(q.x, q.y, q.z);
    if (!p.allFinite()) return;
    hand_position_ = p;
    hand_tracking_ = m.tracking;
    hand_stamp_ = m.header.stamp.toSec();
  }
  void onTool(const bimanual_skills::FollowerState& m) {
    const Eigen::Vector3d p(m.tool.x, m.tool.y, m.tool.z);
    if (p.allFinite()) tool_position_ = p;
    controller_following_ = m.following;
    controller_reason_ = m.reason;
    controller_stamp_ = ros::Time::now().toSec();  // on this node's clock, as the ticks' (hosts' clocks may differ)
    if (m.following && (stage_ == Stage::Approach || stage_ == Stage::Run || stage_ == Stage::Settle)) {
      controller_confirmed_ = true;
    }
  }
  void onObstacles(const geometry_msgs::PoseArray& m) {
    down_ = 0;
    for (const geometry_msgs::Pose& pose : m.poses) {
      const Eigen::Quaterniond q(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
      if (q.norm() > 0.5 && (q.normalized() * Eigen::Vector3d::UnitZ()).z() < std::cos(task_->config().tilt)) ++down_;
    }
  }

  void publishPhase(const ros::Time& now, const std::string& outcome = "") {
    const char* name = stage_ == Stage::Done ? "done" : phaseName(stage_, follower_->phase());
    if (std::strcmp(name, last_phase_) == 0 && run_ == last_run_) return;
    bimanual_skills::GuidancePhase m;
    m.header.stamp = now;
    m.run = static_cast<std::uint32_t>(run_);
    m.runs = static_cast<std::uint32_t>(runs_);
    m.phase = name;
    m.outcome = outcome;
    phase_.publish(m);
    ROS_INFO("bottles_guidance: run %d: %s", run_, name);
    last_phase_ = name;
    last_run_ = run_;
  }

  void publishTarget(const Eigen::Vector2d& line, const Eigen::Vector2d& velocity, const ros::Time& now) {
    bimanual_skills::TrackedObject t;
    t.header.stamp = now;
    t.header.frame_id = "world";
    t.tracking = true;
    t.state = "tracking";
    const Eigen::Vector3d p = task_->fromLine(line);
    t.pose.pose.position.x = p.x();
    t.pose.pose.position.y = p.y();
    t.pose.pose.position.z = p.z();
    t.pose.pose.orientation.w = 1.0;
    const Eigen::Vector3d v = task_->fromLine(velocity) - task_->fromLine(Eigen::Vector2d::Zero());
    t.velocity.x = v.x();
    t.velocity.y = v.y();
    t.velocity.z = v.z();
    t.last_accepted = now;
    target_.publish(t);
  }

  void onTick(const ros::TimerEvent& event) {
    const ros::Time now = event.current_real;
    const double t = now.toSec();
    if (stage_ == Stage::Done) return;
    if (last_tick_ < 0.0) {
      last_tick_ = t;
      stage_start_ = t;
    }
    const double dt = t - last_tick_;
    last_tick_ = t;
    // A clock that stood still or jumped back (a paused or reset simulation), or a long gap: hold this tick; a clock
    // that jumped back starts the stage again.
    const bool usable = dt > 0.0 && dt < 0.5;
    if (dt < 0.0) stage_start_ = t;
    if (stage_ == Stage::MoveToStart) {
      // The arm to the task's start posture (its tool at the line's start, pointing down) by a joint trajectory,
      // then into follow mode: the follower takes over where the tool already is. Sent once the controller has
      // answered the last run's hold (a stopped controller would take it, and the reset after it, only when it
      // resumes, far from where they belong); a controller silent for ~max_run fails the run.
      if (!moving_ && set_mode_->busy()) {
        publishTarget(Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), now);
        publishPhase(now);
        if (t - stage_start_ > max_run_) {
          finishRun(set_mode_->service() + " hold unanswered within ~max_run: the arm's controller is not answering",
                    now);
        }
        return;
      }
      if (!moving_) {
        stage_start_ = t;  // the move's time runs from when it is sent
        trajectory_msgs::JointTrajectory move;
        move.header.stamp = ros::Time(0);
        move.joint_names = task_->jointNames()[static_cast<std::size_t>(task_->arm())];
        trajectory_msgs::JointTrajectoryPoint point;
        const Eigen::VectorXd q = task_->starts()[static_cast<std::size_t>(task_->arm())];
        point.positions.assign(q.data(), q.data() + q.size());
        point.velocities.assign(static_cast<std::size_t>(q.size()), 0.0);
        point.time_from_start = ros::Duration(move_time_);
        move.points.push_back(point);
        command_.publish(move);
        moving_ = true;
      }
      if (t - stage_start_ >= move_time_ + 0.5) {
        moving_ = false;
        follow_wait_ = 0.0;
        if (reset_pending_) {
          reset_pending_ = false;
          resetScene();
          follow_wait_ = 0.5;
        }
        stage_ = Stage::Follow;
        stage_start_ = t;
      }
      publishTarget(Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), now);
      publishPhase(now);
      return;
    }
    // After a reset (a simulator's clock goes back: the stage starts again on it), half a second for the arm's
    // states of the new scene; then the controller follows the reference from where the tool is.
    if (stage_ == Stage::Follow) {
      publishTarget(Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), now);
      if (t - stage_start_ < follow_wait_) return;
      const ModeCalls::Answer answer = set_mode_->last();
      const bool answered = follow_call_ != 0 && answer.id == follow_call_;
      if (!answered || !answer.success) {
        const std::string why = set_mode_->busy() ? "no answer yet" : answered ? answer.message : "not asked yet";
        if (t - stage_start_ > max_run_) {
          finishRun(set_mode_->service() + " follow not taken within ~max_run: " + why, now);
          return;
        }
        if (answered) {
          ROS_WARN_THROTTLE(2.0, "bottles_guidance: %s follow: %s (trying again)", set_mode_->service().c_str(),
                            why.c_str());
        }
        if (!set_mode_->busy() && (!answered || t >= follow_retry_at_)) {
          follow_call_ = set_mode_->start("follow");
          follow_retry_at_ = t + 0.5;
        }
        return;
      }
      follow_call_ = 0;
      stage_ = Stage::Approach;
      stage_start_ = t;
      controller_confirmed_ = false;
      publishPhase(now);
      return;
    }
    if (stage_ == Stage::Approach) {
      publishTarget(Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), now);
      if (t - stage_start_ >= approach_) {
        stage_ = Stage::Run;
        stage_start_ = t;
        follower_->reset();
        rows_.clear();
        take_ = release_ = -1.0;
      }
      publishPhase(now);
      return;
    }
    // The arm's controller left follow mode (its states came late, a velocity limit) or went silent (stopped,
    // dead): the tool no longer went where the person led it; the run ends and is not learned from.
    if (usable && (stage_ == Stage::Run || stage_ == Stage::Settle)) {
      std::string stopped;
      if (!controller_confirmed_ && t - stage_start_ > controller_max_age_) {
        stopped = "the arm's controller never reported following";
      } else if (controller_confirmed_ && !controller_following_) {
        stopped = "the arm's controller stopped following" +
                  (controller_reason_.empty() ? std::string() : " (" + controller_reason_ + ")");
      } else if (controller_confirmed_ && t - controller_stamp_ > controller_max_age_) {
        std::ostringstream age;
        age << "the arm's controller went silent (no follow_state for " << t - controller_stamp_ << " s)";
        stopped = age.str();
      }
      if (!stopped.empty()) {
        ROS_WARN("bottles_guidance: run %d: %s", run_, stopped.c_str());
        finishRun(stopped, now);
        return;
      }
    }
    const bool fresh = hand_tracking_ && t - hand_stamp_ <= hand_max_age_;
    const bool raised = fresh && hand_position_.z() > gesture_height_;
    if (usable && stage_ == Stage::Run) {
      const bt::GuidanceFollower::Phase before = follower_->phase();
      // A hand lost while it guides lets go of the arm (safe), but the person did not: not a guided run to learn.
      if (before == bt::GuidanceFollower::Phase::Guided && !fresh && !hand_lost_) {
        hand_lost_ = true;
        ROS_WARN(
            "bottles_guidance: run %d: the hand's estimate is %s while it guides: the tool goes back to the line; "
            "the run is recorded as HandLost and not learned from",
            run_, hand_tracking_ ? "stale" : "lost by the tracker");
      }
      const bt::GuidanceFollower::Phase phase = follower_->step(dt, raised, task_->toLine(hand_position_));
      if (before == bt::GuidanceFollower::Phase::Line && phase == bt::GuidanceFollower::Phase::Guided) {
        take_ = t - stage_start_;
      }
      if (before == bt::GuidanceFollower::Phase::Guided && phase == bt::GuidanceFollower::Phase::Back) {
        release_ = t - stage_start_;
      }
      if (phase == bt::GuidanceFollower::Phase::Arrived) {
        end_ = t - stage_start_;
        stage_ = Stage::Settle;
      } else if (t - stage_start_ > max_run_) {
        finishRun("not arrived within ~max_run", now);
        return;
      }
    }
    publishTarget(follower_->position(), follower_->velocity(), now);
    rows_.push_back({t - stage_start_, phaseName(stage_, follower_->phase()), follower_->position(), hand_position_,
                     raised, tool_position_});
    if (stage_ == Stage::Settle && t - stage_start_ >= end_ + settle_) finishRun("", now);
    publishPhase(now);
    if (rows_.size() % 10 == 0) publishMarkers(now);
  }

  void resetScene() {
    std_srvs::Trigger call;
    if (!reset_.call(call) || !call.response.success) {
      ROS_WARN("bottles_guidance: %s failed: %s", reset_.getService().c_str(), call.response.message.c_str());
    }
  }

  void publishMarkers(const ros::Time& now) {
    visualization_msgs::MarkerArray a;
    visualization_msgs::Marker line =
        bs::nodes::marker("world", "line", 0, visualization_msgs::Marker::LINE_STRIP, now);
    line.scale.x = 0.004;
    line.color.r = line.color.g = line.color.b = 0.3f;
    line.color.a = 1.0f;
    line.points = {bs::nodes::toPoint(task_->fromLine({0.0, 0.0})), bs::nodes::toPoint(task_->fromLine({1.0, 0.0}))};
    a.markers.push_back(line);
    visualization_msgs::Marker path =
        bs::nodes::marker("world", "tool_path", 0, visualization_msgs::Marker::LINE_STRIP, now);
    path.scale.x = 0.006;
    path.color.b = 1.0f;
    path.color.a = 1.0f;
    for (const Row& r : rows_) path.points.push_back(bs::nodes::toPoint(r.tool));
    if (path.points.size() >= 2) a.markers.push_back(path);
    visualization_msgs::Marker hand = bs::nodes::marker("world", "hand", 0, visualization_msgs::Marker::SPHERE, now);
    hand.scale.x = hand.scale.y = hand.scale.z = 0.05;
    hand.color.r = 1.0f;
    hand.color.g = rows_.empty() || !rows_.back().raised ? 0.6f : 0.1f;
    hand.color.a = 0.8f;
    hand.pose.position = bs::nodes::toPoint(hand_position_);
    hand.pose.orientation.w = 1.0;
    a.markers.push_back(hand);
    markers_.publish(a);
  }

  void finishRun(const std::string& failure, const ros::Time& now) {
    const std::string name = out_ + "/run_" + std::to_string(run_) + ".csv";
    {
      std::ofstream csv(name);
      csv << "time,phase,reference_along,reference_left,hand_x,hand_y,hand_z,raised,tool_x,tool_y,tool_z\n";
      for (const Row& r : rows_) {
        csv << r.time << ',' << r.phase << ',' << r.reference.x() << ',' << r.reference.y() << ',' << r.hand.x() << ','
            << r.hand.y() << ',' << r.hand.z() << ',' << (r.raised ? 1 : 0) << ',' << r.tool.x() << ',' << r.tool.y()
            << ',' << r.tool.z() << '\n';
      }
    }
    bt::WamBottleRollout score;
    score.tool_path.resize(3, static_cast<Eigen::Index>(rows_.size()));
    score.path_times.resize(static_cast<Eigen::Index>(rows_.size()));
    for (std::size_t i = 0; i < rows_.size(); ++i) {
      score.tool_path.col(static_cast<Eigen::Index>(i)) = rows_[i].tool;
      score.path_times[static_cast<Eigen::Index>(i)] = rows_[i].time;
    }
    task_->score(score, down_);
    std::string outcome = "Ok";
    if (!failure.empty()) {
      outcome = "Failed";
    } else if (hand_lost_) {
      outcome = "HandLost";
    } else if (take_ < 0.0 || release_ < 0.0) {
      outcome = "NotGuided";
    }
    runs_csv_ << run_ << ',' << outcome << ',' << take_ << ',' << release_ << ',' << end_ << ',' << score.down << ','
              << score.sides[0] << ',' << score.sides[1] << ',' << (score.crossed ? 1 : 0) << ','
              << (score.satisfactory ? 1 : 0) << ',' << score.length << ',' << score.reward << '\n';
    runs_csv_.flush();
    ROS_INFO("bottles_guidance: run %d %s%s: take %.2f s, release %.2f s, %d bottles down, %s, reward %.3f (%s)", run_,
             outcome.c_str(), failure.empty() ? "" : (" (" + failure + ")").c_str(), take_, release_, score.down,
             score.crossed ? "crossed" : "not crossed", score.reward, name.c_str());
    if (outcome == "Ok") {
      std::array<double, 3> seconds{};
      try {
        parts_.push_back(
            bt::splitGuidedPath(*task_, score.tool_path, score.path_times, take_, release_, end_, seconds));
        seconds_.push_back(seconds);
        rewards_.push_back(score.reward);
        satisfactory_ += score.satisfactory ? 1 : 0;
      } catch (const std::invalid_argument& e) {
        ROS_WARN("bottles_guidance: run %d left out of the average: %s", run_, e.what());
      }
    }
    ++run_;
    if (run_ >= runs_) {
      try {
        learned_ = learn();
      } catch (const std::exception& e) {
        ROS_ERROR("bottles_guidance: nothing learned from the %zu guided runs: %s", parts_.size(), e.what());
      }
      stage_ = Stage::Done;
      publishPhase(now, outcome);
      return;
    }
    // The arm held while it goes back (answered or not: the next run's follow waits for this call to end).
    if (set_mode_->start("hold") == 0) {
      ROS_WARN("bottles_guidance: %s has not answered its last call: hold not sent", set_mode_->service().c_str());
    }
    rows_.clear();
    reset_pending_ = static_cast<bool>(reset_);
    stage_ = Stage::MoveToStart;
    stage_start_ = last_tick_;
    follower_->reset();
    hand_lost_ = false;
    take_ = release_ = -1.0;
    end_ = 0.0;
    publishPhase(now, outcome);
  }

  /// After the last run: the aligned, reward-weighted average's DMP, run and recorded. Throws with the reason the
  /// runs give no policy.
  bool learn() {
    if (parts_.size() < 2) {
      ROS_ERROR("bottles_guidance: %zu of %d runs were guided and recorded (Ok): nothing to learn from", parts_.size(),
                runs_);
      return false;
    }
    bt::GuidedLearningConfig config;
    config.guidance = guidance_;
    const bt::GuidedAverage average = bt::averageGuidedRuns(parts_, seconds_, rewards_, config, task_->kernels());
    std::ofstream policy(out_ + "/guided_policy.csv");
    policy << "weight\n";
    for (Eigen::Index i = 0; i < average.theta.size(); ++i) policy << average.theta[i] << '\n';
    const bt::WamBottleRollout run = task_->run(average.theta, seed_);
    bs::io::JsonRow row;
    row.add("guided_runs", static_cast<int>(parts_.size()))
        .add("guided_runs_satisfactory", satisfactory_)
        .add("policy_reward", run.reward)
        .add("policy_satisfactory", run.satisfactory)
        .add("policy_bottles_down", run.down)
        .add("policy_crossed", run.crossed)
        .add("alignment_cost_before", average.alignment[1].cost_before)
        .add("alignment_cost_after", average.alignment[1].cost_after);
    bs::io::writeSummaryJson(out_ + "/summary.json",
                             {"bottles_guidance", "guided", seed_, false, bs::cli::numericsState()}, {row});
    ROS_INFO(
        "bottles_guidance: learned from %zu guided runs (%d satisfactory): the DMP of their aligned, "
        "reward-weighted average, run on the simulated WAM: reward %.3f, %d bottles down, %s%s; %s/guided_policy.csv",
        parts_.size(), satisfactory_, run.reward, run.down, run.crossed ? "crossed" : "not crossed",
        run.satisfactory ? " (satisfactory)" : "", out_.c_str());
    return true;
  }

  std::unique_ptr<bt::WamBottleTask> task_;
  bt::GuidanceConfig guidance_;
  std::optional<bt::GuidanceFollower> follower_;
  std::string out_;
  int runs_ = 20, run_ = 0, down_ = 0, satisfactory_ = 0;
  double gesture_height_ = 0.0, period_ = 0.01, approach_ = 4.0, settle_ = 0.5, max_run_ = 30.0, hand_max_age_ = 0.3;
  double move_time_ = 3.0, follow_wait_ = 0.0, controller_max_age_ = 0.5, controller_stamp_ = -1e9;
  bool controller_following_ = false, controller_confirmed_ = false;
  std::string controller_reason_;
  Stage stage_ = Stage::MoveToStart;
  bool moving_ = false;
  double stage_start_ = 0.0, last_tick_ = -1.0, take_ = -1.0, release_ = -1.0, end_ = 0.0;
  Eigen::Vector3d hand_position_ = Eigen::Vector3d::Zero(), tool_position_ = Eigen::Vector3d::Zero();
  bool hand_tracking_ = false;
  double hand_stamp_ = -1e9;
  std::vector<Row> rows_;
  std::vector<std::array<Eigen::MatrixXd, 3>> parts_;
  std::vector<std::array<double, 3>> seconds_;
  std::vector<double> rewards_;
  std::ofstream runs_csv_;
  const char* last_phase_ = "";
  int last_run_ = -1;
  std::uint32_t seed_ = 1;
  bool hand_lost_ = false, learned_ = false, reset_pending_ = false;
  ros::Publisher target_, phase_, markers_, command_;
  ros::Subscriber hand_, tool_, obstacles_;
  ros::ServiceClient reset_;
  std::optional<ModeCalls> set_mode_;
  int follow_call_ = 0;
  double follow_retry_at_ = 0.0;
  ros::Timer timer_;
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "bottles_guidance");
  ros::NodeHandle node, private_node("~");
  try {
    Guidance guidance(node, private_node);
    ros::WallRate wait(100.0);
    while (ros::ok() && !guidance.done()) {
      ros::spinOnce();
      wait.sleep();
    }
    if (guidance.done() && !guidance.learned()) return 1;
  } catch (const std::exception& e) {
    ROS_FATAL("bottles_guidance: %s", e.what());
    return 1;
  }
  return 0;
}
