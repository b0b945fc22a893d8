// rollout_worker: evaluates shares of rollout batches for a dispatching learner (rollout::Dispatcher through
// ros_layer/workers/action_workers.hpp), one rollout at a time, with one simulator. A thin shell around the task
// registry.
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "node_cli.hpp"

#include <bimanual_skills/EvaluateRolloutsAction.h>

#include <actionlib/server/simple_action_server.h>
#include <ros/ros.h>

#include <unistd.h>

#include <chrono>
#include <memory>
#include <string>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;

namespace {

/// The shortest time between two feedback messages of a share (and from its start to the first).
constexpr std::chrono::milliseconds kFeedbackPeriod{100};

std::string usage() {
  std::string text =
      "usage: rosrun bimanual_skills rollout_worker [__name:=NAME] [__ns:=NAMESPACE] [_task:=TASK]\n"
      "\n"
      "A rollout worker: serves the action ~evaluate_rollouts (bimanual_skills/EvaluateRollouts). Each goal names a\n"
      "task and its configuration file (read on this host), and carries parameter vectors and seeds; the worker runs\n"
      "them one after another on its one simulator, sends feedback (rollouts done, at most every 0.1 s), and\n"
      "returns the rewards and reward terms. The same parameters and seed give the same result on any worker. A\n"
      "cancelled goal stops after the rollout in progress. Learners dispatch to every worker under a namespace "
      "(default /rollout_workers):\n"
      "  roslaunch bimanual_skills rollout_workers.launch workers:=2\n"
      "\n"
      "Parameters (private):\n"
      "  ~task   accept only goals of this task (default: any)\n"
      "  ~pid    set by the worker: its process id (for tools that stop or kill it)\n"
      "\n"
      "Tasks:\n";
  for (const br::RolloutTaskInfo& t : br::rolloutTasks()) {
    text += "  " + t.name + ": " + t.description + "\n    configuration: " + t.config + "\n";
  }
  return text;
}

using Server = actionlib::SimpleActionServer<bs::EvaluateRolloutsAction>;

class RolloutWorker {
 public:
  RolloutWorker()
      : private_node_("~"),
        server_(
            private_node_, "evaluate_rollouts", [this](const auto& goal) { execute(goal); }, false) {
    bimanual_skills::ros_layer::ParameterReader parameters(private_node_, "rollout_worker");
    only_task_ = parameters.text("task", "");
    parameters.accept("pid");  // written below
    parameters.warnUnknown();
    private_node_.setParam("pid", static_cast<int>(::getpid()));
    server_.start();
    ROS_INFO("rollout_worker %s: ready (%s)", ros::this_node::getName().c_str(),
             only_task_.empty() ? "any task" : ("task " + only_task_).c_str());
  }

 private:
  void refuse(const std::string& why) {
    ROS_ERROR("rollout_worker %s: refused a goal: %s", ros::this_node::getName().c_str(), why.c_str());
    bs::EvaluateRolloutsResult result;
    result.refused = true;
    server_.setAborted(result, why);
  }

  void execute(const bs::EvaluateRolloutsGoalConstPtr& goal) {
    if (!only_task_.empty() && goal->task != only_task_) {
      refuse("this worker runs task '" + only_task_ + "' only, not '" + goal->task + "'");
      return;
    }
    const std::size_t n = goal->seeds.size(), dimension = goal->dimension;
    if (goal->parameters.size() != n * dimension) {
      refuse("malformed goal: " + std::to_string(goal->parameters.size()) + " parameters for " + std::to_string(n) +
             " rollouts of dimension " + std::to_string(dimension));
      return;
    }
    if (!task_ || goal->task != task_name_ || goal->config != task_config_) {
      try {
        task_ = br::makeRolloutTask(goal->task, goal->config);
        task_name_ = goal->task;
        task_config_ = goal->config;
      } catch (const std::invalid_argument& e) {
        task_.reset();
        refuse(e.what());
        return;
      }
    }
    bs::EvaluateRolloutsResult result;
    result.term_names = task_->termNames();
    bs::EvaluateRolloutsFeedback feedback;
    feedback.total = static_cast<std::uint32_t>(n);
    const auto start = std::chrono::steady_clock::now();
    auto last_feedback = start;
    try {
      for (std::size_t k = 0; k < n; ++k) {
        if (server_.isPreemptRequested() || !ros::ok()) {
          ROS_INFO("rollout_worker %s: share cancelled after %zu of %zu rollouts", ros::this_node::getName().c_str(), k,
                   n);
          server_.setPreempted();
          return;
        }
        const Eigen::Map<const Eigen::VectorXd> parameters(goal->parameters.data() + k * dimension,
                                                           static_cast<Eigen::Index>(dimension));
        const auto begin = std::chrono::steady_clock::now();
        const br::RolloutResult r = task_->run(parameters, goal->seeds[k]);
        result.rewards.push_back(r.reward);
        result.terms.insert(result.terms.end(), r.terms.data(), r.terms.data() + r.terms.size());
        result.ok.push_back(r.ok);
        result.outcomes.push_back(r.outcome);
        result.reasons.push_back(r.reason);
        result.wall_seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count());
        result.trajectory_rows.push_back(static_cast<std::uint32_t>(r.trajectory.rows()));
        result.trajectory_cols.push_back(static_cast<std::uint32_t>(r.trajectory.cols()));
        result.trajectory.insert(result.trajectory.end(), r.trajectory.data(),
                                 r.trajectory.data() + r.trajectory.size());
        // Progress at most every kFeedbackPeriod, and none after the last rollout (the result follows at once):
        // a feedback that reaches the learner after its goal's result, when the learner's action client already
        // holds the next goal, is logged there as an error of actionlib's client.
        if (k + 1 < n && std::chrono::steady_clock::now() - last_feedback >= kFeedbackPeriod) {
          feedback.done = static_cast<std::uint32_t>(k + 1);
          server_.publishFeedback(feedback);
          last_feedback = std::chrono::steady_clock::now();
        }
      }
    } catch (const std::exception& e) {
      ROS_ERROR("rollout_worker %s: fault in a rollout: %s", ros::this_node::getName().c_str(), e.what());
      server_.setAborted(result, std::string("fault in a rollout: ") + e.what());
      return;
    }
    ROS_INFO("rollout_worker %s: %zu rollout(s) of %s in %.2f s", ros::this_node::getName().c_str(), n,
             goal->task.c_str(), std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    server_.setSucceeded(result);
  }

  ros::NodeHandle private_node_;
  Server server_;
  std::string only_task_;
  std::unique_ptr<br::RolloutTask> task_;
  std::string task_name_, task_config_;
};

}  // namespace

int main(int argc, char** argv) {
  bs::nodes::handleCommandLine(argc, argv, usage());
  ros::init(argc, argv, "rollout_worker");
  try {
    RolloutWorker worker;
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("rollout_worker: %s", e.what());
    return 1;
  }
  return 0;
}
