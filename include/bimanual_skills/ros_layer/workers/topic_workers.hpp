/// \file
/// Rollout workers over ROS: rollout::WorkerDirectory and WorkerLink on actionlib. A worker is the action server
/// `evaluate_rollouts` of a rollout_worker node (nodes/rollout_worker.cpp). The directory lists them from a
/// parameter list or, by default, every such server under a namespace registered with the master, and counts one as
/// alive while its action server publishes its status (5 Hz): a killed or stopped worker drops out at once, even
/// though the master still lists its topics. Its callbacks run on a thread of its own, so it works inside a node
/// that never spins.
#pragma once

#include "bimanual_skills/rollout/dispatcher.hpp"

#include <actionlib_msgs/GoalStatusArray.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// Where the dispatcher finds its workers and what it asks of them (the `~workers`, `~worker_namespace`,
/// `~worker_timeout` and `~share` parameters of the nodes that dispatch).
struct WorkerSelection {
  std::vector<std::string> names;  ///< Workers' node or action names; empty: discover under `space`.
  std::string space = "/rollout_workers";
  std::string task;    ///< The task name of the goals.
  std::string config;  ///< Its configuration file, as the workers' hosts see it.
};

/// The worker names of a string that separates them by commas or spaces ("a,b", "[a, b]").
std::vector<std::string> splitWorkerNames(const std::string& text);

/// Reads `~workers` (a list of names, or one string of names separated by commas or spaces, as `_workers:=a,b` on
/// a command line gives it) and `~worker_namespace` of `private_node` into `selection`; false when neither is set
/// (the rollouts then run here). \throws std::invalid_argument for an empty list or a value of another type.
bool readWorkerSelection(const ros::NodeHandle& private_node, WorkerSelection& selection);

/// An action name for a worker given as a node name ("/rollout_workers/worker_0") or already as its action name.
std::string workerActionName(const std::string& name);

class ActionWorkerDirectory : public rollout::WorkerDirectory {
 public:
  explicit ActionWorkerDirectory(WorkerSelection selection);
  ~ActionWorkerDirectory() override;

  std::vector<std::string> alive() override;
  std::unique_ptr<rollout::WorkerLink> connect(const std::string& name) override;
  std::string where() const override;

 private:
  void watch(const std::string& action);

  WorkerSelection selection_;
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::NodeHandle> node_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::mutex mutex_;
  std::map<std::string, ros::Subscriber> status_;
  std::map<std::string, ros::WallTime> last_status_;
};

}  // namespace bimanual_skills::ros_layer
