/// \file
/// A ROS service call with a deadline. ROS 1's ServiceClient::call has none: a server that stops answering (a process
/// stopped with SIGSTOP, a driver stuck in a blocking call) would hold the caller for good. The call runs on a thread
/// of its own and the caller waits at most the timeout for its answer; a call still running then is left to end on
/// its thread (it holds only copies), and the caller goes on with a failure it can report. Target
/// bimanual_skills_ros. Not for a real-time loop: starts a thread per call.
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
  Failed,    ///< The call returned false (no server, a server that failed or the connection dropped).
  TimedOut,  ///< No answer within the timeout: the call goes on on its own thread, `service` is unchanged.
};

/// Calls `client` with `service` (its request in, its response out) and waits at most `timeout` [s of wall time].
template <class Service>
CallOutcome callWithin(const ros::ServiceClient& client, Service& service, double timeout) {
  struct Shared {
    Service service;
    std::promise<bool> done;
  };
  auto shared = std::make_shared<Shared>();
  shared->service = service;
  std::future<bool> answer = shared->done.get_future();
  ros::ServiceClient own = client;  // a handle: the copy calls the same service
  std::thread([own, shared]() mutable { shared->done.set_value(own.call(shared->service)); }).detach();
  if (answer.wait_for(std::chrono::duration<double>(timeout)) != std::future_status::ready)
    return CallOutcome::TimedOut;
  if (!answer.get()) return CallOutcome::Failed;
  service = shared->service;
  return CallOutcome::Answered;
}

}  // namespace bimanual_skills::ros_layer
