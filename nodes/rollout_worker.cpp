// rollout_worker: evaluates shares of rollout batches for a dispatching learner (rollout::Dispatcher through
// ros_layer/workers/topic_workers.hpp), one rollout at a time, with one simulator, on a thread of its own beside the
// spinner that takes shares and sends the heartbeat. A thin shell around the task registry.
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_cli.hpp"

#include <bimanual_skills/RolloutShare.h>
#include <bimanual_skills/RolloutShareState.h>

#include <ros/ros.h>

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;

namespace {

std::string usage() {
  std::string text =
      "usage: rosrun bimanual_skills rollout_worker [__name:=NAME] [__ns:=NAMESPACE] [_task:=TASK]\n"
      "\n"
      "A rollout worker: takes shares of rollout batches (bimanual_skills/RolloutShare) on ~share and says what it\n"
      "does (bimanual_skills/RolloutShareState) on ~state, at 5 Hz and when a share ends. A share names a task and\n"
      "its configuration file (read on this host) and carries parameter vectors and seeds; the worker runs them one\n"
      "after another on its one simulator and answers the rewards and reward terms. The same parameters and seed\n"
      "give the same result on any worker. A cancelled share stops after the rollout in progress; a new share\n"
      "replaces the one running. Both topics run with TCP_NODELAY. Learners dispatch to every worker under a\n"
      "namespace (default /rollout_workers):\n"
      "  roslaunch bimanual_skills rollout_workers.launch workers:=2\n"
      "\n"
      "Parameters (private):\n"
      "  ~task   accept only shares of this task (default: any)\n"
      "  ~pid    set by the worker: its process id (for tools that stop or kill it)\n"
      "\n"
      "Tasks:\n";
  for (const br::RolloutTaskInfo& t : br::rolloutTasks()) {
    text += "  " + t.name + ": " + t.description + "\n    configuration: " + t.config + "\n";
  }
  return text;
}

class RolloutWorker {
 public:
  RolloutWorker() : private_node_("~") {
    bimanual_skills::ros_layer::ParameterReader parameters(private_node_, "rollout_worker");
    only_task_ = parameters.text("task", "");
    parameters.accept("pid");  // written below
    parameters.warnUnknown();
    private_node_.setParam("pid", static_cast<int>(::getpid()));
    state_ = private_node_.advertise<bs::RolloutShareState>("state", 16);
    share_ = private_node_.subscribe<bs::RolloutShare>(
        "share", 16, [this](const bs::RolloutShareConstPtr& m) { take(m); }, ros::VoidConstPtr(),
        ros::TransportHints().tcpNoDelay());
    heartbeat_ = private_node_.createWallTimer(ros::WallDuration(0.2), [this](const ros::WallTimerEvent&) { beat(); });
    thread_ = std::thread([this] { work(); });
    ROS_INFO("rollout_worker %s: ready (%s)", ros::this_node::getName().c_str(),
             only_task_.empty() ? "any task" : ("task " + only_task_).c_str());
  }

  ~RolloutWorker() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
      cancel_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }

 private:
  /// On the spinner: a new share (it replaces the one running) or a cancel.
  void take(const bs::RolloutShareConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (m->cancel) {
      if (running_ && m->client == current_.client && m->id == current_.id) cancel_ = true;
      if (pending_ && m->client == pending_->client && m->id == pending_->id) pending_.reset();
      return;
    }
    // Another learner's share while one runs or waits: answered BUSY, never preempting the first learner's.
    const std::string& holder = running_ ? current_.client : pending_ ? pending_->client : m->client;
    if (holder != m->client) {
      bs::RolloutShareState busy;
      busy.state = bs::RolloutShareState::BUSY;
      busy.client = m->client;
      busy.id = m->id;
      busy.text = holder;
      state_.publish(busy);
      ROS_WARN_THROTTLE(5.0, "rollout_worker %s: busy with a share of %s: one of %s answered BUSY",
                        ros::this_node::getName().c_str(), holder.c_str(), m->client.c_str());
      return;
    }
    if (running_) cancel_ = true;
    if (pending_) {  // never started: its sender hears that it was replaced
      bs::RolloutShareState replaced;
      replaced.state = bs::RolloutShareState::CANCELLED;
      replaced.client = pending_->client;
      replaced.id = pending_->id;
      replaced.text = "replaced by a newer share before it started";
      state_.publish(replaced);
    }
    pending_ = m;
    wake_.notify_all();
  }

  /// On the spinner, at 5 Hz: the heartbeat, with the progress of the share running.
  void beat() {
    bs::RolloutShareState state;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (running_) {
        state.state = bs::RolloutShareState::RUNNING;
        state.client = current_.client;
        state.id = current_.id;
        state.done = static_cast<std::uint32_t>(done_);
        state.total = current_.total;
      }
    }
    state_.publish(state);
  }

  /// The worker's thread: one share after another.
  void work() {
    for (;;) {
      bs::RolloutShareConstPtr share;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stopping_ || pending_; });
        if (stopping_) return;
        share = std::move(pending_);
        pending_.reset();
        running_ = true;
        cancel_ = false;
        done_ = 0;
        current_ = {share->client, share->id, static_cast<std::uint32_t>(share->seeds.size())};
      }
      bs::RolloutShareState end = run(*share);
      end.client = share->client;
      end.id = share->id;
      end.total = static_cast<std::uint32_t>(share->seeds.size());
      state_.publish(end);  // before the heartbeat can say IDLE
      const std::lock_guard<std::mutex> lock(mutex_);
      running_ = false;
    }
  }

  bs::RolloutShareState refuse(const std::string& why) {
    ROS_ERROR("rollout_worker %s: refused a share: %s", ros::this_node::getName().c_str(), why.c_str());
    bs::RolloutShareState state;
    state.state = bs::RolloutShareState::REFUSED;
    state.text = why;
    return state;
  }

  bool cancelled() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return cancel_;
  }

  bs::RolloutShareState run(const bs::RolloutShare& share) {
    if (!only_task_.empty() && share.task != only_task_) {
      return refuse("this worker runs task '" + only_task_ + "' only, not '" + share.task + "'");
    }
    const std::size_t n = share.seeds.size(), dimension = share.dimension;
    if (share.parameters.size() != n * dimension) {
      return refuse("malformed share: " + std::to_string(share.parameters.size()) + " parameters for " +
                    std::to_string(n) + " rollouts of dimension " + std::to_string(dimension));
    }
    // The learner's configuration file and this host's copy must be the same bytes: another reward, say, would give
    // results the learner cannot tell from its own.
    const std::string digest = bs::ros_layer::configDigest(share.config);
    if (!share.config_digest.empty() && digest != share.config_digest) {
      return refuse("the configuration file " + share.config + " on this host " +
                    (digest.empty() ? std::string("cannot be read") : "has digest " + digest) +
                    ", the dispatcher's copy " + share.config_digest + ": give both the same file");
    }
    if (!task_ || share.task != task_name_ || share.config != task_config_ || digest != task_digest_) {
      try {
        task_ = br::makeRolloutTask(share.task, share.config);
        task_name_ = share.task;
        task_config_ = share.config;
        task_digest_ = digest;
      } catch (const std::exception& e) {
        task_.reset();
        return refuse(e.what());
      }
    }
    bs::RolloutShareState result;
    result.state = bs::RolloutShareState::SUCCEEDED;
    result.term_names = task_->termNames();
    const auto start = std::chrono::steady_clock::now();
    try {
      for (std::size_t k = 0; k < n; ++k) {
        if (cancelled() || !ros::ok()) {
          ROS_INFO("rollout_worker %s: share cancelled after %zu of %zu rollouts", ros::this_node::getName().c_str(), k,
                   n);
          bs::RolloutShareState state;
          state.state = bs::RolloutShareState::CANCELLED;
          state.done = static_cast<std::uint32_t>(k);
          return state;
        }
        const Eigen::Map<const Eigen::VectorXd> parameters(share.parameters.data() + k * dimension,
                                                           static_cast<Eigen::Index>(dimension));
        const auto begin = std::chrono::steady_clock::now();
        const br::RolloutResult r = task_->run(parameters, share.seeds[k]);
        result.rewards.push_back(r.reward);
        result.terms.insert(result.terms.end(), r.terms.data(), r.terms.data() + r.terms.size());
        result.ok.push_back(r.ok);
        result.outcomes.push_back(r.outcome);
        result.reasons.push_back(r.reason);
        result.wall_seconds.push_back(bs::realtime::secondsSince(begin));
        result.trajectory_rows.push_back(static_cast<std::uint32_t>(r.trajectory.rows()));
        result.trajectory_cols.push_back(static_cast<std::uint32_t>(r.trajectory.cols()));
        result.trajectory.insert(result.trajectory.end(), r.trajectory.data(),
                                 r.trajectory.data() + r.trajectory.size());
        const std::lock_guard<std::mutex> lock(mutex_);
        done_ = k + 1;
      }
    } catch (const std::exception& e) {
      ROS_ERROR("rollout_worker %s: fault in a rollout: %s", ros::this_node::getName().c_str(), e.what());
      bs::RolloutShareState state;
      state.state = bs::RolloutShareState::FAILED;
      state.text = std::string("fault in a rollout: ") + e.what();
      return state;
    }
    result.done = static_cast<std::uint32_t>(n);
    ROS_DEBUG("rollout_worker %s: %zu rollout(s) of %s in %.3f s", ros::this_node::getName().c_str(), n,
              share.task.c_str(), bs::realtime::secondsSince(start));
    return result;
  }

  struct Current {
    std::string client;
    std::uint64_t id = 0;
    std::uint32_t total = 0;
  };

  ros::NodeHandle private_node_;
  std::string only_task_;
  std::unique_ptr<br::RolloutTask> task_;  ///< On the worker's thread only.
  std::string task_name_, task_config_, task_digest_;
  ros::Publisher state_;
  std::mutex mutex_;  ///< Guards the members below, shared by the spinner and the worker's thread.
  std::condition_variable wake_;
  bs::RolloutShareConstPtr pending_;
  Current current_;
  bool running_ = false, cancel_ = false, stopping_ = false;
  std::size_t done_ = 0;
  std::thread thread_;
  ros::Subscriber share_;
  ros::WallTimer heartbeat_;
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
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
