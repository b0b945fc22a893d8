/// \file
/// What the learner nodes (fold_learner, scarf_learner, bottles_learner) share besides the library: rollout workers
/// chosen by their parameters, the learning section's parameters, summary.json's rows of a DMP learning, and file
/// names made of algorithm names.
#pragma once

#include "bimanual_skills/rollout/dispatcher.hpp"
#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/robot/robot_connection.hpp"
#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"
#include "io/summary_json.hpp"

#include <ros/ros.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::nodes {

/// How a learner's summary.json names what its task scores: `value` "reward" (as learnt) or "cost" (the reward
/// negated: the scarf's), and a success `policy_success` of the noise-free policy and `rollout_successes` counted
/// over an epoch's rollouts.
struct EpochRowNames {
  std::string value = "reward";
  std::string policy_success = "policy_success", rollout_successes = "rollout_successes";
};

/// summary.json's rows of a DMP learning: one per algorithm, run and epoch (its policy's value, success and failure,
/// the rollouts' mean and standard deviation, successes, failures, and each of `terms`' rollout mean).
inline std::vector<io::JsonRow> epochRows(const rollout::DmpLearningResult& result,
                                          const std::vector<std::string>& terms, const EpochRowNames& names) {
  const double sign = names.value == "cost" ? -1.0 : 1.0;
  std::vector<io::JsonRow> rows;
  for (const rollout::DmpRunResult& run : result.runs) {
    for (const rollout::DmpEpochStats& s : run.epochs) {
      io::JsonRow row;
      row.add("algorithm", s.algorithm)
          .add("run", s.run)
          .add("epoch", s.epoch)
          .add("policy_" + names.value, sign * s.policy_reward)
          .add(names.policy_success, s.policy_success)
          .add("policy_failed", s.policy_failed)
          .add("rollout_" + names.value + "_mean", sign * s.mean_reward)
          .add("rollout_" + names.value + "_std", s.std_reward)
          .add(names.rollout_successes, s.successes)
          .add("rollout_failures", s.failures);
      for (std::size_t t = 0; t < terms.size(); ++t) {
        row.add("rollout_mean_" + terms[t], s.term_means[static_cast<Eigen::Index>(t)]);
      }
      rows.push_back(row);
    }
  }
  return rows;
}

/// `text` with every character other than a letter, a digit, '-' or '_' as '_' (an algorithm's name as a file name).
inline std::string fileName(std::string text) {
  for (char& c : text) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  }
  return text;
}

/// ~jobs, ~runs, ~updates, ~rollouts, ~seed (an integer in [0, 2^32)) and ~algorithms over the config file's
/// learning section. \throws std::invalid_argument for a value out of range.
inline void readLearningParameters(ros_layer::ParameterReader& parameters, rollout::DmpLearningConfig& learning) {
  learning.jobs = parameters.integer("jobs", learning.jobs, 0, 256);
  learning.runs = parameters.integer("runs", learning.runs, 1, 1000);
  learning.updates = parameters.integer("updates", learning.updates, 0, 10000);
  learning.rollouts = parameters.integer("rollouts", learning.rollouts, 2, 10000);
  const double seed = parameters.number("seed", learning.seed, 0.0, 4294967295.0);
  if (seed != std::floor(seed)) throw std::invalid_argument("~seed must be an integer in [0, 2^32)");
  learning.seed = static_cast<std::uint32_t>(seed);
  learning.algorithms = parameters.texts("algorithms", learning.algorithms);
}

/// A dispatcher to the rollout workers of ~worker_namespace or ~workers (with ~worker_timeout and ~share), running
/// the registry's `task` configured by `config` (a path valid on the workers' hosts); null when neither is set (the
/// rollouts run on threads here). `where` is told where the workers are; `batch` hears each batch's statistics.
/// \throws std::invalid_argument for bad parameters.
/// The robot's interfaces a learner's ROS backend reads (~reset_service, ~grasp_service, ~pause_service,
/// ~step_service, ~camera, ~camera_depth, ~register_depth, ~cloth_topic, ~world_digest_param, ~robot_timeout,
/// ~reset_timeout), its defaults kept.
inline void readRobotInterfaces(ros_layer::ParameterReader& parameters, ros_layer::RobotInterfaces& robot) {
  robot.reset_service = parameters.text("reset_service", robot.reset_service);
  robot.grasp_service = parameters.text("grasp_service", robot.grasp_service);
  robot.pause_service = parameters.text("pause_service", robot.pause_service);
  robot.step_service = parameters.text("step_service", robot.step_service);
  robot.camera = parameters.text("camera", robot.camera);
  robot.depth = parameters.text("camera_depth", robot.depth, {"depth", "depth_registered"});
  robot.register_depth = parameters.boolean("register_depth", robot.register_depth);
  robot.cloth = parameters.text("cloth_topic", robot.cloth);
  robot.world_digest = parameters.text("world_digest_param", robot.world_digest);
  robot.timeout = parameters.number("robot_timeout", robot.timeout, 0.1, 3600.0);
  robot.reset_timeout = parameters.number("reset_timeout", robot.reset_timeout, 0.1, 86400.0);
}

inline std::unique_ptr<rollout::Evaluator> workerDispatcher(
    ros_layer::ParameterReader& parameters, const ros::NodeHandle& private_node, const std::string& task,
    const std::string& config, std::size_t terms, const std::string& node, std::string& where,
    std::function<void(const rollout::DispatchStats&)> batch = {}) {
  ros_layer::WorkerSelection selection;
  parameters.accept("workers");
  parameters.accept("worker_namespace");
  const double timeout = parameters.number("worker_timeout", rollout::DispatchConfig{}.timeout, 1e-3, 1e6);
  const int share = parameters.integer("share", 0, 0, 1000000);
  if (!ros_layer::readWorkerSelection(private_node, selection)) return nullptr;
  selection.task = task;
  selection.config = std::filesystem::absolute(config).string();
  rollout::DispatchConfig dispatch;
  dispatch.timeout = timeout;
  dispatch.share = static_cast<std::size_t>(share);
  dispatch.log = [node](const std::string& line, bool fault) {
    if (fault) {
      ROS_WARN("%s: %s", node.c_str(), line.c_str());
    } else {
      ROS_INFO("%s: %s", node.c_str(), line.c_str());
    }
  };
  dispatch.batch = std::move(batch);
  where = selection.names.empty() ? selection.space : "~workers";
  return std::make_unique<rollout::Dispatcher>(std::make_unique<ros_layer::TopicWorkerDirectory>(selection), terms,
                                               dispatch);
}

}  // namespace bimanual_skills::nodes
