// The rostests' wait: spins this process' callbacks until `done` holds or `seconds` of wall time pass.
#pragma once

#include <ros/ros.h>

#include <functional>

namespace bimanual_skills::test {

/// Spins (ros::spinOnce every 50 ms) until `done()` or `seconds` of wall time; returns done().
inline bool spinUntil(const std::function<bool()>& done, double seconds) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < deadline && !done()) {
    ros::spinOnce();
    ros::WallDuration(0.05).sleep();
  }
  return done();
}

}  // namespace bimanual_skills::test
