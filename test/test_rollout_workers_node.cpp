// rostest (test/rollout_workers.test): the fault run. fold_learner learns on three rollout workers; once the first
// rollout is on disk and both worker_0 and worker_1 hold shares, this test kills worker_0 (SIGKILL) and stops
// worker_1 (SIGSTOP) for ~stop_seconds (longer than the learner's worker timeout), then continues it. When the
// learner is done, its results must be those of the same learning run on threads here (rollout::FoldLearner): every
// rollout exactly once, with bit-identical rewards and reward terms, and the same learning curve (epochs.csv); its
// summary.json must report both workers lost and their rollouts re-dispatched, and the learner must show the tool
// paths of the workers' rollouts on ~tool_paths.
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"
#include "cli/pinned_numerics.hpp"
#include "rollout_test_support.hpp"

#include <bimanual_skills/RolloutShare.h>
#include <bimanual_skills/RolloutShareState.h>

#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace br = bimanual_skills::rollout;
using bimanual_skills::test::lines;
using bimanual_skills::test::pidOf;

namespace {

/// rollouts.csv rows by key (algorithm, run, epoch, kind, index) with the fields up to the reward terms (the wall
/// time and the order of completion differ between runs).
std::map<std::string, std::string> rolloutsByKey(const std::string& path, std::size_t& rows) {
  std::map<std::string, std::string> out;
  const std::vector<std::string> all = lines(path);
  rows = all.empty() ? 0 : all.size() - 1;
  for (std::size_t n = 1; n < all.size(); ++n) {
    std::vector<std::string> f;
    std::stringstream ss(all[n]);
    for (std::string field; std::getline(ss, field, ',');) f.push_back(field);
    if (f.size() < 21) continue;
    const std::string key = f[0] + "," + f[1] + "," + f[2] + "," + f[3] + "," + f[4];
    std::string value;
    for (std::size_t i = 5; i < 21; ++i) value += f[i] + ",";
    out[key] = value;
  }
  return out;
}

/// worker_2's topics as a client sees them: its states of the clients named, and its share topic.
struct WorkerTwo {
  explicit WorkerTwo(std::vector<std::string> clients) : clients_(std::move(clients)) {
    state_ = node_.subscribe<bimanual_skills::RolloutShareState>(
        "/rollout_workers/worker_2/state", 64, [this](const bimanual_skills::RolloutShareStateConstPtr& m) {
          if (std::find(clients_.begin(), clients_.end(), m->client) == clients_.end()) return;
          const std::lock_guard<std::mutex> lock(mutex_);
          heard_.push_back(*m);
        });
    share_ = node_.advertise<bimanual_skills::RolloutShare>("/rollout_workers/worker_2/share", 4);
    spinner_.start();
  }
  /// Whether both topics connected within 20 s.
  bool connected() {
    const ros::WallTime by = ros::WallTime::now() + ros::WallDuration(20.0);
    while ((share_.getNumSubscribers() == 0 || state_.getNumPublishers() == 0) && ros::WallTime::now() < by) {
      ros::WallDuration(0.01).sleep();
    }
    return share_.getNumSubscribers() > 0;
  }
  void send(const bimanual_skills::RolloutShare& m) { share_.publish(m); }
  /// The first state heard that `match` accepts, waiting up to 60 s; a default state if none.
  template <typename Match>
  bimanual_skills::RolloutShareState first(const Match& match) {
    const ros::WallTime by = ros::WallTime::now() + ros::WallDuration(60.0);
    do {
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        for (const bimanual_skills::RolloutShareState& m : heard_) {
          if (match(m)) return m;
        }
      }
      ros::WallDuration(0.01).sleep();
    } while (ros::WallTime::now() < by);
    return bimanual_skills::RolloutShareState{};
  }

 private:
  std::vector<std::string> clients_;
  ros::NodeHandle node_;
  std::mutex mutex_;
  std::vector<bimanual_skills::RolloutShareState> heard_;
  ros::Subscriber state_;
  ros::Publisher share_;
  ros::AsyncSpinner spinner_{1};
};

}  // namespace

TEST(RolloutWorkers, AFaultRunLearnsExactlyAsTheFaultFreeOne) {
  std::string out, config;
  double stop_seconds = 9.0, timeout = 0.0;
  const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::ok() && ros::WallTime::now() < give_up && !ros::param::get("/fold_learner/out", out)) {
    ros::WallDuration(0.1).sleep();
  }
  ASSERT_FALSE(out.empty());
  ASSERT_TRUE(ros::param::get("~config", config));
  ros::param::get("~stop_seconds", stop_seconds);
  ASSERT_TRUE(ros::param::get("/fold_learner/worker_timeout", timeout));
  ASSERT_GT(stop_seconds, timeout + 1.0) << "the stop must outlast the learner's worker timeout";
  // The learner shows the tool paths of the rollouts the workers ran (their results' trajectory summaries).
  ros::NodeHandle node;
  std::size_t paths_seen = 0;
  const ros::Subscriber paths = node.subscribe<visualization_msgs::MarkerArray>(
      "/fold_learner/tool_paths", 1, [&](const visualization_msgs::MarkerArrayConstPtr& message) {
        std::size_t n = 0;
        for (const visualization_msgs::Marker& m : message->markers) {
          if (m.type == visualization_msgs::Marker::LINE_STRIP && m.points.size() > 10) ++n;
        }
        paths_seen = std::max(paths_seen, n);
      });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int killed = pidOf("/rollout_workers/worker_0"), stopped = pidOf("/rollout_workers/worker_1");
  ASSERT_GT(killed, 0);
  ASSERT_GT(stopped, 0);

  // Each worker's last state message (its 5 Hz heartbeat, or the end of a share) and when it came.
  std::mutex state_mutex;
  std::map<std::string, std::pair<bimanual_skills::RolloutShareState, ros::WallTime>> last_state;
  std::vector<ros::Subscriber> states;
  for (const std::string name : {"worker_0", "worker_1"}) {
    states.push_back(node.subscribe<bimanual_skills::RolloutShareState>(
        "/rollout_workers/" + name + "/state", 16, [&, name](const bimanual_skills::RolloutShareStateConstPtr& m) {
          const std::lock_guard<std::mutex> lock(state_mutex);
          last_state[name] = {*m, ros::WallTime::now()};
        }));
  }
  // Whether the worker's last word says it holds a share with rollouts left, heard within `age` seconds.
  const auto holding = [&](const std::string& name, double age) {
    const std::lock_guard<std::mutex> lock(state_mutex);
    const auto it = last_state.find(name);
    return it != last_state.end() && it->second.first.state == bimanual_skills::RolloutShareState::RUNNING &&
           it->second.first.done < it->second.first.total && (ros::WallTime::now() - it->second.second).toSec() < age;
  };

  // Mid-batch: the first rollout is on disk, the others are running on the three workers.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(120.0);
  while (ros::ok() && ros::WallTime::now() < deadline && lines(out + "/rollouts.csv").size() < 2) {
    ros::WallDuration(0.02).sleep();
  }
  ASSERT_GE(lines(out + "/rollouts.csv").size(), 2u) << "the learner never finished a rollout";
  // Both faults must strike a worker holding a share (an idle one is not missed by the learner). Stop both while
  // their heartbeats say so; if a share's end was already on its way (heard once the messages in flight are in),
  // let them go on and try again.
  bool caught = false;
  while (ros::ok() && ros::WallTime::now() < deadline && !caught) {
    if (!holding("worker_0", 0.25) || !holding("worker_1", 0.25)) {
      ros::WallDuration(0.01).sleep();
      continue;
    }
    ASSERT_EQ(::kill(killed, SIGSTOP), 0);
    ASSERT_EQ(::kill(stopped, SIGSTOP), 0);
    ros::WallDuration(0.3).sleep();
    caught = holding("worker_0", 1.0) && holding("worker_1", 1.0);
    if (!caught) {
      ASSERT_EQ(::kill(killed, SIGCONT), 0);
      ASSERT_EQ(::kill(stopped, SIGCONT), 0);
    }
  }
  ASSERT_TRUE(caught) << "the two workers never held shares at once";
  ASSERT_EQ(::kill(killed, SIGKILL), 0);
  ros::WallDuration(stop_seconds).sleep();
  ASSERT_EQ(::kill(stopped, SIGCONT), 0);

  // summary.json is the learner's last file (after the pictures and the bag).
  while (ros::ok() && ros::WallTime::now() < deadline && !std::filesystem::exists(out + "/summary.json")) {
    ros::WallDuration(0.1).sleep();
  }
  ASSERT_TRUE(std::filesystem::exists(out + "/summary.json")) << "the learner did not finish";
  std::ifstream summary_file(out + "/summary.json");
  const std::string summary((std::istreambuf_iterator<char>(summary_file)), std::istreambuf_iterator<char>());
  const auto number = [&](const std::string& key) {
    const std::size_t at = summary.find("\"" + key + "\"");
    return at == std::string::npos ? -1 : std::stoi(summary.substr(summary.find(':', at) + 1));
  };
  EXPECT_GE(number("workers_lost"), 2) << summary;
  EXPECT_GE(number("redispatched"), 1) << summary;
  EXPECT_GE(paths_seen, 2u) << "no tool paths of the workers' rollouts on /fold_learner/tool_paths";

  // The same learning on threads here.
  const std::string reference = out + "_threads";
  br::FoldLearner(br::FoldLearningConfig::fromYamlFile(config), reference).learn();
  std::size_t rows = 0, reference_rows = 0;
  const std::map<std::string, std::string> got = rolloutsByKey(out + "/rollouts.csv", rows);
  const std::map<std::string, std::string> want = rolloutsByKey(reference + "/rollouts.csv", reference_rows);
  EXPECT_EQ(rows, reference_rows) << "no rollout lost or written twice";
  EXPECT_EQ(got.size(), rows) << "no rollout written twice";
  EXPECT_EQ(got, want);
  EXPECT_EQ(lines(out + "/epochs.csv"), lines(reference + "/epochs.csv"));
}

// A share whose configuration digest is not that of the worker's copy of the file is refused with the reason; the
// same share with the right digest runs. Talks to worker_2 (the fault run above leaves it alive and idle).
TEST(RolloutWorkers, AWorkerRefusesAShareOfAnotherConfigurationFile) {
  const std::string config = ::testing::TempDir() + "digest_quadratic.yaml";
  std::ofstream(config) << "dimension: 2\n";
  const std::string digest = bimanual_skills::ros_layer::configDigest(config);
  ASSERT_EQ(digest.size(), 16u);
  EXPECT_NE(digest, bimanual_skills::ros_layer::configDigest(config + ".missing"));
  EXPECT_EQ(bimanual_skills::ros_layer::configDigest(config + ".missing"), "");

  WorkerTwo worker({"digest_test"});
  ASSERT_TRUE(worker.connected()) << "worker_2 is not there";
  const auto send = [&](std::uint64_t id, const std::string& with) {
    bimanual_skills::RolloutShare m;
    m.client = "digest_test";
    m.id = id;
    m.task = "quadratic";
    m.config = config;
    m.config_digest = with;
    m.dimension = 2;
    m.parameters = {0.5, -0.5, 1.0, 1.0};
    m.seeds = {1, 2};
    worker.send(m);
    return worker.first([id](const bimanual_skills::RolloutShareState& e) {
      return e.id == id && (e.state == bimanual_skills::RolloutShareState::REFUSED ||
                            e.state == bimanual_skills::RolloutShareState::SUCCEEDED);
    });
  };
  const bimanual_skills::RolloutShareState refused = send(1, "0123456789abcdef");
  EXPECT_EQ(refused.state, bimanual_skills::RolloutShareState::REFUSED);
  EXPECT_NE(refused.text.find("digest " + digest), std::string::npos) << refused.text;
  const bimanual_skills::RolloutShareState ran = send(2, digest);
  EXPECT_EQ(ran.state, bimanual_skills::RolloutShareState::SUCCEEDED) << ran.text;
  EXPECT_EQ(ran.rewards.size(), 2u);
}

// A worker running one learner's share answers another learner's share BUSY instead of dropping the first.
TEST(RolloutWorkers, ABusyWorkerAnswersBusyToAnotherClientAndFinishesItsShare) {
  std::string config;
  ros::param::get("~config", config);
  const Eigen::VectorXd fold = br::makeRolloutTask("fold", config)->initialParameters();
  WorkerTwo worker({"busy_a", "busy_b"});
  ASSERT_TRUE(worker.connected()) << "worker_2 is not there";
  const auto heard = [&](const std::string& client, std::uint8_t which) {
    return worker.first(
        [&](const bimanual_skills::RolloutShareState& m) { return m.client == client && m.state == which; });
  };
  bimanual_skills::RolloutShare a;
  a.client = "busy_a";
  a.id = 1;
  a.task = "fold";
  a.config = config;
  a.dimension = static_cast<std::uint32_t>(fold.size());
  for (int k = 0; k < 2; ++k) a.parameters.insert(a.parameters.end(), fold.data(), fold.data() + fold.size());
  a.seeds = {1, 2};
  worker.send(a);
  ASSERT_EQ(heard("busy_a", bimanual_skills::RolloutShareState::RUNNING).id, 1u) << "the fold share did not start";
  bimanual_skills::RolloutShare b;
  b.client = "busy_b";
  b.id = 7;
  b.task = "quadratic";
  b.dimension = 2;
  b.parameters = {0.5, -0.5};
  b.seeds = {1};
  worker.send(b);
  const bimanual_skills::RolloutShareState busy = heard("busy_b", bimanual_skills::RolloutShareState::BUSY);
  EXPECT_EQ(busy.id, 7u) << "no BUSY for the second client";
  EXPECT_EQ(busy.text, "busy_a");
  const bimanual_skills::RolloutShareState end = worker.first([](const bimanual_skills::RolloutShareState& m) {
    return m.client == "busy_a" && m.state != bimanual_skills::RolloutShareState::RUNNING;
  });
  EXPECT_EQ(end.state, bimanual_skills::RolloutShareState::SUCCEEDED) << "the first share was dropped: " << end.text;
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_rollout_workers");
  ros::NodeHandle node;
  return RUN_ALL_TESTS();
}
