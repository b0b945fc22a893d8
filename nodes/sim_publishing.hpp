/// \file
/// bullet_sim's publishing, off the loop thread: the loop hands each cycle's joint states (hosting::StateSink) and,
/// at the marker rate, the cloth to two threads through triple buffers and semaphores. The first publishes /clock
/// and joint_states (and logs the grippers' scheduled commands); the second the scene markers, ~cloth, the moving
/// object's true motion (~object_truth) and, at their rates, the top-down camera's images and the perspective RGB-D
/// camera's (rgbd/...).
#pragma once

#include "bimanual_skills/hosting/control_loop.hpp"
#include "bimanual_skills/realtime/triple_buffer.hpp"
#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "scene_markers.hpp"

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
    // The perspective camera sees the scene with or without a cloth (a mannequin, an object to track).
    if (settings_.rgbd_rate > 0.0) {
      rgbd_ = std::make_unique<vision::PerspectiveRenderer>(tasks::rendererFor(simulation.config()), settings_.rgbd,
                                                            settings_.rgbd_noise);
      rgbd_rng_.seed(simulation.config().seed + 1u);
      if (simulation.hasObject()) rgbd_->addMovingSolid(tasks::sceneSolid(simulation.config().object.body));
    }
    frame.object = simulation.hasObject() ? simulation.objectPose() : Eigen::Isometry3d::Identity();
    frames_ = std::make_unique<realtime::TripleBuffer<ClothFrame>>(frame);
    sem_init(&state_signal_, 0, 0);
    sem_init(&scene_signal_, 0, 0);
    joint_states_ = node.advertise<sensor_msgs::JointState>("joint_states", 10);
    clock_ = node.advertise<rosgraph_msgs::Clock>("/clock", 10);
    markers_ = private_node.advertise<visualization_msgs::MarkerArray>("markers", 1, true);
    cloth_ = private_node.advertise<sensor_msgs::PointCloud2>("cloth", 1, true);
    if (simulation.hasObject()) object_ = private_node.advertise<nav_msgs::Odometry>("object_truth", 10);
    std::vector<geometry_msgs::TransformStamped> frames;
    if (renderer_) {
      camera_ = ros_layer::RgbdPublisher(node, false);
      frames.push_back(ros_layer::cameraTransform(renderer_->parameters().camera, "world", kCameraFrame, ros::Time(0)));
    }
    if (rgbd_) {
      rgbd_camera_ = ros_layer::RgbdPublisher(node, false, "rgbd");
      frames.push_back(ros_layer::cameraTransform(rgbd_->camera(), "world", kRgbdFrame, ros::Time(0)));
    }
    if (!frames.empty()) camera_frame_.sendTransform(frames);
    state_thread_ = std::thread([this] { stateLoop(); });
    scene_thread_ = std::thread([this] { sceneLoop(); });
    // Named for top -H and scripts/thread_cpu.py (the loop runs on the process's main thread).
    pthread_setname_np(state_thread_.native_handle(), "sim_states");
    pthread_setname_np(scene_thread_.native_handle(), "sim_scene");
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
    if ((simulation_.hasCloth() || rgbd_ || simulation_.hasObject()) &&
        (forced || t >= next_marker_ || t < last_marker_)) {
      ClothFrame& frame = frames_->writeSlot();
      frame.time = t;
      if (simulation_.hasCloth()) frame.vertices = simulation_.cloth().vertices();
      if (simulation_.hasObject()) {
        frame.object = simulation_.objectPose();
        frame.object_velocity = simulation_.objectVelocity();
        frame.object_holder = simulation_.objectHolder();
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
    Eigen::Vector3d object_velocity = Eigen::Vector3d::Zero();
    int object_holder = -1;
  };

  /// Waits for the loop's signal, at most 0.1 s (so that a stopping node is seen).
  static void waitForSignal(sem_t& signal) {
    timespec deadline{};
    clock_gettime(CLOCK_REALTIME, &deadline);
    deadline.tv_nsec += 100000000;
    if (deadline.tv_nsec >= 1000000000) deadline.tv_nsec -= 1000000000, ++deadline.tv_sec;
    sem_timedwait(&signal, &deadline);
  }

  /// /clock first, so that the controllers' clocks move before the states arrive.
  void stateLoop() {
    sensor_msgs::JointState states;
    states.name = names_;
    WallRateCap cap(settings_.max_state_rate);
    double last_time = -std::numeric_limits<double>::infinity();
    while (running_ && ros::ok()) {
      waitForSignal(state_signal_);
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
      rosgraph_msgs::Clock clock;
      clock.clock = stamp;
      clock_.publish(clock);
      states.header.stamp = stamp;
      states.position.assign(s->position.data(), s->position.data() + s->position.size());
      states.velocity.assign(s->velocity.data(), s->velocity.data() + s->velocity.size());
      states.effort.assign(s->effort.data(), s->effort.data() + s->effort.size());
      joint_states_.publish(states);
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
        markers.markers.push_back(obstacleMarker(simulation_.config().obstacles[k], static_cast<int>(k), ros::Time()));
      }
      if (simulation_.hasCloth()) markers.markers.push_back(clothMarker(frame->vertices, triangles_, ros::Time()));
      if (simulation_.hasObject()) {
        sim::Obstacle body = simulation_.config().object.body;
        body.pose = frame->object;
        visualization_msgs::Marker object = obstacleMarker(body, 0, ros::Time());
        object.ns = "object";
        markers.markers.push_back(object);
        object_.publish(objectTruth(*frame));
        if (rgbd_) rgbd_->setMovingPose(0, frame->object);
      }
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
      last_time = frame->time;
    }
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
  std::mt19937 rgbd_rng_;
  tf2_ros::StaticTransformBroadcaster camera_frame_;
  ros::Publisher joint_states_, clock_, markers_, cloth_, object_;
  ros_layer::RgbdPublisher camera_, rgbd_camera_;
  sem_t state_signal_{}, scene_signal_{};
  std::atomic<bool> running_{true};
  double next_marker_ = 0.0, last_marker_ = 0.0;  ///< Loop thread.
  std::thread state_thread_, scene_thread_;
};

}  // namespace bimanual_skills::nodes
