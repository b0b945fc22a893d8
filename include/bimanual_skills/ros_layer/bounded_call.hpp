/// \file
/// A ROS service call with a deadline. ROS 1's ServiceClient::call has none, nor has its existence probe: a server
/// that stops answering (a process stopped with SIGSTOP, a driver stuck in a blocking call) would hold the caller for
/// good. The wait for the server and the call run on a thread of their own and the caller waits at most the timeout
/// for their answer; a call still running then is left to end on its thread (it holds only copies), and the caller
/// goes on with a failure it can report. Target bimanual_skills_ros. Not for a real-time loop: starts a thread per
/// call.
#pragma once

#include <ros/service_client.h>

#include <chrono>
#include <future>
#include <memory>
#include <thread>

namespace bimanual_skills::ros_layer {

/// Outcome of callWithin().
enum class CallOutcome {
  Answered,  ///< The server answered and the call succeeded: `service.response` holds its answer.
  NoServer,  ///< No server of that name appeared within the timeout.
  Failed,    ///< The call returned false (a server that failed, or the connection dropped).
  TimedOut,  ///< No answer within the timeout: the call goes on on its own thread, `service` is unchanged.
};

/// What an outcome means, for messages ("answered", "no server", "the call failed", "no answer in time").
inline const char* describe(CallOutcome outcome) noexcept {
  switch (outcome) {
    case CallOutcome::Answered:
      return "answered";
    case CallOutcome::NoServer:
      return "no server";
    case CallOutcome::Failed:
      return "the call failed";
    case CallOutcome::TimedOut:
      break;
  }
  return "no answer in time";
}

/// Waits for `client`'s server and calls it with `service` (its request in, its response out), all within at most
/// `timeout` [s of wall time] (> 0).
template <class Service>
CallOutcome callWithin(const ros::ServiceClient& client, Service& service, double timeout) {
  struct Shared {
    Service service;
    std::promise<CallOutcome> done;
  };
  auto shared = std::make_shared<Shared>();
  shared->service = service;
  std::future<CallOutcome> answer = shared->done.get_future();
  ros::ServiceClient own = client;  // a handle: the copy calls the same service
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  std::thread([own, shared, timeout]() mutable {
    if (!own.waitForExistence(ros::Duration(timeout))) {
      shared->done.set_value(CallOutcome::NoServer);
      return;
    }
    shared->done.set_value(own.call(shared->service) ? CallOutcome::Answered : CallOutcome::Failed);
  }).detach();
  // The existence wait ends at the deadline too: a moment more for its answer to come across.
  if (answer.wait_until(deadline + std::chrono::milliseconds(100)) != std::future_status::ready) {
    return CallOutcome::TimedOut;
  }
  const CallOutcome outcome = answer.get();
  if (outcome == CallOutcome::Answered) service = shared->service;
  return outcome;
}

}  // namespace bimanual_skills::ros_layer
