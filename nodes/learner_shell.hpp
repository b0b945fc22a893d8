/// \file
/// What the learner nodes (fold_learner, scarf_learner) share besides the library: rollout workers chosen by their
/// parameters, and file names made of algorithm names.
#pragma once

#include "bimanual_skills/rollout/dispatcher.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"

#include <ros/ros.h>

#include <cctype>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

namespace bimanual_skills::nodes {

/// `text` with every character other than a letter, a digit, '-' or '_' as '_' (an algorithm's name as a file name).
inline std::string fileName(std::string text) {
  for (char& c : text) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  }
  return text;
}

/// A dispatcher to the rollout workers of ~worker_namespace or ~workers (with ~worker_timeout and ~share), running
/// the registry's `task` configured by `config` (a path valid on the workers' hosts); null when neither is set (the
/// rollouts run on threads here). `where` is told where the workers are; `batch` hears each batch's statistics.
/// \throws std::invalid_argument for bad parameters.
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
