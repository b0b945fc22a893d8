#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"

#include "io/digest.hpp"

#include <bimanual_skills/RolloutShare.h>

#include <ros/master.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <utility>

namespace bimanual_skills::ros_layer {

namespace {

/// A worker not heard for this long [s] is not alive (it publishes its state at 5 Hz).
constexpr double kStateAge = 1.0;
/// A worker holding a share and not heard for this long [s] is lost (stopped, hung, or its host gone), long before
/// the dispatcher's timeout for a rollout.
constexpr double kSilence = 3.0;
constexpr double kConnectTimeout = 3.0;  ///< [s] to connect to a worker's topics.

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

bool terminal(std::uint8_t state) {
  return state == RolloutShareState::SUCCEEDED || state == RolloutShareState::REFUSED ||
         state == RolloutShareState::FAILED || state == RolloutShareState::CANCELLED ||
         state == RolloutShareState::BUSY;
}

class TopicWorkerLink : public rollout::WorkerLink {
 public:
  TopicWorkerLink(ros::NodeHandle& node, std::string name, const WorkerSelection& selection)
      : name_(std::move(name)),
        selection_(selection),
        digest_(configDigest(selection.config)),
        client_(ros::this_node::getName()),
        // Numbers start at the clock so that a restarted learner never reuses the number of a share still running.
        next_id_(ros::WallTime::now().toNSec()) {
    share_ = node.advertise<RolloutShare>(name_ + "/share", 4);
    state_ = node.subscribe<RolloutShareState>(
        name_ + "/state", 16, [this](const RolloutShareStateConstPtr& m) { heard(m); }, ros::VoidConstPtr(),
        ros::TransportHints().tcpNoDelay());
  }

  /// Whether the worker takes shares: it subscribes to this link's shares and has been heard, within a timeout.
  bool connected() {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(kConnectTimeout);
    while (ros::WallTime::now() < deadline && ros::ok()) {
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (heard_ && share_.getNumSubscribers() > 0) return true;
      }
      ros::WallDuration(0.005).sleep();
    }
    return false;
  }

  const std::string& name() const override { return name_; }

  bool start(const std::vector<rollout::RolloutRequest>& share) override {
    if (share_.getNumSubscribers() == 0) return false;
    RolloutShare message;
    message.client = client_;
    message.id = ++next_id_;
    message.task = selection_.task;
    message.config = selection_.config;
    message.config_digest = digest_;
    message.dimension = share.empty() ? 0 : static_cast<std::uint32_t>(share.front().parameters.size());
    for (const rollout::RolloutRequest& r : share) {
      if (static_cast<std::uint32_t>(r.parameters.size()) != message.dimension) {
        throw std::invalid_argument("dispatch: the rollouts of a batch must have parameter vectors of one size");
      }
      message.parameters.insert(message.parameters.end(), r.parameters.data(),
                                r.parameters.data() + r.parameters.size());
      message.seeds.push_back(r.seed);
    }
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      active_ = message.id;
      done_ = 0;
      end_.reset();
      taken_ = false;
      dropped_.clear();
      last_heard_ = sent_ = ros::WallTime::now();
    }
    share_.publish(message);
    return true;
  }

  Status poll() override {
    RolloutShareStateConstPtr end;
    Status status;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (active_ == 0) return status;
      end = end_;
      status.done = done_;
    }
    if (!end) {
      if (share_.getNumSubscribers() == 0) return lost("it disconnected");
      if ((ros::WallTime::now() - lastHeard()).toSec() > kSilence) {
        return lost("not heard for " + std::to_string(static_cast<int>(kSilence)) + " s");
      }
      std::string dropped;
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        dropped = dropped_;
        // Heard, but never with this share, for as long as a silent worker gets: it did not take it.
        if (dropped.empty() && !taken_ && (ros::WallTime::now() - sent_).toSec() > kSilence) {
          dropped = "it never took the share (heard idle or busy with another for " +
                    std::to_string(static_cast<int>(kSilence)) + " s)";
        }
      }
      if (!dropped.empty()) return lost(dropped);
      status.state = State::Running;
      return status;
    }
    forget();
    switch (end->state) {
      case RolloutShareState::SUCCEEDED:
        return finished(*end);
      case RolloutShareState::REFUSED:
        status.state = State::Refused;
        status.reason = end->text.empty() ? "refused" : end->text;
        return status;
      case RolloutShareState::FAILED:
        return lost(end->text.empty() ? "it failed" : end->text);
      case RolloutShareState::BUSY:
        return lost("it is busy with a share of " + (end->text.empty() ? std::string("another client") : end->text));
      default:
        return lost("its share was cancelled" + (end->text.empty() ? std::string() : ": " + end->text));
    }
  }

  void cancel() override {
    std::uint64_t id = 0;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      id = active_;
    }
    if (id == 0) return;
    RolloutShare message;
    message.client = client_;
    message.id = id;
    message.cancel = true;
    share_.publish(message);
    forget();
  }

 private:
  /// On the directory's spinner thread: keeps the progress and the end of the active share.
  void heard(const RolloutShareStateConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    heard_ = true;
    last_heard_ = ros::WallTime::now();
    if (active_ == 0 || end_) return;
    const bool ours = m->id == active_ && m->client == client_;
    if (!ours) {
      if (m->state == RolloutShareState::RUNNING && m->client == client_) {
        if (!taken_) sent_ = last_heard_;  // still finishing an earlier share of ours (cancelled): it waits
        return;
      }
      // Once it ran this share, a heartbeat without it means the worker dropped it (restarted, or taken over).
      if (taken_ && dropped_.empty() && m->state == RolloutShareState::IDLE) {
        dropped_ = "it went idle holding the share (restarted?)";
      } else if (taken_ && dropped_.empty() && m->state == RolloutShareState::RUNNING) {
        dropped_ = "it runs a share of " + m->client + " instead of this one";
      }
      return;
    }
    taken_ = true;
    done_ = m->done;
    if (terminal(m->state)) end_ = m;
  }

  ros::WallTime lastHeard() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return last_heard_;
  }

  void forget() {
    const std::lock_guard<std::mutex> lock(mutex_);
    active_ = 0;
    end_.reset();
  }

  /// A lost worker: its share is cancelled there (a worker still alive stops running what others now run).
  Status lost(const std::string& why) {
    cancel();
    Status status;
    status.state = State::Lost;
    status.reason = why;
    return status;
  }

  /// The results of a succeeded share; a malformed answer is a lost worker (its share goes to the others).
  static Status finished(const RolloutShareState& r) {
    Status status;
    const std::size_t n = r.rewards.size(), terms = r.term_names.size();
    if (r.ok.size() != n || r.outcomes.size() != n || r.reasons.size() != n || r.wall_seconds.size() != n ||
        r.terms.size() != n * terms || r.trajectory_rows.size() != n || r.trajectory_cols.size() != n) {
      status.state = State::Lost;
      status.reason = "it answered a malformed result (arrays of different lengths)";
      return status;
    }
    std::size_t values = 0;
    for (std::size_t k = 0; k < n; ++k) values += static_cast<std::size_t>(r.trajectory_rows[k]) * r.trajectory_cols[k];
    if (values != r.trajectory.size()) {
      status.state = State::Lost;
      status.reason = "it answered a malformed result (trajectory sizes)";
      return status;
    }
    status.state = State::Finished;
    status.done = n;
    std::size_t offset = 0;
    for (std::size_t k = 0; k < n; ++k) {
      rollout::RolloutResult result;
      result.reward = r.rewards[k];
      result.terms = Eigen::Map<const Eigen::VectorXd>(r.terms.data() + k * terms, static_cast<Eigen::Index>(terms));
      result.ok = r.ok[k];
      result.outcome = r.outcomes[k];
      result.reason = r.reasons[k];
      result.wall_seconds = r.wall_seconds[k];
      const Eigen::Index rows = r.trajectory_rows[k], cols = r.trajectory_cols[k];
      result.trajectory = Eigen::Map<const Eigen::MatrixXd>(r.trajectory.data() + offset, rows, cols);
      offset += static_cast<std::size_t>(rows * cols);
      status.results.push_back(std::move(result));
    }
    return status;
  }

  std::string name_;
  WorkerSelection selection_;
  std::string digest_;  ///< configDigest() of the configuration file, as this host reads it.
  std::string client_;
  std::uint64_t next_id_;
  std::mutex mutex_;  ///< Guards what heard() writes on the spinner thread.
  bool heard_ = false;
  ros::WallTime last_heard_;  ///< When the worker was last heard (set by start() too).
  std::uint64_t active_ = 0;  ///< The share running, 0 for none.
  std::size_t done_ = 0;
  RolloutShareStateConstPtr end_;  ///< Its final state, once heard.
  bool taken_ = false;             ///< The worker was heard with the share (running it, or its end).
  std::string dropped_;            ///< Why the worker, once it had the share, no longer has it ("": it has).
  ros::WallTime sent_;             ///< When the share was sent.
  ros::Publisher share_;
  /// Last, so that it is shut down first: its callback uses the members above.
  ros::Subscriber state_;
};

}  // namespace

std::string configDigest(const std::string& path) {
  return io::fileDigest({path});
}

std::vector<std::string> splitWorkerNames(const std::string& text) {
  std::vector<std::string> names;
  std::string name;
  for (const char c : text + ",") {
    if (c == ',' || c == ' ' || c == '[' || c == ']') {
      if (!name.empty()) names.push_back(name);
      name.clear();
    } else {
      name += c;
    }
  }
  return names;
}

bool readWorkerSelection(const ros::NodeHandle& private_node, WorkerSelection& selection) {
  bool by_list = false;
  if (private_node.hasParam("workers")) {
    by_list = true;
    std::string text;
    if (private_node.getParam("workers", text)) {
      selection.names = splitWorkerNames(text);
    } else if (!private_node.getParam("workers", selection.names)) {
      throw std::invalid_argument("~workers must be a list of worker names or a string of them");
    }
    if (selection.names.empty()) throw std::invalid_argument("~workers names no worker");
  }
  const bool by_space = private_node.getParam("worker_namespace", selection.space);
  return by_list || by_space;
}

TopicWorkerDirectory::TopicWorkerDirectory(WorkerSelection selection) : selection_(std::move(selection)) {
  if (selection_.task.empty()) throw std::invalid_argument("dispatch: no task named for the rollout workers");
  node_ = std::make_unique<ros::NodeHandle>();
  node_->setCallbackQueue(&queue_);
  spinner_ = std::make_unique<ros::AsyncSpinner>(1, &queue_);
  spinner_->start();
  for (const std::string& name : selection_.names) watch(name);
}

TopicWorkerDirectory::~TopicWorkerDirectory() {
  spinner_->stop();
}

void TopicWorkerDirectory::watch(const std::string& worker) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (state_.count(worker) != 0) return;
  }
  // Subscribing talks to the master: not under the lock the spinner's callbacks take.
  ros::Subscriber subscriber = node_->subscribe<RolloutShareState>(
      worker + "/state", 16,
      [this, worker](const RolloutShareStateConstPtr&) {
        const std::lock_guard<std::mutex> lock(mutex_);
        last_state_[worker] = ros::WallTime::now();
      },
      ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  const std::lock_guard<std::mutex> lock(mutex_);
  state_.emplace(worker, std::move(subscriber));
}

std::vector<std::string> TopicWorkerDirectory::alive() {
  if (selection_.names.empty()) {
    ros::master::V_TopicInfo topics;
    ros::master::getTopics(topics);
    const std::string space =
        selection_.space.empty() || selection_.space.back() != '/' ? selection_.space + "/" : selection_.space;
    const std::string tail = "/state";
    for (const ros::master::TopicInfo& t : topics) {
      if (t.name.rfind(space, 0) == 0 && endsWith(t.name, tail) &&
          t.datatype == ros::message_traits::datatype<RolloutShareState>()) {
        watch(t.name.substr(0, t.name.size() - tail.size()));
      }
    }
  }
  std::vector<std::string> names;
  const ros::WallTime now = ros::WallTime::now();
  const std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [worker, time] : last_state_) {
    if ((now - time).toSec() < kStateAge) names.push_back(worker);
  }
  return names;
}

std::string TopicWorkerDirectory::where() const {
  std::string names;
  for (const std::string& n : selection_.names) names += (names.empty() ? "" : ", ") + n;
  return (selection_.names.empty() ? "under " + selection_.space : "among " + names) +
         " (start them with: roslaunch bimanual_skills rollout_workers.launch workers:=N)";
}

std::unique_ptr<rollout::WorkerLink> TopicWorkerDirectory::connect(const std::string& name) {
  auto link = std::make_unique<TopicWorkerLink>(*node_, name, selection_);
  if (!link->connected()) return nullptr;
  return link;
}

}  // namespace bimanual_skills::ros_layer
