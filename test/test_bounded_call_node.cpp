// ros_layer::ServiceCaller against servers in this process that answer, hang, fail and come back: an answer is never
// lost, a hung call ends at its deadline and is drained before the next one to its service (which is refused as
// Busy meanwhile), a server that restarts is found again, a missing one is said, and timeouts leak no thread.
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "cli/pinned_numerics.hpp"

#include <gtest/gtest.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

#include <dirent.h>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>

namespace bl = bimanual_skills::ros_layer;

namespace {

/// Threads of this process now.
int threadCount() {
  int n = 0;
  if (DIR* dir = opendir("/proc/self/task")) {
    while (const dirent* entry = readdir(dir)) n += entry->d_name[0] != '.';
    closedir(dir);
  }
  return n;
}

/// A std_srvs/SetBool server on its own queue and threads: answers with its request's value, or holds the call
/// until released, or fails it (returns false).
class Server {
 public:
  Server() {
    node_.setCallbackQueue(&queue_);
    advertise();
    spinner_.start();
  }
  ~Server() {
    release();
    spinner_.stop();
  }
  void advertise() {
    server_ = node_.advertiseService<std_srvs::SetBool::Request, std_srvs::SetBool::Response>(
        "/caller_test/set", [this](std_srvs::SetBool::Request& request, std_srvs::SetBool::Response& response) {
          calls_.fetch_add(1);
          std::unique_lock<std::mutex> lock(mutex_);
          changed_.wait(lock, [this] { return !hang_; });
          if (fail_) return false;
          response.success = request.data;
          response.message = "call " + std::to_string(calls_.load());
          return true;
        });
  }
  void shutdown() { server_.shutdown(); }
  void hang() {
    const std::lock_guard<std::mutex> lock(mutex_);
    hang_ = true;
  }
  void release() {
    const std::lock_guard<std::mutex> lock(mutex_);
    hang_ = false;
    changed_.notify_all();
  }
  void fail(bool on) {
    const std::lock_guard<std::mutex> lock(mutex_);
    fail_ = on;
  }
  std::atomic<int> calls_{0};

 private:
  ros::CallbackQueue queue_;
  ros::NodeHandle node_;
  ros::AsyncSpinner spinner_{2, &queue_};
  ros::ServiceServer server_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool hang_ = false, fail_ = false;
};

/// A first call that the server answers (the persistent connection made), its request true.
std_srvs::SetBool answeredCall(bl::ServiceCaller& caller) {
  std_srvs::SetBool call;
  call.request.data = true;
  EXPECT_EQ(caller.call("/caller_test/set", call, 5.0), bl::CallOutcome::Answered);
  return call;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

TEST(ServiceCaller, AnswersOverOneConnectionAndLosesNone) {
  Server server;
  bl::ServiceCaller caller{ros::NodeHandle()};
  for (int k = 0; k < 500; ++k) {
    std_srvs::SetBool call;
    call.request.data = k % 2 == 0;
    ASSERT_EQ(caller.call("/caller_test/set", call, 5.0), bl::CallOutcome::Answered) << "call " << k;
    EXPECT_EQ(call.response.success, k % 2 == 0);
  }
  EXPECT_EQ(server.calls_.load(), 500);
}

TEST(ServiceCaller, AHungCallEndsAtItsDeadlineIsDrainedAndTheNextOneWaitsForIt) {
  Server server;
  bl::ServiceCaller caller{ros::NodeHandle()};
  std_srvs::SetBool call = answeredCall(caller);
  server.hang();
  call.response = {};
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(caller.call("/caller_test/set", call, 0.5), bl::CallOutcome::TimedOut);
  const double waited = secondsSince(start);
  EXPECT_GE(waited, 0.5);
  EXPECT_LT(waited, 3.0) << "the deadline did not hold";
  EXPECT_FALSE(call.response.success) << "a timed-out call wrote the response";
  // The stale call is still the service's: nothing else is sent until it is answered.
  std_srvs::SetBool next;
  next.request.data = true;
  EXPECT_EQ(caller.call("/caller_test/set", next, 0.5), bl::CallOutcome::Busy);
  std::string busy;
  EXPECT_FALSE(caller.drain(0.2, &busy));
  EXPECT_EQ(busy, "/caller_test/set");
  server.release();
  EXPECT_TRUE(caller.drain(5.0)) << "the released call did not end";
  EXPECT_EQ(server.calls_.load(), 2) << "the Busy call reached the server";
  ASSERT_EQ(caller.call("/caller_test/set", next, 5.0), bl::CallOutcome::Answered);
  EXPECT_TRUE(next.response.success);
  EXPECT_EQ(next.response.message, "call 3");
}

TEST(ServiceCaller, ARestartedServerIsFoundAgainAndAMissingOneIsSaid) {
  Server server;
  bl::ServiceCaller caller{ros::NodeHandle()};
  std_srvs::SetBool call = answeredCall(caller);
  server.shutdown();
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(caller.call("/caller_test/set", call, 0.5), bl::CallOutcome::NoServer);
  EXPECT_LT(secondsSince(start), 3.0);
  server.advertise();
  EXPECT_EQ(caller.call("/caller_test/set", call, 5.0), bl::CallOutcome::Answered)
      << "the persistent connection was not made again";
  std_srvs::Trigger missing;
  EXPECT_EQ(caller.call("/caller_test/none", missing, 0.3), bl::CallOutcome::NoServer);
}

TEST(ServiceCaller, AFailingServerIsSaidOnceRetriedAndNeverRetriedForAStep) {
  Server server;
  bl::ServiceCaller caller{ros::NodeHandle()};
  std_srvs::SetBool call;
  server.fail(true);
  const int before = server.calls_.load();
  EXPECT_EQ(caller.call("/caller_test/set", call, 5.0), bl::CallOutcome::Failed);
  EXPECT_EQ(server.calls_.load() - before, 2) << "a dropped call is sent once more on a new connection";
  EXPECT_EQ(caller.call("/caller_test/set", call, 5.0, bl::Retry::Never), bl::CallOutcome::Failed);
  EXPECT_EQ(server.calls_.load() - before, 3) << "Retry::Never sent it again";
  server.fail(false);
  EXPECT_EQ(caller.call("/caller_test/set", call, 5.0), bl::CallOutcome::Answered);
}

TEST(ServiceCaller, TimeoutsLeakNoThread) {
  Server server;
  const int before = threadCount();
  {
    bl::ServiceCaller caller{ros::NodeHandle()};
    for (int k = 0; k < 20; ++k) {
      server.hang();
      std_srvs::SetBool call;
      EXPECT_EQ(caller.call("/caller_test/set", call, 0.05), bl::CallOutcome::TimedOut);
      // The robot wakes up: its answer ends the call's thread.
      server.release();
      ASSERT_TRUE(caller.drain(5.0));
    }
    EXPECT_LE(threadCount(), before + 1) << "threads left behind by timed-out calls";
  }
  EXPECT_LE(threadCount(), before) << "threads left behind by the caller";
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bounded_call");
  ros::NodeHandle node;
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
