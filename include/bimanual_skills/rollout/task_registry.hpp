/// \file
/// The rollout tasks by name, as a rollout worker (nodes/rollout_worker.cpp) builds them from a goal's task name
/// and configuration file. Target bimanual_skills_rollout. Offline: allocates; errors are exceptions.
#pragma once

#include "bimanual_skills/rollout/parallel_evaluator.hpp"

#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

struct RolloutTaskInfo {
  std::string name;
  std::string config;       ///< What its configuration file is.
  std::string description;  ///< One line.
};

/// Every task makeRolloutTask() builds:
/// - "fold": FoldRolloutTask, the cloth fold of a fold learning file (config/fold_demo.yaml).
/// - "scarf": ScarfRolloutTask, the scarf of a scarf learning file (config/scarf_learning.yaml).
/// - "quadratic": reward −‖θ‖²/n + σ ε with ε ~ N(0, 1) drawn from the rollout's seed; no simulation, so a batch
///   of it measures what the dispatch itself costs. Its optional YAML file sets `dimension` (n, default 10) and
///   `noise` (σ, default 0).
/// - "bottles", "circle", "viapoint", "multimodal": the policy-search tasks of Ch. 6 (tasks/policy_search_tasks.hpp),
///   θ the DMP's weights (the 2-D point of reward 6.16 for "multimodal"); deterministic, so the seed is not used.
///   The via-point task's terms are its step costs (what PI2 learns from), then the via-point's error.
/// - "wam_bottles": tasks::WamBottleTask, the bottle task on the simulated WAM (config/bottles_wam.yaml); the
///   rollout's seed is the simulation's sensor noise, the trajectory the measured tool path.
/// - "planar_viapoint": Table 7.3's planar arm with a DR-DMP, exploration drawn from the rollout's seed.
const std::vector<RolloutTaskInfo>& rolloutTasks();

/// A new task `name` configured by the file `config` (read on this host; "" for the defaults where the task has
/// them). \throws std::invalid_argument for an unknown name or a bad configuration, naming them.
std::unique_ptr<RolloutTask> makeRolloutTask(const std::string& name, const std::string& config);

}  // namespace bimanual_skills::rollout
