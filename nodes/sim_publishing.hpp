/// \file
/// bullet_sim's publishing, off the loop thread: the loop hands each cycle's joint states (hosting::StateSink) and,
/// at the marker rate, the cloth to two threads through triple buffers and semaphores. The first publishes /clock
/// and joint_states (and logs the grippers' scheduled commands); the second the scene markers, ~cloth, the moving
/// object's true motion (~object_truth) and, at their rates, the top-down camera's images and the perspective RGB-D
/// camera's (rgbd/...).
#pragma once

#include "bimanual_skills/hosting/control_loop.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/realtime/triple_buffer.hpp"
#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/raw_rgbd_sensor.hpp"
#include "scene_markers.hpp"

#include <geometry_msgs/PoseArray.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <pthread.h>
#include <semaphore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace bimanual_skills::nodes {

/// At most `rate` passes per wall second (0: no bound), for a publisher thread that takes the newest of what a
/// faster loop hands over: pass() waits out what is left of the interval since the last pass, so that the caller
/// then takes what is newest after the wait.
class WallRateCap {
 public:
  explicit WallRateCap(double rate)
      : interval_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(rate > 0.0 ? std::min(1.0 / rate, kLongest) : 0.0))),
        last_(std::chrono::steady_clock::now() - interval_) {}
  /// Returns true if it waited (something newer may have come meanwhile); `at_once`: no wait.
  bool pass(bool at_once) {
    const bool wait = !at_once && std::chrono::steady_clock::now() < last_ + interval_;
    if (wait) std::this_thread::sleep_until(last_ + interval_);
    last_ = std::chrono::steady_clock::now();
    return wait;
  }

 private:
  static constexpr double kLongest = 3600.0;  ///< [s]: a rate under one an hour waits an hour (no overflow).
  std::chrono::steady_clock::duration interval_;
  std::chrono::steady_clock::time_point last_;
};

/// Publishes what the loop hands over. states() runs on the loop thread (real-time safe: copies into preallocated
/// slots and posts a semaphore); everything else on its own threads.
class SimPublishing final : public hosting::StateSink {
 public:
  struct Settings {
    double marker_rate = 30.0;  ///< Cloth markers and ~cloth per simulated second.
    /// Scenes (markers, ~cloth, the cameras' images) per wall second at most: a simulation 20 times faster than
    /// real time would otherwise keep a core drawing 640 x 480 images (and starve the learner beside it).
    double max_scene_rate = 60.0;
    /// Joint states and /clock per wall second at most (0: every state the loop hands out, as lockstep with external
    /// controllers needs). Many times faster than real time the loop hands out tens of thousands a second, which
    /// every node on /clock and robot_state_publisher (a TF tree per joint state) would have to take.
    double max_state_rate = 2000.0;
    double camera_rate = 30.0;  ///< Camera images per simulated second (0: no camera).
    vision::RenderNoise camera_noise;
    double rgbd_rate = 0.0;  ///< Perspective RGB-D images per simulated second (0: no such camera).
    vision::PinholeCamera rgbd;
    vision::DepthSensorNoise rgbd_noise;
    /// Standing in for hardware: no /clock (the robot's clock is the wall's)...
    bool publish_clock = true;
    /// ...the RGB-D camera as a Kinect's driver sends it (vision::RawRgbdSensor: raw distorted colour with its
    /// plumb_bob camera_info, 16UC1 millimetre depth on rgbd_depth_optical_frame with its own camera_info)...
    bool raw_rgbd = false;
    /// ...the arms drawn in the RGB-D camera (their links as cylinders and spheres)...
    bool arms_in_view = false;
    /// ...and the states and images delivered this late [s of wall time], give or take a uniform jitter.
    double latency = 0.0, latency_jitter = 0.0;
  };
  /// Logs, on the publisher thread, the scheduled gripper commands done since the last call.
  using GripperLog = std::function<void()>;

  SimPublishing(ros::NodeHandle& node, ros::NodeHandle& private_node, const sim::BimanualSimulation& simulation,
                std::vector<std::string> joint_names, Settings settings, GripperLog log_grippers)
      : simulation_(simulation),
        names_(std::move(joint_names)),
        settings_(settings),
        log_grippers_(std::move(log_grippers)) {
    Snapshot initial;
    initial.position = initial.velocity = initial.effort =
        Eigen::VectorXd::Zero(static_cast<Eigen::Index>(names_.size()));
    snapshots_ = std::make_unique<realtime::TripleBuffer<Snapshot>>(initial);
    ClothFrame frame;
    if (simulation.hasCloth()) {
      frame.vertices = simulation.cloth().vertices();
      triangles_ = simulation.cloth().triangles();
      if (settings_.camera_rate > 0.0) {
        vision::ClothRendererParameters camera = tasks::rendererFor(simulation.config());
        camera.noise = settings_.camera_noise;
        renderer_ = std::make_unique<vision::ClothRenderer>(camera);
        camera_rng_.seed(simulation.config().seed);
      }
    }
    // The perspective camera sees the scene with or without a cloth (a mannequin, an object to track); standing in
    // for hardware, as a Kinect's driver sends it, with the arms in view.
    if (settings_.rgbd_rate > 0.0) {
      if (settings_.raw_rgbd) {
        vision::RawRgbdSensorConfig sensor;
        sensor.colour = settings_.rgbd;
        sensor.noise = settings_.rgbd_noise;
        raw_rgbd_ = std::make_unique<vision::RawRgbdSensor>(rgbdScene(simulation.config()), sensor);
      } else {
        rgbd_ = std::make_unique<vision::PerspectiveRenderer>(rgbdScene(simulation.config()), settings_.rgbd,
                                                              settings_.rgbd_noise);
      }
      rgbd_rng_.seed(simulation.config().seed + 1u);
      if (simulation.hasObject()) addMovingSolid(tasks::sceneSolid(simulation.config().object.body));
      if (settings_.arms_in_view) addArms();
      for (std::size_t k = 0; k < simulation.config().obstacles.size(); ++k) {
        if (simulation.config().obstacles[k].mass <= 0.0) continue;
        const int solid = addMovingSolid(tasks::sceneSolid(simulation.config().obstacles[k]));
        setMovingPose(solid, simulation.obstaclePose(static_cast<int>(k)));
        free_solids_.emplace_back(k, solid);
      }
    }
    frame.object = simulation.hasObject() ? simulation.objectPose() : Eigen::Isometry3d::Identity();
    frame.joints = initial.position;
    for (std::size_t k = 0; k < simulation.config().obstacles.size(); ++k) {
      frame.obstacles.push_back(simulation.obstaclePose(static_cast<int>(k)));
      free_obstacles_ = free_obstacles_ || simulation.config().obstacles[k].mass > 0.0;
    }
    frames_ = std::make_unique<realtime::TripleBuffer<ClothFrame>>(frame);
    sem_init(&state_signal_, 0, 0);
    sem_init(&scene_signal_, 0, 0);
    joint_states_ = node.advertise<sensor_msgs::JointState>("joint_states", 10);
    clock_ = node.advertise<rosgraph_msgs::Clock>("/clock", 10);
    markers_ = private_node.advertise<visualization_msgs::MarkerArray>("markers", 1, true);
    cloth_ = private_node.advertise<sensor_msgs::PointCloud2>("cloth", 1, true);
    if (simulation.hasObject()) object_ = private_node.advertise<nav_msgs::Odometry>("object_truth", 10);
    if (free_obstacles_) obstacle_poses_ = private_node.advertise<geometry_msgs::PoseArray>("obstacle_poses", 10);
    std::vector<geometry_msgs::TransformStamped> frames;
    if (renderer_) {
      camera_ = ros_layer::RgbdPublisher(node, false);
      frames.push_back(ros_layer::cameraTransform(renderer_->parameters().camera, "world", kCameraFrame, ros::Time(0)));
    }
    if (rgbd_) {
      rgbd_camera_ = ros_layer::RgbdPublisher(node, false, "rgbd");
      frames.push_back(ros_layer::cameraTransform(rgbd_->camera(), "world", kRgbdFrame, ros::Time(0)));
    }
    if (raw_rgbd_) {
      raw_colour_ = node.advertise<sensor_msgs::Image>("rgbd/image_raw", 1);
      raw_colour_info_ = node.advertise<sensor_msgs::CameraInfo>("rgbd/camera_info", 1);
      raw_depth_ = node.advertise<sensor_msgs::Image>("rgbd/depth/image_raw", 1);
      raw_depth_info_ = node.advertise<sensor_msgs::CameraInfo>("rgbd/depth/camera_info", 1);
      frames.push_back(ros_layer::cameraTransform(settings_.rgbd, "world", kRgbdFrame, ros::Time(0)));
      vision::PinholeCamera depth = settings_.rgbd;
      depth.pose = raw_rgbd_->depthPose();
      frames.push_back(ros_layer::cameraTransform(depth, "world", kRgbdDepthFrame, ros::Time(0)));
    }
    if (!frames.empty()) camera_frame_.sendTransform(frames);
    state_thread_ = std::thread([this] { stateLoop(); });
    scene_thread_ = std::thread([this] { sceneLoop(); });
    // Named for top -H and scripts/thread_cpu.py (the loop runs on the process's main thread).
    pthread_setname_np(state_thread_.native_handle(), "sim_states");
    pthread_setname_np(scene_thread_.native_handle(), "sim_scene");
    // The scene's rendering (cameras, markers: 84 % of a core with the RGB-D camera at 30 Hz) is no part of the
    // robot's real-time path: at the normal policy even in a process run at SCHED_FIFO (sim.launch
    // process_priority), where it would take a core from every other process.
    sched_param normal{};
    (void)pthread_setschedparam(scene_thread_.native_handle(), SCHED_OTHER, &normal);
  }

  ~SimPublishing() override {
    running_ = false;
    sem_post(&state_signal_);
    sem_post(&scene_signal_);
    state_thread_.join();
    scene_thread_.join();
    sem_destroy(&state_signal_);
    sem_destroy(&scene_signal_);
  }
  SimPublishing(const SimPublishing&) = delete;
  SimPublishing& operator=(const SimPublishing&) = delete;

  /// Loop thread: the joint states at t; at the marker rate (always when forced) the cloth too, with the camera's
  /// images when forced (the end of a ~step).
  void states(double t, const std::vector<sim::JointState>& states, bool forced) noexcept override {
    Snapshot& s = snapshots_->writeSlot();
    s.time = t;
    s.forced = forced;
    Eigen::Index offset = 0;
    for (const sim::JointState& state : states) {
      const Eigen::Index n = state.position.size();
      s.position.segment(offset, n) = state.position;
      s.velocity.segment(offset, n) = state.velocity;
      s.effort.segment(offset, n) = state.effort;
      offset += n;
    }
    snapshots_->publish();
    sem_post(&state_signal_);
    if ((simulation_.hasCloth() || rgbd_ || raw_rgbd_ || simulation_.hasObject() || free_obstacles_) &&
        (forced || t >= next_marker_ || t < last_marker_)) {
      ClothFrame& frame = frames_->writeSlot();
      frame.time = t;
      frame.joints = s.position;
      if (simulation_.hasCloth()) frame.vertices = simulation_.cloth().vertices();
      if (simulation_.hasObject()) {
        frame.object = simulation_.objectPose();
        frame.object_velocity = simulation_.objectVelocity();
        frame.object_holder = simulation_.objectHolder();
      }
      for (std::size_t k = 0; free_obstacles_ && k < frame.obstacles.size(); ++k) {
        frame.obstacles[k] = simulation_.obstaclePose(static_cast<int>(k));
      }
      frame.image = forced;
      frames_->publish();
      sem_post(&scene_signal_);
      next_marker_ = t + 1.0 / settings_.marker_rate;
      last_marker_ = t;
    }
  }

 private:
  static constexpr const char* kCameraFrame = "top_down_camera";
  static constexpr const char* kRgbdFrame = "rgbd_camera_optical_frame";
  static constexpr const char* kRgbdDepthFrame = "rgbd_depth_optical_frame";
  static constexpr double kArmRadius = 0.045;  ///< Of the arms' links as the camera sees them [m].

  struct Snapshot {
    double time = 0.0;
    bool forced = false;  ///< A ~step's end or a reset's start: published at once, whatever the rate.
    Eigen::VectorXd position, velocity, effort;  ///< All arms, in joint-name order.
  };
  struct ClothFrame {
    double time = 0.0;
    Eigen::Matrix3Xd vertices;
    bool image = false;  ///< The camera's images of this frame too, whatever the camera's rate.
    Eigen::Isometry3d object = Eigen::Isometry3d::Identity();  ///< The moving object, when the scene has one.
    Eigen::VectorXd joints;                                    ///< Every arm's joint positions, in joint-name order.
    Eigen::Vector3d object_velocity = Eigen::Vector3d::Zero();
    int object_holder = -1;
    std::vector<Eigen::Isometry3d> obstacles;  ///< Every obstacle's pose now (the free ones move), the file's order.
  };

  /// Waits for the loop's signal, at most `seconds` (< 1; so that a stopping node is seen).
  static void waitForSignal(sem_t& signal, double seconds = 0.1) {
    timespec deadline{};
    clock_gettime(CLOCK_REALTIME, &deadline);
    deadline.tv_nsec += static_cast<long>(seconds * 1e9);
    if (deadline.tv_nsec >= 1000000000) deadline.tv_nsec -= 1000000000, ++deadline.tv_sec;
    sem_timedwait(&signal, &deadline);
  }

  /// The RGB-D camera's static scene: the renderer's (tasks::rendererFor) without the obstacles that have a mass:
  /// they fall and are pushed, and the camera sees them as moving solids posed from each frame (free_solids_).
  static vision::ClothRendererParameters rgbdScene(const sim::SimConfig& config) {
    vision::ClothRendererParameters scene = tasks::rendererFor(config);
    scene.solids.clear();
    for (const sim::Obstacle& obstacle : config.obstacles) {
      if (obstacle.mass <= 0.0) scene.solids.push_back(tasks::sceneSolid(obstacle));
    }
    return scene;
  }
  /// A moving solid in the RGB-D camera, whichever it is.
  int addMovingSolid(const vision::SceneSolid& solid) {
    return raw_rgbd_ ? raw_rgbd_->addMovingSolid(solid) : rgbd_->addMovingSolid(solid);
  }
  void setMovingPose(int index, const Eigen::Isometry3d& pose) {
    if (raw_rgbd_) raw_rgbd_->setMovingPose(index, pose);
    if (rgbd_) rgbd_->setMovingPose(index, pose);
  }

  /// The arms' links as the camera sees them: a cylinder between consecutive joint frames (where they are apart) and
  /// a sphere at each, grey, posed from the joint positions of each frame (their lengths are the chain's).
  void addArms() {
    vision::SceneSolid sphere;
    sphere.shape = vision::SceneSolid::Shape::Sphere;
    sphere.size = Eigen::Vector3d(kArmRadius, 0.0, 0.0);
    sphere.colour = Eigen::Vector3d(0.35, 0.35, 0.38);
    Eigen::Index offset = 0;
    for (int a = 0; a < simulation_.armCount(); ++a) {
      ArmView arm;
      arm.model = std::make_unique<kinematics::ChainModel>(simulation_.armModel(a));
      arm.data = std::make_unique<kinematics::ChainData>(*arm.model);
      arm.base = simulation_.basePose(a);
      arm.offset = offset;
      offset += arm.model->nq();
      (void)kinematics::forwardKinematics(*arm.model, *arm.data, Eigen::VectorXd::Zero(arm.model->nq()));
      const std::vector<Eigen::Isometry3d>& frames = arm.data->frame_poses;
      for (std::size_t f = 0; f < frames.size(); ++f) {
        arm.spheres.push_back({static_cast<int>(f), addMovingSolid(sphere)});
        if (f + 1 == frames.size()) break;
        const double length = (frames[f + 1].translation() - frames[f].translation()).norm();
        if (length < 0.02) continue;
        vision::SceneSolid link = sphere;
        link.shape = vision::SceneSolid::Shape::Cylinder;
        link.size = Eigen::Vector3d(kArmRadius, length, 0.0);
        arm.links.push_back({static_cast<int>(f), addMovingSolid(link)});
      }
      arms_.push_back(std::move(arm));
    }
  }
  /// The arms' solids where the joints `q` (all arms, joint-name order) put them.
  void poseArms(const Eigen::VectorXd& q) {
    for (ArmView& arm : arms_) {
      if (kinematics::forwardKinematics(*arm.model, *arm.data, q.segment(arm.offset, arm.model->nq())) !=
          kinematics::KinematicsStatus::Success)
        continue;
      const std::vector<Eigen::Isometry3d>& frames = arm.data->frame_poses;
      for (const auto& [f, solid] : arm.spheres) {
        setMovingPose(solid, Eigen::Isometry3d(Eigen::Translation3d(arm.base * frames[f].translation())));
      }
      for (const auto& [f, solid] : arm.links) {
        const Eigen::Vector3d from = arm.base * frames[f].translation(), to = arm.base * frames[f + 1].translation();
        Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
        pose.translation() = 0.5 * (from + to);
        pose.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), to - from).toRotationMatrix();
        setMovingPose(solid, pose);
      }
    }
  }

  /// /clock first, so that the controllers' clocks move before the states arrive.
  void stateLoop() {
    sensor_msgs::JointState states;
    states.name = names_;
    WallRateCap cap(settings_.max_state_rate);
    double last_time = -std::numeric_limits<double>::infinity();
    while (running_ && ros::ok()) {
      waitForSignal(state_signal_, late_.empty() ? 0.1 : 0.0005);
      drainLate();
      log_grippers_();
      const Snapshot* s = snapshots_->readNew();
      if (!s) continue;
      // At most max_state_rate per wall second, the newest after the wait (so the last state before the loop stops
      // goes out too); a forced one and time going back (a reset) at once.
      if (cap.pass(s->forced || s->time < last_time)) {
        if (const Snapshot* newer = snapshots_->readNew()) s = newer;
      }
      last_time = s->time;
      const ros::Time stamp(s->time);
      if (settings_.publish_clock) {
        rosgraph_msgs::Clock clock;
        clock.clock = stamp;
        clock_.publish(clock);
      }
      states.header.stamp = stamp;
      states.position.assign(s->position.data(), s->position.data() + s->position.size());
      states.velocity.assign(s->velocity.data(), s->velocity.data() + s->velocity.size());
      states.effort.assign(s->effort.data(), s->effort.data() + s->effort.size());
      if (settings_.latency <= 0.0) {
        joint_states_.publish(states);
        continue;
      }
      // Delivered late, in order: each state waits its transport latency in a line that the next wake-ups drain.
      const double due =
          std::max(late_.empty() ? 0.0 : late_.back().first, realtime::monotonicSeconds() + delay(state_jitter_));
      late_.emplace_back(due, states);
      drainLate();
    }
  }

  /// The transport latency of one message [s], its jitter drawn from `rng` (each thread its own).
  double delay(std::mt19937& rng) const {
    return settings_.latency + settings_.latency_jitter * (2.0 * std::uniform_real_distribution<double>()(rng) - 1.0);
  }
  /// Publishes the late states that are due; waits (at most 1 ms) for the next one when nothing else comes.
  void drainLate() {
    while (!late_.empty() && late_.front().first <= realtime::monotonicSeconds()) {
      joint_states_.publish(late_.front().second);
      late_.pop_front();
    }
  }

  void sceneLoop() {
    bool first = true;
    double next_image = 0.0, next_rgbd = 0.0, last_time = 0.0;
    WallRateCap cap(settings_.max_scene_rate);
    while (running_ && ros::ok()) {
      waitForSignal(scene_signal_);
      const ClothFrame* frame = frames_->readNew();
      if (!frame && !first) continue;
      if (!frame) frame = &frames_->current();
      // At most max_scene_rate scenes per wall second; the newest frame after the wait is the one published. The
      // last moment of a ~step (forced) and a reset (time going back) go at once.
      if (cap.pass(first || frame->image || frame->time < last_time)) {
        if (const ClothFrame* newer = frames_->readNew()) frame = newer;
      }
      first = false;
      // The table each time too: the topic is latched, and a late subscriber gets only the last message. Stamped
      // 0 (the latest transform): rviz drops markers stamped before a reset's jump back in time.
      visualization_msgs::MarkerArray markers;
      if (simulation_.config().has_table)
        markers.markers.push_back(tableMarker(simulation_.config().table, ros::Time()));
      for (std::size_t k = 0; k < simulation_.config().obstacles.size(); ++k) {
        sim::Obstacle obstacle = simulation_.config().obstacles[k];
        obstacle.pose = frame->obstacles[k];
        markers.markers.push_back(obstacleMarker(obstacle, static_cast<int>(k), ros::Time()));
      }
      if (free_obstacles_) obstacle_poses_.publish(obstaclePoses(*frame));
      if (simulation_.hasCloth()) markers.markers.push_back(clothMarker(frame->vertices, triangles_, ros::Time()));
      if (simulation_.hasObject()) {
        sim::Obstacle body = simulation_.config().object.body;
        body.pose = frame->object;
        visualization_msgs::Marker object = obstacleMarker(body, 0, ros::Time());
        object.ns = "object";
        markers.markers.push_back(object);
        object_.publish(objectTruth(*frame));
        if (rgbd_ || raw_rgbd_) setMovingPose(0, frame->object);
      }
      if (!arms_.empty()) poseArms(frame->joints);
      for (const auto& [k, solid] : free_solids_) setMovingPose(solid, frame->obstacles[k]);
      markers_.publish(markers);
      if (simulation_.hasCloth()) cloth_.publish(clothCloud(frame->vertices, ros::Time(frame->time)));
      // An image every 1/camera_rate simulated seconds, and at once after a reset (time going back).
      if (renderer_ && (frame->image || frame->time >= next_image - 1e-9 || frame->time < last_time)) {
        if (renderer_->render(frame->vertices, triangles_, camera_rng_) == vision::VisionStatus::Ok) {
          std_msgs::Header header;
          header.stamp = ros::Time(frame->time);
          header.frame_id = kCameraFrame;
          camera_.publish(ros_layer::RgbdFrame(header, renderer_->bgr(), renderer_->depth(),
                                               ros_layer::cameraInfo(renderer_->parameters().camera, header)));
        }
        next_image = frame->time + 1.0 / settings_.camera_rate;
      }
      if (rgbd_ && (frame->image || frame->time >= next_rgbd - 1e-9 || frame->time < last_time)) {
        // Without a cloth there is no mesh to draw: the scene alone (EmptyMesh) is the image.
        const vision::VisionStatus status = rgbd_->render(frame->vertices, triangles_, rgbd_rng_);
        if (status == vision::VisionStatus::Ok ||
            (status == vision::VisionStatus::EmptyMesh && !simulation_.hasCloth())) {
          std_msgs::Header header;
          header.stamp = ros::Time(frame->time);
          header.frame_id = kRgbdFrame;
          rgbd_camera_.publish(ros_layer::RgbdFrame(header, rgbd_->bgr(), rgbd_->depth(),
                                                    ros_layer::cameraInfo(rgbd_->camera(), header)));
        }
        next_rgbd = frame->time + 1.0 / settings_.rgbd_rate;
      }
      if (raw_rgbd_ && (frame->image || frame->time >= next_rgbd - 1e-9 || frame->time < last_time)) {
        const vision::VisionStatus status = raw_rgbd_->render(frame->vertices, triangles_, rgbd_rng_);
        if (status == vision::VisionStatus::Ok ||
            (status == vision::VisionStatus::EmptyMesh && !simulation_.hasCloth())) {
          publishRaw(ros::Time(frame->time));
        }
        next_rgbd = frame->time + 1.0 / settings_.rgbd_rate;
      }
      last_time = frame->time;
    }
  }

  /// The raw RGB-D sensor's images as its driver sends them: colour and depth of one moment, each on its camera's
  /// frame with its camera_info, after the transport latency.
  void publishRaw(const ros::Time& stamp) {
    if (settings_.latency > 0.0) std::this_thread::sleep_for(std::chrono::duration<double>(delay(image_jitter_)));
    std_msgs::Header colour, depth;
    colour.stamp = depth.stamp = stamp;
    colour.frame_id = kRgbdFrame;
    depth.frame_id = kRgbdDepthFrame;
    raw_colour_.publish(cv_bridge::CvImage(colour, "bgr8", raw_rgbd_->rawBgr()).toImageMsg());
    raw_colour_info_.publish(ros_layer::cameraInfo(raw_rgbd_->colourCalibration(), colour));
    raw_depth_.publish(cv_bridge::CvImage(depth, "16UC1", raw_rgbd_->depthMillimetres()).toImageMsg());
    raw_depth_info_.publish(ros_layer::cameraInfo(raw_rgbd_->depthCalibration(), depth));
  }

  /// Every obstacle's pose (world frame, the scene file's order; the free ones where contacts moved them).
  static geometry_msgs::PoseArray obstaclePoses(const ClothFrame& frame) {
    geometry_msgs::PoseArray poses;
    poses.header.stamp = ros::Time(frame.time);
    poses.header.frame_id = "world";
    for (const Eigen::Isometry3d& pose : frame.obstacles) {
      geometry_msgs::Pose p;
      p.position = toPoint(pose.translation());
      const Eigen::Quaterniond q(pose.linear());
      p.orientation.w = q.w();
      p.orientation.x = q.x();
      p.orientation.y = q.y();
      p.orientation.z = q.z();
      poses.poses.push_back(p);
    }
    return poses;
  }

  /// The object's true pose and velocity (world frame; child frame: its name).
  nav_msgs::Odometry objectTruth(const ClothFrame& frame) const {
    nav_msgs::Odometry truth;
    truth.header.stamp = ros::Time(frame.time);
    truth.header.frame_id = "world";
    truth.child_frame_id = simulation_.config().object.body.name;
    const Eigen::Quaterniond q(frame.object.linear());
    truth.pose.pose.position = toPoint(frame.object.translation());
    truth.pose.pose.orientation.w = q.w();
    truth.pose.pose.orientation.x = q.x();
    truth.pose.pose.orientation.y = q.y();
    truth.pose.pose.orientation.z = q.z();
    truth.twist.twist.linear.x = frame.object_velocity.x();
    truth.twist.twist.linear.y = frame.object_velocity.y();
    truth.twist.twist.linear.z = frame.object_velocity.z();
    return truth;
  }

  /// The cloth's nodes (world frame) as a point cloud, in the simulation's node order.
  static sensor_msgs::PointCloud2 clothCloud(const Eigen::Matrix3Xd& vertices, const ros::Time& stamp) {
    sensor_msgs::PointCloud2 cloud;
    cloud.header.stamp = stamp;
    cloud.header.frame_id = "world";
    sensor_msgs::PointCloud2Modifier modifier(cloud);
    modifier.setPointCloud2FieldsByString(1, "xyz");
    modifier.resize(static_cast<std::size_t>(vertices.cols()));
    sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
    for (Eigen::Index i = 0; i < vertices.cols(); ++i, ++x, ++y, ++z) {
      *x = static_cast<float>(vertices(0, i));
      *y = static_cast<float>(vertices(1, i));
      *z = static_cast<float>(vertices(2, i));
    }
    return cloud;
  }

  const sim::BimanualSimulation& simulation_;
  std::vector<std::string> names_;
  Settings settings_;
  GripperLog log_grippers_;
  std::unique_ptr<realtime::TripleBuffer<Snapshot>> snapshots_;
  std::unique_ptr<realtime::TripleBuffer<ClothFrame>> frames_;
  Eigen::Matrix3Xi triangles_;                       ///< Constant.
  std::unique_ptr<vision::ClothRenderer> renderer_;  ///< The top-down camera (scene thread); null without one.
  std::mt19937 camera_rng_;
  std::unique_ptr<vision::PerspectiveRenderer> rgbd_;  ///< The perspective RGB-D camera (scene thread); null without.
  std::unique_ptr<vision::RawRgbdSensor> raw_rgbd_;    ///< Or the same as hardware sends it (scene thread).
  std::mt19937 rgbd_rng_;
  /// An arm as the camera sees it (scene thread): its chain, and the solids of its frames and links.
  struct ArmView {
    std::unique_ptr<kinematics::ChainModel> model;
    std::unique_ptr<kinematics::ChainData> data;
    Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
    Eigen::Index offset = 0;                          ///< Of its joints among all arms'.
    std::vector<std::pair<int, int>> spheres, links;  ///< (frame, solid): at a frame, from it to the next.
  };
  std::vector<ArmView> arms_;
  std::deque<std::pair<double, sensor_msgs::JointState>> late_;  ///< States in transport (state thread).
  std::mt19937 state_jitter_{7}, image_jitter_{8};  ///< The transport's jitter (state thread, scene thread).
  ros::Publisher raw_colour_, raw_colour_info_, raw_depth_, raw_depth_info_;
  tf2_ros::StaticTransformBroadcaster camera_frame_;
  ros::Publisher joint_states_, clock_, markers_, cloth_, object_, obstacle_poses_;
  bool free_obstacles_ = false;  ///< The scene has obstacles with a mass: their poses go out with the markers.
  /// The obstacles with a mass in the RGB-D camera: (obstacle, its moving solid).
  std::vector<std::pair<std::size_t, int>> free_solids_;
  ros_layer::RgbdPublisher camera_, rgbd_camera_;
  sem_t state_signal_{}, scene_signal_{};
  std::atomic<bool> running_{true};
  double next_marker_ = 0.0, last_marker_ = 0.0;  ///< Loop thread.
  std::thread state_thread_, scene_thread_;
};

}  // namespace bimanual_skills::nodes
