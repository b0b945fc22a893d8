#include "bimanual_skills/ros_layer/workers/action_workers.hpp"

#include <bimanual_skills/EvaluateRolloutsAction.h>

#include <actionlib/client/simple_action_client.h>
#include <ros/master.h>

#include <atomic>
#include <utility>

namespace bimanual_skills::ros_layer {

namespace {

constexpr const char* kAction = "evaluate_rollouts";
/// A worker whose status is older than this [s] is not alive (actionlib publishes it at 5 Hz).
constexpr double kStatusAge = 1.0;
constexpr double kConnectTimeout = 3.0;  ///< [s] to connect to a worker's action server.

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

class ActionWorkerLink : public rollout::WorkerLink {
 public:
  ActionWorkerLink(ros::NodeHandle& node, std::string name, const WorkerSelection& selection)
      : name_(std::move(name)), selection_(selection), client_(node, name_, false) {}

  bool connected() { return client_.waitForServer(ros::Duration(kConnectTimeout)); }

  const std::string& name() const override { return name_; }

  bool start(const std::vector<rollout::RolloutRequest>& share) override {
    if (!client_.isServerConnected()) return false;
    EvaluateRolloutsGoal goal;
    goal.task = selection_.task;
    goal.config = selection_.config;
    goal.dimension = share.empty() ? 0 : static_cast<std::uint32_t>(share.front().parameters.size());
    for (const rollout::RolloutRequest& r : share) {
      if (static_cast<std::uint32_t>(r.parameters.size()) != goal.dimension) {
        throw std::invalid_argument("dispatch: the rollouts of a batch must have parameter vectors of one size");
      }
      goal.parameters.insert(goal.parameters.end(), r.parameters.data(), r.parameters.data() + r.parameters.size());
      goal.seeds.push_back(r.seed);
    }
    done_ = 0;
    client_.sendGoal(goal, actionlib::SimpleActionClient<EvaluateRolloutsAction>::SimpleDoneCallback(),
                     actionlib::SimpleActionClient<EvaluateRolloutsAction>::SimpleActiveCallback(),
                     [this](const EvaluateRolloutsFeedbackConstPtr& feedback) { done_ = feedback->done; });
    active_ = true;
    return true;
  }

  Status poll() override {
    Status status;
    if (!active_) return status;
    const actionlib::SimpleClientGoalState state = client_.getState();
    switch (state.state_) {
      case actionlib::SimpleClientGoalState::PENDING:
      case actionlib::SimpleClientGoalState::ACTIVE:
        if (!client_.isServerConnected()) return lost("its action server disconnected");
        status.state = State::Running;
        status.done = done_;
        return status;
      case actionlib::SimpleClientGoalState::SUCCEEDED:
        return finished();
      case actionlib::SimpleClientGoalState::ABORTED: {
        active_ = false;
        const EvaluateRolloutsResultConstPtr result = client_.getResult();
        status.state = result && result->refused ? State::Refused : State::Lost;
        status.reason = state.getText().empty() ? "aborted" : state.getText();
        return status;
      }
      case actionlib::SimpleClientGoalState::REJECTED:
        active_ = false;
        status.state = State::Refused;
        status.reason = state.getText().empty() ? "rejected" : state.getText();
        return status;
      default:
        return lost("its goal ended " + state.toString());
    }
  }

  void cancel() override {
    if (active_) client_.cancelGoal();
    active_ = false;
  }

 private:
  Status lost(const std::string& why) {
    active_ = false;
    Status status;
    status.state = State::Lost;
    status.reason = why;
    return status;
  }

  /// The results of a succeeded goal; a malformed answer is a lost worker (its share goes to the others).
  Status finished() {
    active_ = false;
    const EvaluateRolloutsResultConstPtr r = client_.getResult();
    if (!r) return lost("it answered no result");
    const std::size_t n = r->rewards.size(), terms = r->term_names.size();
    if (r->ok.size() != n || r->outcomes.size() != n || r->reasons.size() != n || r->wall_seconds.size() != n ||
        r->terms.size() != n * terms || r->trajectory_rows.size() != n || r->trajectory_cols.size() != n) {
      return lost("it answered a malformed result (arrays of different lengths)");
    }
    std::size_t values = 0;
    for (std::size_t k = 0; k < n; ++k) {
      values += static_cast<std::size_t>(r->trajectory_rows[k]) * r->trajectory_cols[k];
    }
    if (values != r->trajectory.size()) return lost("it answered a malformed result (trajectory sizes)");
    Status status;
    status.state = State::Finished;
    status.done = n;
    std::size_t offset = 0;
    for (std::size_t k = 0; k < n; ++k) {
      rollout::RolloutResult result;
      result.reward = r->rewards[k];
      result.terms = Eigen::Map<const Eigen::VectorXd>(r->terms.data() + k * terms, static_cast<Eigen::Index>(terms));
      result.ok = r->ok[k];
      result.outcome = r->outcomes[k];
      result.reason = r->reasons[k];
      result.wall_seconds = r->wall_seconds[k];
      const Eigen::Index rows = r->trajectory_rows[k], cols = r->trajectory_cols[k];
      result.trajectory = Eigen::Map<const Eigen::MatrixXd>(r->trajectory.data() + offset, rows, cols);
      offset += static_cast<std::size_t>(rows * cols);
      status.results.push_back(std::move(result));
    }
    return status;
  }

  std::string name_;
  WorkerSelection selection_;
  std::atomic<std::size_t> done_{0};  ///< Written by the feedback callback on the directory's spinner thread.
  bool active_ = false;
  /// Last, so that it is destroyed first: its destructor waits for its callbacks, which use the members above.
  actionlib::SimpleActionClient<EvaluateRolloutsAction> client_;
};

}  // namespace

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

std::string workerActionName(const std::string& name) {
  if (endsWith(name, std::string("/") + kAction)) return name;
  return (endsWith(name, "/") ? name : name + "/") + kAction;
}

ActionWorkerDirectory::ActionWorkerDirectory(WorkerSelection selection) : selection_(std::move(selection)) {
  if (selection_.task.empty()) throw std::invalid_argument("dispatch: no task named for the rollout workers");
  node_ = std::make_unique<ros::NodeHandle>();
  node_->setCallbackQueue(&queue_);
  spinner_ = std::make_unique<ros::AsyncSpinner>(1, &queue_);
  spinner_->start();
  for (const std::string& name : selection_.names) watch(workerActionName(name));
}

ActionWorkerDirectory::~ActionWorkerDirectory() {
  spinner_->stop();
}

void ActionWorkerDirectory::watch(const std::string& action) {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (status_.count(action) != 0) return;
  status_[action] = node_->subscribe<actionlib_msgs::GoalStatusArray>(
      action + "/status", 1, [this, action](const actionlib_msgs::GoalStatusArrayConstPtr&) {
        const std::lock_guard<std::mutex> lock(mutex_);
        last_status_[action] = ros::WallTime::now();
      });
}

std::vector<std::string> ActionWorkerDirectory::alive() {
  if (selection_.names.empty()) {
    ros::master::V_TopicInfo topics;
    ros::master::getTopics(topics);
    const std::string space =
        selection_.space.empty() || selection_.space.back() != '/' ? selection_.space + "/" : selection_.space;
    const std::string tail = std::string("/") + kAction + "/status";
    for (const ros::master::TopicInfo& t : topics) {
      if (t.name.rfind(space, 0) == 0 && endsWith(t.name, tail) && t.datatype == "actionlib_msgs/GoalStatusArray") {
        watch(t.name.substr(0, t.name.size() - std::string("/status").size()));
      }
    }
  }
  std::vector<std::string> names;
  const ros::WallTime now = ros::WallTime::now();
  const std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [action, time] : last_status_) {
    if ((now - time).toSec() < kStatusAge) names.push_back(action);
  }
  return names;
}

std::string ActionWorkerDirectory::where() const {
  std::string names;
  for (const std::string& n : selection_.names) names += (names.empty() ? "" : ", ") + workerActionName(n);
  return (selection_.names.empty() ? "under " + selection_.space : "among " + names) +
         " (start them with: roslaunch bimanual_skills rollout_workers.launch workers:=N)";
}

std::unique_ptr<rollout::WorkerLink> ActionWorkerDirectory::connect(const std::string& name) {
  auto link = std::make_unique<ActionWorkerLink>(*node_, name, selection_);
  if (!link->connected()) return nullptr;
  return link;
}

}  // namespace bimanual_skills::ros_layer
