/// \file
/// rviz markers shared by the nodes: a marker of any frame and a point from Eigen, and the simulated scene's (frame
/// "world"): the table as a box, the cloth as a TRIANGLE_LIST, a tool path as a LINE_STRIP.
#pragma once

#include "bimanual_skills/sim/obstacle.hpp"
#include "bimanual_skills/sim/table.hpp"

#include <ros/time.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace bimanual_skills::nodes {

/// An ADD marker in `frame`: identity pose, unit scale, opaque black.
inline visualization_msgs::Marker marker(const std::string& frame, const std::string& ns, int id, int type,
                                         const ros::Time& stamp) {
  visualization_msgs::Marker m;
  m.header.frame_id = frame;
  m.header.stamp = stamp;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.color.a = 1.0f;
  return m;
}

inline visualization_msgs::Marker worldMarker(const std::string& ns, int id, int type, const ros::Time& stamp) {
  return marker("world", ns, id, type, stamp);
}

inline geometry_msgs::Point toPoint(const Eigen::Vector3d& v) {
  geometry_msgs::Point p;
  p.x = v.x();
  p.y = v.y();
  p.z = v.z();
  return p;
}

/// Sets a marker's pose from a rigid transform.
inline void setPose(visualization_msgs::Marker& m, const Eigen::Isometry3d& pose) {
  const Eigen::Quaterniond r(pose.rotation());
  m.pose.position.x = pose.translation().x();
  m.pose.position.y = pose.translation().y();
  m.pose.position.z = pose.translation().z();
  m.pose.orientation.w = r.w();
  m.pose.orientation.x = r.x();
  m.pose.orientation.y = r.y();
  m.pose.orientation.z = r.z();
}

inline visualization_msgs::Marker tableMarker(const sim::Table& table, const ros::Time& stamp) {
  visualization_msgs::Marker m = worldMarker("table", 0, visualization_msgs::Marker::CUBE, stamp);
  setPose(m, table.pose);
  m.scale.x = table.size.x();
  m.scale.y = table.size.y();
  m.scale.z = table.size.z();
  m.color.r = 0.55f;
  m.color.g = 0.42f;
  m.color.b = 0.3f;
  return m;
}

/// An obstacle of the scene (a mannequin's head, neck, ...) in its shape and colour (namespace "obstacles", id k).
inline visualization_msgs::Marker obstacleMarker(const sim::Obstacle& obstacle, int k, const ros::Time& stamp) {
  const int type = obstacle.shape == sim::Obstacle::Shape::Box      ? visualization_msgs::Marker::CUBE
                   : obstacle.shape == sim::Obstacle::Shape::Sphere ? visualization_msgs::Marker::SPHERE
                                                                    : visualization_msgs::Marker::CYLINDER;
  visualization_msgs::Marker m = worldMarker("obstacles", k, type, stamp);
  setPose(m, obstacle.pose);
  // rviz scales spheres and cylinders by their diameters (and a cylinder's height along its z).
  const Eigen::Vector3d& s = obstacle.size;
  const Eigen::Vector3d scale = obstacle.shape == sim::Obstacle::Shape::Box ? s
                                : obstacle.shape == sim::Obstacle::Shape::Sphere
                                    ? Eigen::Vector3d::Constant(2.0 * s[0])
                                    : Eigen::Vector3d(2.0 * s[0], 2.0 * s[0], s[1]);
  m.scale.x = scale.x();
  m.scale.y = scale.y();
  m.scale.z = scale.z();
  m.color.r = static_cast<float>(obstacle.colour.x());
  m.color.g = static_cast<float>(obstacle.colour.y());
  m.color.b = static_cast<float>(obstacle.colour.z());
  return m;
}

/// The cloth mesh (3 × N vertices, 3 × M triangles, world frame) in the renderer's blue. rviz lights only a
/// triangle's front: each triangle is wound so that its front faces up (world +z), the side a camera over the table
/// sees, whichever way the cloth was folded. An index out of range gives an empty marker.
inline visualization_msgs::Marker clothMarker(const Eigen::Matrix3Xd& vertices, const Eigen::Matrix3Xi& triangles,
                                              const ros::Time& stamp) {
  visualization_msgs::Marker m = worldMarker("cloth", 0, visualization_msgs::Marker::TRIANGLE_LIST, stamp);
  m.color.r = 0.15f;
  m.color.g = 0.35f;
  m.color.b = 0.8f;
  if (triangles.size() > 0 && (triangles.minCoeff() < 0 || triangles.maxCoeff() >= vertices.cols())) return m;
  m.points.reserve(static_cast<std::size_t>(3 * triangles.cols()));
  const auto point = [&](Eigen::Index i) { m.points.push_back(toPoint(vertices.col(i))); };
  for (Eigen::Index t = 0; t < triangles.cols(); ++t) {
    const Eigen::Vector3d a = vertices.col(triangles(0, t)), b = vertices.col(triangles(1, t)),
                          c = vertices.col(triangles(2, t));
    const bool up = (b - a).cross(c - a).z() >= 0.0;
    point(triangles(0, t));
    point(triangles(up ? 1 : 2, t));
    point(triangles(up ? 2 : 1, t));
  }
  return m;
}

/// A path (3 × N points, world frame) as a line of `width` metres.
inline visualization_msgs::Marker pathMarker(const std::string& ns, int id, const Eigen::Matrix3Xd& path, double width,
                                             const ros::Time& stamp) {
  visualization_msgs::Marker m = worldMarker(ns, id, visualization_msgs::Marker::LINE_STRIP, stamp);
  m.scale.x = width;
  m.points.reserve(static_cast<std::size_t>(path.cols()));
  for (Eigen::Index k = 0; k < path.cols(); ++k) m.points.push_back(toPoint(path.col(k)));
  return m;
}

/// Rollouts' paths (reward, 3 × N points) as lines of `width` metres in namespace "tool_paths", coloured by their
/// rewards from red (the worst) to green (the best).
inline visualization_msgs::MarkerArray rankedPathMarkers(const std::vector<std::pair<double, Eigen::Matrix3Xd>>& paths,
                                                         double width, float alpha, const ros::Time& stamp) {
  visualization_msgs::MarkerArray array;
  double best = -std::numeric_limits<double>::infinity(), worst = std::numeric_limits<double>::infinity();
  for (const auto& [reward, path] : paths) {
    best = std::max(best, reward);
    worst = std::min(worst, reward);
  }
  for (std::size_t k = 0; k < paths.size(); ++k) {
    visualization_msgs::Marker m = pathMarker("tool_paths", static_cast<int>(k), paths[k].second, width, stamp);
    const double good = best > worst ? (paths[k].first - worst) / (best - worst) : 1.0;
    m.color.r = static_cast<float>(1.0 - good);
    m.color.g = static_cast<float>(good);
    m.color.a = alpha;
    array.markers.push_back(m);
  }
  return array;
}

}  // namespace bimanual_skills::nodes
