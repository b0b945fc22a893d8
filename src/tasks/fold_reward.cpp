#include "bimanual_skills/tasks/fold_reward.hpp"

#include "bimanual_skills/sim/sim_config.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::tasks {

void FoldRewardConfig::validate(const char* where) const {
  renderer.validate(where);
  image.validate(where);
  if (!(acceleration_weight >= 0.0) || !std::isfinite(acceleration_weight)) {
    throw std::invalid_argument(std::string(where) + ": acceleration_weight must be finite and >= 0");
  }
  if (!std::isfinite(failure_reward)) throw std::invalid_argument(std::string(where) + ": failure_reward not finite");
}

FoldRewardConfig rewardSetting(FoldRewardConfig config, const std::string& name, const std::string& where) {
  config.image.colour_weight = config.image.depth_weight = config.image.goal_weight = config.image.fold_weight = 0.0;
  if (name == "fold") {
    config.acceleration_weight = 0.001;
    config.image.fold_weight = 1.0;
  } else if (name == "thesis") {
    config.acceleration_weight = 0.01;
    config.image.colour_weight = config.image.depth_weight = 1.0;
  } else if (name == "goal") {
    config.acceleration_weight = 0.002;
    config.image.goal_weight = 1.0;
  } else {
    throw std::invalid_argument(where + ": unknown reward setting '" + name + "' (fold, thesis, goal)");
  }
  config.setting = name;
  return config;
}

vision::ClothRendererParameters rendererFor(const sim::SimConfig& sim) {
  vision::ClothRendererParameters p;
  const Eigen::Vector3d top = sim.table.topCentre();
  p.table.height = top.z();
  p.table.centre = top.head<2>();
  p.table.size = sim.table.size.head<2>();
  // The floor under the table, or the world's ground (z = 0) in a scene without one.
  p.floor_height = sim.has_table ? top.z() - sim.table.size.z() : 0.0;
  const Eigen::Vector2d centre =
      sim.has_cloth ? Eigen::Vector2d(sim.cloth.pose.translation().head<2>()) : p.table.centre;
  p.camera = vision::TopDownCamera::covering(320, 240, 1.0, centre, top.z() + 1.5);
  p.has_table = sim.has_table;
  for (const sim::Obstacle& obstacle : sim.obstacles) p.solids.push_back(sceneSolid(obstacle));
  return p;
}

vision::SceneSolid sceneSolid(const sim::Obstacle& body) {
  vision::SceneSolid solid;
  solid.shape = body.shape == sim::Obstacle::Shape::Box      ? vision::SceneSolid::Shape::Box
                : body.shape == sim::Obstacle::Shape::Sphere ? vision::SceneSolid::Shape::Sphere
                                                             : vision::SceneSolid::Shape::Cylinder;
  solid.pose = body.pose;
  solid.size = body.size;
  solid.colour = body.colour;
  return solid;
}

vision::PinholeCamera rgbdCameraFor(const sim::SimConfig& sim) {
  const Eigen::Vector3d top = sim.table.topCentre();
  return vision::PinholeCamera::lookingAt(top + Eigen::Vector3d(0.65, 0.0, 1.3), top);
}

FoldReward::FoldReward(const FoldRewardConfig& config, double flat_area, const Eigen::Matrix3Xd& goal_vertices,
                       const Eigen::Matrix3Xi& triangles)
    : config_(config),
      flat_area_(flat_area),
      renderer_((config.validate("fold reward"), config.renderer)),
      flat_renderer_(config.renderer),
      image_(config.renderer.camera, config.image) {
  if (!(flat_area > 0.0) || !std::isfinite(flat_area)) {
    throw std::invalid_argument("fold reward: the flat cloth's area must be > 0");
  }
  const vision::VisionStatus goal = renderer_.render(goal_vertices, triangles);
  if (goal != vision::VisionStatus::Ok || renderer_.clothPixelCount() == 0) {
    throw std::invalid_argument(std::string("fold reward: the camera does not see the goal mesh (") +
                                vision::toString(goal) + ")");
  }
  image_.setGoal(renderer_.clothMask(), renderer_.depth());
}

FoldRewardTerms FoldReward::evaluate(const FoldRollout& rollout, std::mt19937& rng) {
  renderer_.render(rollout.cloth_image_vertices.cols() > 0 ? rollout.cloth_image_vertices : rollout.cloth_vertices,
                   rollout.cloth_triangles, rng);
  // The flat cloth after the reset: the rollout's cloth at rest, drawn after the final images so that those stay
  // what the same seed gave before the fold term existed.
  image_.clearFlat();
  if (rollout.cloth_rest_vertices.cols() > 0 &&
      flat_renderer_.render(rollout.cloth_rest_vertices, rollout.cloth_triangles, rng) == vision::VisionStatus::Ok) {
    try {
      image_.setFlat(flat_renderer_.bgr(), flat_renderer_.depth());
    } catch (const std::invalid_argument&) {
      // No flat cloth in view: the fold term is unknown (ImageReward::evaluate).
    }
  }
  FoldRewardTerms t = evaluateImages(rollout.outcome, rollout.acceleration_cost, renderer_.bgr(), renderer_.depth());
  t.fold_quality = rollout.fold.q;
  t.fold_distance = rollout.fold.distance;
  t.fold_displacement = rollout.fold.displacement;
  return t;
}

void FoldReward::observeFlat(const cv::Mat& bgr, const cv::Mat& depth) {
  image_.clearFlat();
  image_.setFlat(bgr, depth);
}

FoldRewardTerms FoldReward::evaluateImages(FoldOutcome outcome, double acceleration_cost, const cv::Mat& bgr,
                                           const cv::Mat& depth) {
  FoldRewardTerms t;
  t.outcome = outcome;
  const vision::ImageRewardTerms image = image_.evaluate(bgr, depth);
  const vision::FoldFacts facts = image_.foldFacts(image_.mask(), flat_area_);
  t.vision = image.status;
  t.r_color = image.r_color;
  t.r_depth = image.r_depth;
  t.r_goal = image.r_goal;
  t.goal_iou = image.goal.iou;
  t.goal_mismatch = image.goal.mismatch;
  t.r_fold = image.r_fold;
  t.fold_mismatch = image.fold.mismatch;
  t.fold_edge = image.fold.edge;
  t.fold_single = image.fold.single;
  t.fold_length = image.fold.length;
  t.fold_heap = image.fold.heap;
  t.fill_ratio = image.colour.fill_ratio;
  t.mean_gradient = image.depth.mean_gradient;
  t.area_ratio = facts.area_ratio;
  t.aspect = facts.aspect;
  t.r_acceleration = config_.acceleration_weight * acceleration_cost;
  t.reward = outcome == FoldOutcome::Ok ? -t.r_acceleration + image.reward() : config_.failure_reward;
  if (!std::isfinite(t.reward)) t.reward = config_.failure_reward;
  return t;
}

}  // namespace bimanual_skills::tasks
