/// \file
/// Helpers of the rostests that run rollout workers (test/rollout_workers.test, test/ps_benchmark_workers.test).
#pragma once

#include <ros/ros.h>

#include <fstream>
#include <string>
#include <vector>

namespace bimanual_skills::test {

/// The non-empty lines of a text file (none when it does not exist).
inline std::vector<std::string> lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(line);
  }
  return out;
}

/// The process id a rollout_worker node publishes as its `~pid` parameter (waits up to 30 s for it); 0 if none.
inline int pidOf(const std::string& worker) {
  int pid = 0;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  while (ros::ok() && ros::WallTime::now() < deadline && !ros::param::get(worker + "/pid", pid)) {
    ros::WallDuration(0.1).sleep();
  }
  return pid;
}

}  // namespace bimanual_skills::test
