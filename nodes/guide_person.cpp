// guide_person: the person of human-guided learning (thesis Sec. 6.2): moves the simulation's hand (the scene's
// moving object, bullet_sim ~carry_object) that the camera sees and bottles_guidance follows. A thin shell: in
// scripted mode tasks::ScriptedPerson (seeded) says where the hand goes; in marker mode an rviz interactive marker.
#include "bimanual_skills/GuidancePhase.h"
#include "bimanual_skills/TrackedObject.h"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/tasks/human_guidance.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_cli.hpp"

#include <geometry_msgs/PointStamped.h>
#include <interactive_markers/interactive_marker_server.h>
#include <ros/package.h>
#include <ros/ros.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>

namespace bs = bimanual_skills;
namespace bt = bimanual_skills::tasks;

namespace {

const char* kUsage =
    "usage: rosrun bimanual_skills guide_person [_mode:=scripted|marker] [_seed:=S] [_task:=FILE]\n"
    "\n"
    "The person who guides the robot between the bottles (thesis Sec. 6.2): moves the hand the camera sees (the\n"
    "simulation's moving object, through bullet_sim's ~carry_object). The hand rests above the line, below\n"
    "~gesture_height (lowered); raised above it, bottles_guidance has the tool follow the hand's x, y.\n"
    "  scripted  a seeded person (tasks::ScriptedPerson; run K's seed ~seed + K): when the robot's reference reaches\n"
    "            the person's take, the hand goes up and draws the S between the bottles (the first one on the\n"
    "            tool's right), then goes down at the release\n"
    "  marker    an rviz interactive marker (~hand): drag it; above the gesture height it guides\n"
    "\n"
    "Parameters (private):\n"
    "  ~mode            scripted (default) or marker\n"
    "  ~seed            the scripted person's seed of run 0, 0-4294967295 (default 1)\n"
    "  ~task            the bottle task file (default: the package's config/bottles_wam.yaml): the line\n"
    "  ~gesture_height  [m, world z] as bottles_guidance's (default: the line's height + 0.275)\n"
    "  ~lowered, ~raised  the hand's height below and above the gesture's [m] (default 0.075 each)\n"
    "  ~rate            hand positions per second (default 30)\n"
    "  ~guidance        the guidance node (default /bottles_guidance): its ~phase and ~target are watched\n"
    "  ~carry_topic     where the hand goes (default /bullet_sim/carry_object)\n"
    "\n"
    "Topics: publishes ~carry_topic (geometry_msgs/PointStamped, world); subscribes GUIDANCE/phase\n"
    "  (bimanual_skills/GuidancePhase), GUIDANCE/target; marker mode serves the interactive marker ~hand (rviz:\n"
    "  InteractiveMarkers, ~update).\n";

class Person {
 public:
  Person(ros::NodeHandle& node, ros::NodeHandle& private_node) {
    bs::ros_layer::ParameterReader p(private_node, "guide_person");
    mode_ = p.text("mode", "scripted", {"scripted", "marker"});
    seed_ = static_cast<std::uint32_t>(p.number("seed", 1.0, 0.0, 4294967295.0));
    const bt::WamBottleConfig config = bt::WamBottleConfig::fromYamlFile(
        p.text("task", ros::package::getPath("bimanual_skills") + "/config/bottles_wam.yaml"));
    task_ = std::make_unique<bt::WamBottleTask>(config);
    line_speed_ = 1.0 / config.duration;
    const double gesture = p.number("gesture_height", config.start.z() + 0.275, -10.0, 10.0);
    low_ = gesture - p.number("lowered", 0.075, 0.005, 1.0);
    high_ = gesture + p.number("raised", 0.075, 0.005, 1.0);
    const double rate = p.number("rate", 30.0, 1.0, 1000.0);
    const std::string guidance = p.text("guidance", "/bottles_guidance");
    const std::string carry = p.text("carry_topic", "/bullet_sim/carry_object");
    p.warnUnknown();
    hand_ = task_->fromLine(Eigen::Vector2d::Zero());
    hand_.z() = low_;
    carry_ = node.advertise<geometry_msgs::PointStamped>(carry, 10);
    if (mode_ == "scripted") {
      phase_ = node.subscribe(guidance + "/phase", 10, &Person::onPhase, this);
      target_ = node.subscribe(guidance + "/target", 10, &Person::onTarget, this);
    } else {
      server_ = std::make_unique<interactive_markers::InteractiveMarkerServer>(private_node.getNamespace(), "", false);
      addMarker();
    }
    timer_ = node.createTimer(ros::Duration(1.0 / rate), &Person::onTick, this);
    ROS_INFO("guide_person: %s person, the hand lowered at z = %.3f m, raised at %.3f m (gesture %.3f m), on %s",
             mode_.c_str(), low_, high_, gesture, carry.c_str());
  }

 private:
  void onPhase(const bimanual_skills::GuidancePhase& m) {
    const int run = static_cast<int>(m.run);
    const std::string& phase = m.phase;
    // The run's line starts after the arm is back and the scene reset: until then the reference (still where the
    // last run ended, then on a clock that may jump back) says nothing of when to take.
    on_line_ = run == run_ && (phase == "line" || phase == "guided" || phase == "back");
    if (phase == "approach" && run != run_) {
      run_ = run;
      reference_ = Eigen::Vector2d::Zero();
      person_.emplace(bt::PersonConfig{}, task_->lineLength(), seed_ + static_cast<std::uint32_t>(run));
      take_time_ = -1.0;
      ROS_INFO("guide_person: run %d, person %u: takes at %.3f of the line, S of %.3f, %.2f s, lets go at %.3f", run,
               seed_ + static_cast<std::uint32_t>(run), person_->take(), person_->amplitude(), person_->guidedSeconds(),
               person_->release());
    }
  }
  void onTarget(const bimanual_skills::TrackedObject& m) {
    const auto& q = m.pose.pose.position;
    reference_ = task_->toLine(Eigen::Vector3d(q.x, q.y, q.z));
  }

  void onTick(const ros::TimerEvent& event) {
    if (mode_ == "scripted" && person_) {
      const double t = event.current_real.toSec();
      // Raised a fifth of a second before the reference reaches the take, as a person sees it coming.
      if (take_time_ < 0.0 && on_line_ && reference_.x() + 0.2 * line_speed_ >= person_->take()) take_time_ = t;
      const double since = take_time_ < 0.0 ? -1.0 : t - take_time_;
      const Eigen::Vector2d at = since < 0.0 ? Eigen::Vector2d(person_->take(), 0.0) : person_->intended(since);
      hand_ = task_->fromLine(at);
      hand_.z() = since >= 0.0 && since < person_->guidedSeconds() ? high_ : low_;
    }
    geometry_msgs::PointStamped p;
    p.header.stamp = event.current_real;
    p.header.frame_id = "world";
    p.point.x = hand_.x();
    p.point.y = hand_.y();
    p.point.z = hand_.z();
    carry_.publish(p);
  }

  void addMarker() {
    visualization_msgs::InteractiveMarker m;
    m.header.frame_id = "world";
    m.name = "hand";
    m.description = "the hand: raise it to guide";
    m.scale = 0.15f;
    m.pose.position.x = hand_.x();
    m.pose.position.y = hand_.y();
    m.pose.position.z = hand_.z();
    m.pose.orientation.w = 1.0;
    visualization_msgs::InteractiveMarkerControl sphere;
    sphere.always_visible = true;
    sphere.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_3D;
    visualization_msgs::Marker ball;
    ball.type = visualization_msgs::Marker::SPHERE;
    ball.scale.x = ball.scale.y = ball.scale.z = 0.06;
    ball.color.r = 1.0f;
    ball.color.g = 0.5f;
    ball.color.a = 0.9f;
    sphere.markers.push_back(ball);
    m.controls.push_back(sphere);
    const auto axis = [&m](const char* name, double x, double y, double z) {
      visualization_msgs::InteractiveMarkerControl c;
      c.name = name;
      c.orientation.w = 1.0 / std::sqrt(2.0);
      c.orientation.x = x / std::sqrt(2.0);
      c.orientation.y = y / std::sqrt(2.0);
      c.orientation.z = z / std::sqrt(2.0);
      c.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_AXIS;
      m.controls.push_back(c);
    };
    axis("move_x", 1, 0, 0);
    axis("move_y", 0, 0, 1);
    axis("move_z", 0, 1, 0);
    server_->insert(m, [this](const visualization_msgs::InteractiveMarkerFeedbackConstPtr& f) {
      const Eigen::Vector3d p(f->pose.position.x, f->pose.position.y, f->pose.position.z);
      if (p.allFinite()) hand_ = p;
    });
    server_->applyChanges();
  }

  std::string mode_;
  std::uint32_t seed_ = 1;
  std::unique_ptr<bt::WamBottleTask> task_;
  double line_speed_ = 0.25, low_ = 0.0, high_ = 0.0, take_time_ = -1.0;
  int run_ = -1;
  std::optional<bt::ScriptedPerson> person_;
  Eigen::Vector2d reference_ = Eigen::Vector2d::Zero();
  Eigen::Vector3d hand_ = Eigen::Vector3d::Zero();
  ros::Publisher carry_;
  ros::Subscriber phase_, target_;
  bool on_line_ = false;  ///< bottles_guidance's current run is on its line (the person may take).
  std::unique_ptr<interactive_markers::InteractiveMarkerServer> server_;
  ros::Timer timer_;
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "guide_person");
  ros::NodeHandle node, private_node("~");
  try {
    Person person(node, private_node);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("guide_person: %s", e.what());
    return 1;
  }
  return 0;
}
