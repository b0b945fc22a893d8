#include "bimanual_skills/rollout/fold_rollout_task.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace bimanual_skills::rollout {

FoldRolloutTask::FoldRolloutTask(const tasks::ClothFoldConfig& task, const tasks::FoldRewardConfig& reward)
    : task_(task),
      reward_(reward, task_.simConfig().cloth.length * task_.simConfig().cloth.width, task_.idealFoldVertices(),
              task_.clothTriangles()),
      start_renderer_(reward.renderer) {}

std::vector<std::string> FoldRolloutTask::termNames() const {
  return names();
}

std::vector<std::string> FoldRolloutTask::names() {
  return {"r_acceleration", "r_color",     "r_depth",       "fill_ratio",    "mean_gradient",
          "area_ratio",     "aspect",      "fold_quality",  "fold_distance", "fold_displacement",
          "r_goal",         "goal_iou",    "goal_mismatch", "r_fold",        "fold_mismatch",
          "fold_edge",      "fold_single", "fold_length",   "fold_heap"};
}

Eigen::VectorXd FoldRolloutTask::initialParameters() const {
  return encodeCoordinatedPolicy({Eigen::MatrixXd::Identity(tasks::ClothFoldTask::kDofs, tasks::ClothFoldTask::kDofs)},
                                 task_.demonstrationParameters());
}

tasks::FoldRewardTerms FoldRolloutTask::termsOf(const RolloutResult& result) {
  if (static_cast<std::size_t>(result.terms.size()) != kTerms) {
    throw std::invalid_argument("fold rollout: a result with " + std::to_string(result.terms.size()) +
                                " terms instead of " + std::to_string(kTerms));
  }
  tasks::FoldRewardTerms t;
  t.outcome = tasks::foldOutcomeFromString(result.outcome, "fold rollout result");
  t.reward = result.reward;
  t.r_acceleration = result.terms[0];
  t.r_color = result.terms[1];
  t.r_depth = result.terms[2];
  t.fill_ratio = result.terms[3];
  t.mean_gradient = result.terms[4];
  t.area_ratio = result.terms[5];
  t.aspect = result.terms[6];
  t.fold_quality = result.terms[7];
  t.fold_distance = result.terms[8];
  t.fold_displacement = result.terms[9];
  t.r_goal = result.terms[10];
  t.goal_iou = result.terms[11];
  t.goal_mismatch = result.terms[12];
  t.r_fold = result.terms[13];
  t.fold_mismatch = result.terms[14];
  t.fold_edge = result.terms[15];
  t.fold_single = result.terms[16];
  t.fold_length = result.terms[17];
  t.fold_heap = result.terms[18];
  return t;
}

tasks::FoldRewardTerms FoldRolloutTask::score(const tasks::FoldRollout& rollout, std::uint32_t seed) {
  std::seed_seq sequence{seed, 0x5eedu};
  std::mt19937 rng(sequence);
  return reward_.evaluate(rollout, rng);
}

vision::VisionStatus FoldRolloutTask::renderStart(std::uint32_t seed) {
  std::seed_seq sequence{seed, 0x57a27u};
  std::mt19937 rng(sequence);
  return start_renderer_.render(task_.clothStartVertices(seed), task_.clothTriangles(), rng);
}

RolloutResult FoldRolloutTask::run(const Eigen::VectorXd& parameters, std::uint32_t seed) {
  std::vector<Eigen::MatrixXd> coordination;
  Eigen::VectorXd weights;
  if (decodeCoordinatedPolicy(parameters, tasks::ClothFoldTask::kDofs, task_.policyBasisSize(), coordination,
                              weights)) {
    return record(task_.run(coordination, weights, seed), seed);
  }
  tasks::FoldRollout invalid;
  invalid.outcome = tasks::FoldOutcome::InvalidPolicy;
  invalid.reason = "the parameters do not encode a coordinated policy of 12 DoF and " +
                   std::to_string(task_.policyBasisSize()) + " weights per latent DoF";
  return record(std::move(invalid), seed);
}

RolloutResult FoldRolloutTask::record(tasks::FoldRollout rollout, std::uint32_t seed) {
  last_ = std::move(rollout);
  last_terms_ = score(last_, seed);
  return resultOf(last_terms_, last_.reason, last_.actual_path);
}

RolloutResult FoldRolloutTask::resultOf(const tasks::FoldRewardTerms& t, const std::string& reason,
                                        const std::vector<Eigen::Matrix3Xd>& paths) {
  RolloutResult result;
  result.reward = t.reward;
  result.terms.resize(kTerms);
  result.terms << t.r_acceleration, t.r_color, t.r_depth, t.fill_ratio, t.mean_gradient, t.area_ratio, t.aspect,
      t.fold_quality, t.fold_distance, t.fold_displacement, t.r_goal, t.goal_iou, t.goal_mismatch, t.r_fold,
      t.fold_mismatch, t.fold_edge, t.fold_single, t.fold_length, t.fold_heap;
  result.ok = t.outcome == tasks::FoldOutcome::Ok;
  result.outcome = tasks::toString(t.outcome);
  result.reason = reason;
  const bool summarised = !paths.empty() && std::all_of(paths.begin(), paths.end(), [&](const Eigen::Matrix3Xd& p) {
    return p.cols() == paths.front().cols();
  });
  if (summarised) {
    result.trajectory.resize(3 * static_cast<Eigen::Index>(paths.size()), paths.front().cols());
    for (std::size_t arm = 0; arm < paths.size(); ++arm) {
      result.trajectory.middleRows(3 * static_cast<Eigen::Index>(arm), 3) = paths[arm];
    }
  }
  return result;
}

std::vector<Eigen::Matrix3Xd> FoldRolloutTask::toolPaths(const RolloutResult& result) {
  std::vector<Eigen::Matrix3Xd> paths;
  if (result.trajectory.rows() == 0 || result.trajectory.rows() % 3 != 0) return paths;
  for (Eigen::Index row = 0; row < result.trajectory.rows(); row += 3) {
    paths.emplace_back(result.trajectory.middleRows(row, 3));
  }
  return paths;
}

}  // namespace bimanual_skills::rollout
