/// \file
/// The demo nodes' joint-state publishing: a configuration published, restamped, at a rate until tf shows what
/// robot_state_publisher made of it, and on until shutdown when asked to hold.
#pragma once

#include <ros/ros.h>
#include <sensor_msgs/JointState.h>

#include <functional>

namespace bimanual_skills::nodes {

/// Publishes `message` (restamped with ros::Time::now()) at `rate` until `done()` or `timeout` seconds of ROS time;
/// true if done() held.
inline bool publishUntil(ros::Publisher& publisher, sensor_msgs::JointState& message, ros::Rate& rate, double timeout,
                         const std::function<bool()>& done) {
  const ros::Time deadline = ros::Time::now() + ros::Duration(timeout);
  while (ros::ok() && ros::Time::now() < deadline) {
    message.header.stamp = ros::Time::now();
    publisher.publish(message);
    if (done()) return true;
    rate.sleep();
  }
  return false;
}

/// Keeps publishing `message` (restamped) at `rate` until shutdown.
inline void publishUntilShutdown(ros::Publisher& publisher, sensor_msgs::JointState& message, ros::Rate& rate) {
  publishUntil(publisher, message, rate, 1e9, [] { return false; });
}

}  // namespace bimanual_skills::nodes
