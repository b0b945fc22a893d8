/// \file
/// ROS service calls with a deadline that lose no answer and leak no thread. ROS 1's ServiceClient::call has no
/// deadline, nor has its existence probe: a server that stops answering (a process stopped with SIGSTOP, a driver
/// stuck in a blocking call) would hold the caller for good. A ServiceCaller runs each call on a thread of its own
/// and waits at most the timeout for its answer. Calls go over persistent connections, one per service, made again
/// when one drops: a non-persistent roscpp call now and then returns false although the server answered (the
/// server's close after its answer can reach the client first, ros/ros_comm#1976), and each one looks the service up
/// at the master again. One call per service is in flight at a time: a call that timed out is waited for (drain())
/// before anything else is asked of that service, so that a robot that wakes up runs its stale request before the
/// next one, never in the middle of it, and at most one thread per service waits on a stuck server. Target
/// bimanual_skills_ros. Not for a real-time loop: starts a thread per call.
#pragma once

#include <ros/node_handle.h>
#include <ros/service.h>
#include <ros/service_client.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace bimanual_skills::ros_layer {

/// Outcome of ServiceCaller::call().
enum class CallOutcome {
  Answered,  ///< The server answered and the call succeeded: the service's response holds its answer.
  NoServer,  ///< No server of that name appeared within the timeout.
  Failed,    ///< The call returned false (a server that failed, or the connection dropped) and was not retried.
  TimedOut,  ///< No answer within the timeout: the call goes on on its own thread, the service is unchanged.
  Busy,      ///< The last call to this service is still unanswered (see drain()): nothing was sent.
};

/// What an outcome means, for messages ("answered", "no server", "the call failed", "no answer in time", ...).
const char* describe(CallOutcome outcome) noexcept;

/// Whether a call whose connection dropped before its answer is sent once more on a new connection (the server may
/// have run it): for requests that do the same when run twice (a reset, a pause, a gripper command), not for a step.
enum class Retry { IfDropped, Never };

class ServiceCaller {
 public:
  explicit ServiceCaller(ros::NodeHandle node) : state_(std::make_shared<State>()) { state_->node = std::move(node); }
  /// Waits up to 1 s for calls in flight; the ones still waiting then end on their own (they hold only shared
  /// state).
  ~ServiceCaller();
  ServiceCaller(const ServiceCaller&) = delete;
  ServiceCaller& operator=(const ServiceCaller&) = delete;

  /// Calls `name` (resolved in the caller's node) with `service` (request in, response out), waiting at most
  /// `timeout` [s of wall time] (> 0) for the server and its answer together; with `progressed` (asked every few
  /// milliseconds: whether the robot moved on since it was last asked), at most `timeout` after the last progress
  /// instead (a long step of a simulator slower than real time). Thread-safe.
  template <class Service>
  CallOutcome call(const std::string& name, Service& service, double timeout, Retry retry = Retry::IfDropped,
                   const std::function<bool()>& progressed = {});
  /// Waits at most `timeout` [s] until no call is in flight; false (with the services still waited for in `busy`)
  /// when some still are. Thread-safe.
  bool drain(double timeout, std::string* busy = nullptr);
  /// The resolved name of `name`.
  std::string resolve(const std::string& name) const { return state_->node.resolveName(name); }

 private:
  /// One service: its persistent client and the call in flight.
  struct Channel {
    ros::ServiceClient client;
    std::thread worker;
    bool in_flight = false;
  };
  /// What the caller and the calls' threads share (a thread still waiting outlives the caller).
  struct State {
    ros::NodeHandle node;
    std::mutex mutex;
    std::condition_variable changed;
    std::map<std::string, Channel> channels;
  };
  /// What the caller and one call's thread share.
  template <class Service>
  struct Shared {
    Service service;
    CallOutcome outcome = CallOutcome::TimedOut;
    bool done = false;
  };
  /// Under the state's mutex: joins the channel's last thread if its call has ended; false while it is in flight.
  static bool settle(Channel& channel);

  std::shared_ptr<State> state_;
};

template <class Service>
CallOutcome ServiceCaller::call(const std::string& name, Service& service, double timeout, Retry retry,
                                const std::function<bool()>& progressed) {
  const std::string resolved = state_->node.resolveName(name);
  const auto limit =
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(timeout));
  const auto deadline = std::chrono::steady_clock::now() + limit;
  auto shared = std::make_shared<Shared<Service>>();
  shared->service = service;
  {
    std::unique_lock<std::mutex> lock(state_->mutex);
    Channel& channel = state_->channels[resolved];
    if (!settle(channel)) return CallOutcome::Busy;
    channel.in_flight = true;
    channel.worker =
        std::thread([state = state_, resolved, client = channel.client, shared, deadline, retry]() mutable {
          CallOutcome outcome = CallOutcome::NoServer;
          for (int attempt = 0; attempt < 2; ++attempt) {
            // A persistent client connects when made (its connect does not wait: a server that answers the probe
            // first); one whose server was not there yet, or whose connection dropped, is made again until the
            // deadline.
            while (!client.isValid() && std::chrono::steady_clock::now() < deadline && ros::ok()) {
              if (ros::service::exists(resolved, false)) client = state->node.serviceClient<Service>(resolved, true);
              if (!client.isValid()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
            if (!client.isValid()) {
              outcome = CallOutcome::NoServer;  // none came back in time (a dropped one: the server went)
              break;
            }
            if (client.call(shared->service)) {
              outcome = CallOutcome::Answered;
              break;
            }
            outcome = CallOutcome::Failed;
            client.shutdown();  // dropped: the next attempt or call makes a new connection
            client = ros::ServiceClient();
            if (retry == Retry::Never) break;
          }
          const std::lock_guard<std::mutex> guard(state->mutex);
          Channel& mine = state->channels[resolved];
          mine.client = client;
          mine.in_flight = false;
          shared->outcome = outcome;
          shared->done = true;
          state->changed.notify_all();
        });
    // The existence wait ends at the deadline too: a moment more for its outcome to come across.
    auto until = deadline + std::chrono::milliseconds(100);
    while (!state_->changed.wait_until(
        lock, progressed ? std::min(until, std::chrono::steady_clock::now() + std::chrono::milliseconds(10)) : until,
        [&] { return shared->done; })) {
      const auto now = std::chrono::steady_clock::now();
      if (progressed && progressed()) until = now + limit;
      if (now >= until) return CallOutcome::TimedOut;
    }
    settle(channel);
  }
  if (shared->outcome == CallOutcome::Answered) service = shared->service;
  return shared->outcome;
}

}  // namespace bimanual_skills::ros_layer
