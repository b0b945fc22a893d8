/// \file
/// Rollout workers over ROS: rollout::WorkerDirectory and WorkerLink on two topics per worker. A worker is a
/// rollout_worker node (nodes/rollout_worker.cpp): it takes shares (bimanual_skills/RolloutShare) on <worker>/share
/// and tells what it does (bimanual_skills/RolloutShareState) on <worker>/state, at 5 Hz and when a share ends. Both
/// ends subscribe with TCP_NODELAY, so a small message leaves at once instead of waiting for the acknowledgement of
/// the previous one (Nagle's algorithm; actionlib's client and server cannot ask for it). The directory lists the
/// workers from a parameter list or, by default, every <worker>/state under a namespace registered with the master,
/// and counts one alive while it hears its heartbeat: a killed or stopped worker drops out at once, even though the
/// master still lists its topics. Its callbacks run on a thread of its own, so it works inside a node that never
/// spins.
#pragma once

#include "bimanual_skills/rollout/dispatcher.hpp"

#include <bimanual_skills/RolloutShareState.h>

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
  std::vector<std::string> names;  ///< Workers' node names; empty: discover under `space`.
  std::string space = "/rollout_workers";
  std::string task;    ///< The task name of the shares.
  std::string config;  ///< Its configuration file, as the workers' hosts see it.
};

/// A digest of a file's bytes (64-bit FNV-1a, 16 hex digits); "" for a path that cannot be read or is empty. The
/// dispatcher sends that of its configuration file with every share, and a worker refuses a share whose digest is
/// not that of its own copy.
std::string configDigest(const std::string& path);

/// The worker names of a string that separates them by commas or spaces ("a,b", "[a, b]").
std::vector<std::string> splitWorkerNames(const std::string& text);

/// Reads `~workers` (a list of names, or one string of names separated by commas or spaces, as `_workers:=a,b` on
/// a command line gives it) and `~worker_namespace` of `private_node` into `selection`; false when neither is set
/// (the rollouts then run here). \throws std::invalid_argument for an empty list or a value of another type.
bool readWorkerSelection(const ros::NodeHandle& private_node, WorkerSelection& selection);

class TopicWorkerDirectory : public rollout::WorkerDirectory {
 public:
  explicit TopicWorkerDirectory(WorkerSelection selection);
  ~TopicWorkerDirectory() override;

  std::vector<std::string> alive() override;
  std::unique_ptr<rollout::WorkerLink> connect(const std::string& name) override;
  std::string where() const override;

 private:
  void watch(const std::string& worker);

  WorkerSelection selection_;
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::NodeHandle> node_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::mutex mutex_;
  std::map<std::string, ros::Subscriber> state_;
  std::map<std::string, ros::WallTime> last_state_;
};

}  // namespace bimanual_skills::ros_layer
