// object_tracker: finds a known object in an RGB-D camera's frames and tracks it (thesis Sec. 4.3.2, Fig. 4.10):
// tracking::ObjectTracker between the camera's topics and the tracked object's.
#include "bimanual_skills/tracking/object_tracker.hpp"
#include "bimanual_skills/TrackedObject.h"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/rgbd_reader.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "node_cli.hpp"

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <opencv2/imgproc.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace bs = bimanual_skills;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills object_tracker [ROS remappings]\n\n"
    "Finds a known object in an RGB-D camera's frames and tracks its centre in the world (thesis Sec. 4.3.2): its\n"
    "colour picked out in HSV, its upright shape fitted to its depth pixels through the camera's intrinsics and its\n"
    "pose on tf, a constant-velocity Kalman filter with a gate, and the reason whenever it is not tracked.\n\n"
    "Parameters (the object is required, nothing is assumed of it: ~object_from, or ~shape, ~size and ~colour):\n"
    "  ~object_from         a simulation file (config/track_sim.yaml) whose object's shape, size and colour are\n"
    "                       looked for\n"
    "  ~shape, ~size        the object: cylinder [radius, length], sphere [radius] or box [x, y, z] [m], upright\n"
    "  ~colour              its colour, RGB in [0, 1]: the hue looked for\n"
    "  ~camera              the camera's namespace (default rgbd): CAMERA/image_raw in any colour encoding (raw\n"
    "                       images rectified with CAMERA/camera_info's D, R and P)\n"
    "  ~camera_depth        depth (default: CAMERA/depth/image_raw and camera_info) or depth_registered; 32FC1\n"
    "                       metres or 16UC1 millimetres\n"
    "  ~register_depth      depth on a frame of its own is registered into the colour camera from tf (default false:\n"
    "                       refused, with where to get registered depth)\n"
    "  ~world_frame         the frame the object is tracked in (default world)\n"
    "  ~hue_tolerance       degrees (12); ~min_saturation (0.5), ~min_value (0.15) in [0, 1]\n"
    "  ~min_pixels (30), ~min_points (20)  fewer pixels of its colour: not seen; fewer with a depth: not measured\n"
    "  ~min_stddev          floor of the measurement's standard deviation [m] (0.002)\n"
    "  ~outlier_distance    points this far off the fitted surface (or the object's half diagonal and this from\n"
    "                       the points' median) are not the object's: an arm in front of it [m] (0.01)\n"
    "  ~acceleration_noise  the filter's q [m^2/s^3] (1); ~gate chi^2 (16.27); ~lost_after [s] (0.5);\n"
    "  ~reject_limit        measurements in a row outside the gate that lose it (5)\n"
    "  ~camera_timeout      [s] of the clock without a frame: the camera counts as stopped (0.5)\n"
    "  ~tf_timeout          [s] to wait for the camera's pose at a frame's stamp (0.1)\n\n"
    "Topics: subscribes to the camera's four (colour and depth paired within 20 ms); publishes ~object "
    "(bimanual_skills/TrackedObject: every frame, and\n"
    "  at 20 Hz while frames stop), ~pose (geometry_msgs/PoseWithCovarianceStamped, while tracked), ~markers (the\n"
    "  estimate, its 3-sigma ellipsoid and velocity; green tracked, red lost), ~debug_image (bgr8: the frame with\n"
    "  the object outlined) and /diagnostics (1 Hz: state, frames, processing time and its medians by stage: a "
    "frame's\n"
    "  age on arrival, the pose lookup, reading, locating).\n";

class ObjectTrackerNode {
 public:
  ObjectTrackerNode(ros::NodeHandle& node, ros::NodeHandle& private_node) : tf_listener_(tf_buffer_) {
    bs::ros_layer::ParameterReader p(private_node, "object_tracker");
    const std::string camera = p.text("camera", "rgbd");
    const std::string depth = p.text("camera_depth", "depth", {"depth", "depth_registered"});
    register_depth_ = p.boolean("register_depth", false);
    world_ = p.text("world_frame", "world");
    bs::tracking::ObjectTrackerConfig config;
    bs::vision::ObjectLocatorConfig& locator = config.locator;
    const std::string object_from = p.text("object_from", "");
    if (!object_from.empty()) {
      // The object a simulation file carries about: what the simulator draws is what is looked for.
      for (const char* key : {"shape", "size", "colour"}) {
        if (p.has(key))
          throw std::invalid_argument("give " + p.name("object_from") + " or " + p.name(key) + ", not both");
      }
      const bs::sim::SimConfig scene = bs::sim::SimConfig::fromYamlFile(object_from);
      if (!scene.has_object) throw std::invalid_argument(p.name("object_from") + ": " + object_from + " has no object");
      locator.shape = bs::tasks::sceneSolid(scene.object.body);
      shape_ = locator.shape.shape == bs::vision::SceneSolid::Shape::Box      ? "box"
               : locator.shape.shape == bs::vision::SceneSolid::Shape::Sphere ? "sphere"
                                                                              : "cylinder";
      locator.hue = bs::vision::hueOf(locator.shape.colour);
    } else {
      for (const char* key : {"shape", "size", "colour"}) {
        if (!p.has(key)) {
          throw std::invalid_argument("parameter " + p.name(key) +
                                      " is not set: give the tracked object's shape (cylinder, sphere or box), size "
                                      "[m] and colour (RGB in [0, 1]), or a simulation file with the object (" +
                                      p.name("object_from") + ")");
        }
      }
      shape_ = p.text("shape", "", {"cylinder", "sphere", "box"});
      locator.shape.shape = shape_ == "box"      ? bs::vision::SceneSolid::Shape::Box
                            : shape_ == "sphere" ? bs::vision::SceneSolid::Shape::Sphere
                                                 : bs::vision::SceneSolid::Shape::Cylinder;
      const std::size_t dimensions = shape_ == "box" ? 3 : shape_ == "cylinder" ? 2 : 1;
      const std::vector<double> size = p.numbers("size", {}, dimensions, 1e-3, 10.0);
      for (std::size_t i = 0; i < dimensions; ++i) locator.shape.size[static_cast<Eigen::Index>(i)] = size[i];
      const std::vector<double> colour = p.numbers("colour", {}, 3, 0.0, 1.0);
      locator.hue = bs::vision::hueOf(Eigen::Vector3d(colour[0], colour[1], colour[2]));
    }
    locator.hue_tolerance = p.number("hue_tolerance", locator.hue_tolerance, 0.1, 90.0);
    locator.min_saturation = p.number("min_saturation", locator.min_saturation, 0.0, 1.0);
    locator.min_value = p.number("min_value", locator.min_value, 0.0, 1.0);
    locator.min_pixels = p.integer("min_pixels", locator.min_pixels, 1, 1000000);
    locator.min_points = p.integer("min_points", locator.min_points, 4, locator.max_points);
    locator.min_stddev = p.number("min_stddev", locator.min_stddev, 1e-5, 1.0);
    locator.outlier_distance = p.number("outlier_distance", locator.outlier_distance, 1e-4, 1.0);
    config.filter.acceleration_noise = p.number("acceleration_noise", config.filter.acceleration_noise, 1e-6, 1e4);
    config.filter.gate = p.number("gate", config.filter.gate, 0.1, 1e6);
    config.filter.lost_after = p.number("lost_after", config.filter.lost_after, 0.01, 60.0);
    config.filter.reject_limit = p.integer("reject_limit", config.filter.reject_limit, 1, 1000);
    config.camera_timeout = p.number("camera_timeout", config.camera_timeout, 0.01, 60.0);
    tf_timeout_ = p.number("tf_timeout", 0.1, 0.0, 10.0);
    p.warnUnknown();
    tracker_ = std::make_unique<bs::tracking::ObjectTracker>(config);

    object_ = private_node.advertise<bimanual_skills::TrackedObject>("object", 10);
    pose_ = private_node.advertise<geometry_msgs::PoseWithCovarianceStamped>("pose", 10);
    markers_ = private_node.advertise<visualization_msgs::MarkerArray>("markers", 1);
    debug_ = private_node.advertise<sensor_msgs::Image>("debug_image", 1);
    diagnostics_ = node.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    info_ = node.subscribe(camera + "/camera_info", 1, &ObjectTrackerNode::onInfo, this);
    depth_info_ = node.subscribe(camera + "/" + depth + "/camera_info", 1, &ObjectTrackerNode::onDepthInfo, this);
    // The newest frame only: a tracker slower than its camera drops frames rather than working through a backlog,
    // each estimate then a queue's length older than the frame it could have had.
    image_.subscribe(node, camera + "/image_raw", 1);
    depth_.subscribe(node, camera + "/" + depth + "/image_raw", 1);
    // Colour and depth of one moment: the same stamp (one camera), or within 20 ms (a Kinect's two).
    sync_ = std::make_unique<Sync>(Policy(10), image_, depth_);
    sync_->setMaxIntervalDuration(ros::Duration(0.02));
    sync_->registerCallback(&ObjectTrackerNode::onFrame, this);
    stop_timer_ = node.createTimer(ros::Duration(0.05), &ObjectTrackerNode::onTimer, this);
    diagnostics_timer_ = node.createSteadyTimer(ros::WallDuration(1.0), &ObjectTrackerNode::onDiagnostics, this);
    hue_ = locator.hue;
    ROS_INFO("object_tracker: a %s of hue %.0f deg on %s/..., tracked in %s", shape_.c_str(), locator.hue,
             camera.c_str(), world_.c_str());
  }

 private:
  void onInfo(const sensor_msgs::CameraInfo::ConstPtr& info) { info_msg_ = info; }
  void onDepthInfo(const sensor_msgs::CameraInfo::ConstPtr& info) { depth_info_msg_ = info; }

  /// The reader for the camera_infos now (made anew when they change); "" or why there is none.
  std::string reader() {
    if (!info_msg_ || !depth_info_msg_) return info_msg_ ? "no depth camera_info yet" : "no camera_info yet";
    if (reader_ && reader_->madeFor(*info_msg_, depth_info_msg_.get())) return "";
    reader_.reset();
    try {
      std::optional<Eigen::Isometry3d> colour_from_depth;
      if (register_depth_ && depth_info_msg_->header.frame_id != info_msg_->header.frame_id) {
        colour_from_depth = tf2::transformToEigen(tf_buffer_.lookupTransform(
            info_msg_->header.frame_id, depth_info_msg_->header.frame_id, ros::Time(0), ros::Duration(tf_timeout_)));
      }
      reader_ =
          std::make_unique<bs::ros_layer::RgbdReader>(*info_msg_, *depth_info_msg_, colour_from_depth, register_depth_);
      ROS_INFO("object_tracker: the camera: %s", reader_->description().c_str());
      return "";
    } catch (const std::exception& e) {
      return std::string("the camera cannot be read: ") + e.what();
    }
  }

  void onFrame(const sensor_msgs::Image::ConstPtr& image, const sensor_msgs::Image::ConstPtr& depth) {
    const ros::WallTime started = ros::WallTime::now();
    arrival_age_.push_back((ros::Time::now() - image->header.stamp).toSec());
    const double t = image->header.stamp.toSec();
    problem_.clear();
    bs::vision::PinholeCamera camera;
    std::optional<bs::vision::PinholeCamera> depth_camera;
    problem_ = reader();
    Eigen::Isometry3d pose;
    pose.matrix().setConstant(std::nan(""));  // a frame without a pose is a frame the tracker cannot use
    if (problem_.empty()) {
      try {
        pose = tf2::transformToEigen(tf_buffer_.lookupTransform(world_, image->header.frame_id, image->header.stamp,
                                                                ros::Duration(tf_timeout_)));
      } catch (const tf2::TransformException& e) {
        problem_ = "no pose of the camera frame '" + image->header.frame_id + "' in '" + world_ + "': " + e.what();
      }
      camera = reader_->camera(pose);
      depth_camera = reader_->depthCamera(pose);
    }
    const ros::WallTime posed = ros::WallTime::now();
    cv::Mat bgr, metres;
    if (problem_.empty()) problem_ = reader_->read(*image, *depth, bgr, metres);
    const ros::WallTime read = ros::WallTime::now();
    const bs::tracking::TrackedState& state =
        tracker_->frame(t, bgr, metres, camera, depth_camera ? &*depth_camera : nullptr);
    publish(state, image->header.stamp);
    stages_[0].push_back((posed - started).toSec());
    stages_[1].push_back((read - posed).toSec());
    stages_[2].push_back((ros::WallTime::now() - read).toSec());
    if (debug_.getNumSubscribers() > 0 && !bgr.empty()) {
      cv_bridge::CvImage out(image->header, "bgr8", bgr.clone());
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(tracker_->locator().objectMask().clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
      cv::drawContours(out.image, contours, -1, state.tracking ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 0, 255), 2);
      debug_.publish(out.toImageMsg());
    }
    processing_.push_back((ros::WallTime::now() - started).toSec());
  }

  /// Frames that stop: the estimate at the clock's time says so once camera_timeout has passed.
  void onTimer(const ros::TimerEvent&) {
    const bs::tracking::TrackedState& last = tracker_->last();
    const double now = ros::Time::now().toSec();
    if (last.frames == 0 || now - last.last_frame <= tracker_->config().camera_timeout) return;
    publish(tracker_->at(now), ros::Time(now));
  }

  void publish(const bs::tracking::TrackedState& state, const ros::Time& stamp) {
    bimanual_skills::TrackedObject out;
    out.header.stamp = stamp;
    out.header.frame_id = world_;
    out.tracking = state.tracking;
    out.state = bs::tracking::ObjectTracker::describe(state);
    if (!state.tracking && !problem_.empty()) out.state += " (" + problem_ + ")";
    out.pose.pose.position.x = state.position.x();
    out.pose.pose.position.y = state.position.y();
    out.pose.pose.position.z = state.position.z();
    out.pose.pose.orientation.w = 1.0;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) out.pose.covariance[static_cast<std::size_t>(6 * i + j)] = state.covariance(i, j);
    }
    for (int i = 3; i < 6; ++i) out.pose.covariance[static_cast<std::size_t>(7 * i)] = -1.0;  // orientation unknown
    out.velocity.x = state.velocity.x();
    out.velocity.y = state.velocity.y();
    out.velocity.z = state.velocity.z();
    out.last_accepted = ros::Time(std::max(0.0, state.last_accepted));
    out.frames = static_cast<std::uint32_t>(state.frames);
    out.measured = static_cast<std::uint32_t>(state.measured);
    out.accepted = static_cast<std::uint32_t>(state.accepted);
    out.rejected = static_cast<std::uint32_t>(state.rejected);
    out.dropped = static_cast<std::uint32_t>(state.dropped);
    object_.publish(out);
    if (state.tracking) {
      geometry_msgs::PoseWithCovarianceStamped pose;
      pose.header = out.header;
      pose.pose = out.pose;
      pose_.publish(pose);
    }
    markers_.publish(markers(state, out.header));
    last_message_ = out.state;
    last_tracking_ = state.tracking;
  }

  visualization_msgs::MarkerArray markers(const bs::tracking::TrackedState& state,
                                          const std_msgs::Header& header) const {
    visualization_msgs::MarkerArray array;
    visualization_msgs::Marker m;
    m.header = header;
    m.header.stamp = ros::Time();  // the latest transform: rviz keeps markers across a simulation's reset
    m.ns = "tracked_object";
    m.pose.orientation.w = 1.0;
    m.color.a = 0.9f;
    m.color.r = state.tracking ? 0.1f : 0.9f;
    m.color.g = state.tracking ? 0.8f : 0.1f;
    m.color.b = 0.1f;
    // The estimate's 3-sigma ellipsoid (principal axes of its covariance).
    m.id = 0;
    m.type = visualization_msgs::Marker::SPHERE;
    m.pose.position.x = state.position.x();
    m.pose.position.y = state.position.y();
    m.pose.position.z = state.position.z();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> axes(state.covariance);
    Eigen::Matrix3d rotation = axes.eigenvectors();
    if (rotation.determinant() < 0.0) rotation.col(2) *= -1.0;
    const Eigen::Quaterniond q(rotation);
    m.pose.orientation.w = q.w(), m.pose.orientation.x = q.x(), m.pose.orientation.y = q.y(),
    m.pose.orientation.z = q.z();
    // Lost: a 5 cm ball where it was last (the covariance then says nothing useful).
    const Eigen::Vector3d extent =
        state.tracking ? Eigen::Vector3d(6.0 * axes.eigenvalues().cwiseMax(0.0).cwiseSqrt().cwiseMax(0.002))
                       : Eigen::Vector3d::Constant(0.05);
    m.scale.x = extent.x(), m.scale.y = extent.y(), m.scale.z = extent.z();
    array.markers.push_back(m);
    // The velocity, 1 s of it.
    m.id = 1;
    m.type = visualization_msgs::Marker::ARROW;
    m.pose = geometry_msgs::Pose();
    m.pose.orientation.w = 1.0;
    m.scale.x = 0.01, m.scale.y = 0.02, m.scale.z = 0.0;
    geometry_msgs::Point from, to;
    from.x = state.position.x(), from.y = state.position.y(), from.z = state.position.z();
    to.x = from.x + state.velocity.x(), to.y = from.y + state.velocity.y(), to.z = from.z + state.velocity.z();
    m.points = {from, to};
    m.action = state.tracking ? visualization_msgs::Marker::ADD : visualization_msgs::Marker::DELETE;
    array.markers.push_back(m);
    // What it says, above it.
    m.id = 2;
    m.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    m.action = visualization_msgs::Marker::ADD;
    m.points.clear();
    m.pose.position = from;
    m.pose.position.z += 0.12;
    m.scale.z = 0.03;
    m.text = state.tracking ? "tracking" : bs::tracking::toString(state.reason);
    array.markers.push_back(m);
    return array;
  }

  void onDiagnostics(const ros::SteadyTimerEvent&) {
    diagnostic_msgs::DiagnosticStatus status;
    status.name = ros::this_node::getName();
    status.hardware_id = "object_tracker";
    std::vector<double> times, arrival;
    times.swap(processing_);
    arrival.swap(arrival_age_);
    std::array<std::vector<double>, 3> stages;
    for (std::size_t k = 0; k < stages.size(); ++k) stages[k].swap(stages_[k]);
    status.level = last_tracking_ ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN;
    status.message = last_message_.empty() ? "no camera frame yet" : last_message_;
    const bs::tracking::TrackedState& s = tracker_->last();
    if (s.frames > 0 && s.measured == 0) {
      // Frames came and the object was never found in one: most likely not the object the parameters describe.
      std::ostringstream never;
      never << "the object (a " << shape_ << " of hue " << std::lround(hue_) << " deg) has never been seen in "
            << s.frames << " frames: check ~shape, ~size and ~colour against it";
      status.message = never.str();
    }
    const auto add = [&status](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      status.values.push_back(kv);
    };
    std::sort(times.begin(), times.end());
    std::ostringstream text;
    text.precision(3);
    text << std::fixed << times.size() << " frames; processing median "
         << (times.empty() ? 0.0 : 1e3 * times[times.size() / 2]) << " ms, max "
         << (times.empty() ? 0.0 : 1e3 * times.back()) << " ms";
    add("last second", text.str());
    // Where a frame's time goes, for a latency budget: its age when it reached this node (transport, the pairing of
    // colour and depth, the queue), then the stages of its processing.
    const auto median = [](std::vector<double>& v) {
      if (v.empty()) return 0.0;
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      return 1e3 * v[v.size() / 2];
    };
    std::ostringstream split;
    split.precision(3);
    split << std::fixed << "age on arrival " << median(arrival) << " ms; the camera's pose (tf) " << median(stages[0])
          << " ms, reading (conversion, undistortion, registration) " << median(stages[1])
          << " ms, locating and filtering " << median(stages[2]) << " ms";
    add("last second, medians", split.str());
    add("frames, measured, accepted, rejected, dropped",
        std::to_string(s.frames) + ", " + std::to_string(s.measured) + ", " + std::to_string(s.accepted) + ", " +
            std::to_string(s.rejected) + ", " + std::to_string(s.dropped));
    add("last frame", bs::vision::toString(s.located));
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    array.status.push_back(status);
    diagnostics_.publish(array);
  }

  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;
  using Policy = message_filters::sync_policies::ApproximateTime<sensor_msgs::Image, sensor_msgs::Image>;
  using Sync = message_filters::Synchronizer<Policy>;
  std::string world_, problem_, shape_;
  double tf_timeout_ = 0.1, hue_ = 0.0;
  bool register_depth_ = false;
  std::unique_ptr<bs::tracking::ObjectTracker> tracker_;
  sensor_msgs::CameraInfo::ConstPtr info_msg_, depth_info_msg_;
  std::unique_ptr<bs::ros_layer::RgbdReader> reader_;
  ros::Publisher object_, pose_, markers_, debug_, diagnostics_;
  ros::Subscriber info_, depth_info_;
  message_filters::Subscriber<sensor_msgs::Image> image_, depth_;
  std::unique_ptr<Sync> sync_;
  ros::Timer stop_timer_;
  ros::SteadyTimer diagnostics_timer_;
  std::vector<double> processing_;   ///< Wall time of each frame since the last diagnostics [s].
  std::vector<double> arrival_age_;  ///< Each frame's age (this node's clock − its stamp) when it arrived [s].
  std::array<std::vector<double>, 3> stages_;  ///< Pose lookup, reading, locating and filtering, per frame [s].
  std::string last_message_;
  bool last_tracking_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "object_tracker");
  ros::NodeHandle node, private_node("~");
  try {
    ObjectTrackerNode tracker(node, private_node);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("object_tracker: %s", e.what());
    return 1;
  }
  return 0;
}
