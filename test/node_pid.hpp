/// \file
/// The process id of a running ROS node, asked the way `rosnode info` asks it: the master's lookupNode gives the
/// node's XML-RPC URI, the node's getPid its process. Tests signal exactly that process, never a `pgrep -f` match.
#pragma once

#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <ros/this_node.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <string>

namespace bimanual_skills::test {

/// The pid of node `name` (e.g. "/bullet_sim"), waiting up to `timeout` wall seconds for it to register; 0 if it
/// does not answer.
inline int nodePid(const std::string& name, double timeout = 30.0) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = ros::this_node::getName();
    request[1] = name;
    std::string host;
    std::uint32_t port = 0;
    if (ros::master::execute("lookupNode", request, response, payload, false) &&
        payload.getType() == XmlRpc::XmlRpcValue::TypeString &&
        ros::network::splitURI(static_cast<std::string>(payload), host, port)) {
      XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
      XmlRpc::XmlRpcValue args, result;
      args[0] = ros::this_node::getName();
      if (client.execute("getPid", args, result) && result.getType() == XmlRpc::XmlRpcValue::TypeArray &&
          result.size() == 3 && static_cast<int>(result[0]) == 1) {
        return static_cast<int>(result[2]);
      }
    }
    ros::WallDuration(0.1).sleep();
  }
  return 0;
}

}  // namespace bimanual_skills::test
