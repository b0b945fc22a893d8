/// \file
/// The fold's scene as the vision tests render it: the table top at 0.15 m centred at x = 0.55 with the reward's
/// top-down map, a Kinect over the table's far side, a perfect depth sensor.
#pragma once

#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

namespace bimanual_skills::test_support {

/// The fold's scene (table top at 0.15 m, centred at x = 0.55) with the top-down map of the reward, noise-free.
inline vision::ClothRendererParameters foldScene() {
  vision::ClothRendererParameters p;
  p.table.height = 0.15;
  p.table.centre = Eigen::Vector2d(0.55, 0.0);
  p.table.size = Eigen::Vector2d(0.7, 1.2);
  p.floor_height = -0.15;
  p.camera = vision::TopDownCamera::covering(320, 240, 1.0, Eigen::Vector2d(0.55, 0.0), 1.65);
  p.noise.depth_stddev = 0.0;
  p.noise.colour_stddev = 0.0;
  return p;
}

/// A Kinect over the table's far side, looking at the cloth 27° off the vertical.
inline vision::PinholeCamera kinectOverTable() {
  return vision::PinholeCamera::lookingAt(Eigen::Vector3d(1.2, 0.0, 1.45), Eigen::Vector3d(0.55, 0.0, 0.15));
}

/// A depth sensor without errors.
inline vision::DepthSensorNoise perfectSensor() {
  vision::DepthSensorNoise n;
  n.axial = n.dropout = n.edge_dropout = n.grazing = n.colour_stddev = 0.0;
  return n;
}

}  // namespace bimanual_skills::test_support
