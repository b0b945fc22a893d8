#include "bimanual_skills/ros_layer/bounded_call.hpp"

namespace bimanual_skills::ros_layer {

const char* describe(CallOutcome outcome) noexcept {
  switch (outcome) {
    case CallOutcome::Answered:
      return "answered";
    case CallOutcome::NoServer:
      return "no server";
    case CallOutcome::Failed:
      return "the call failed";
    case CallOutcome::Busy:
      return "its last call is still unanswered";
    case CallOutcome::TimedOut:
      break;
  }
  return "no answer in time";
}

bool ServiceCaller::settle(Channel& channel) {
  if (channel.in_flight) return false;
  if (channel.worker.joinable()) channel.worker.join();  // its call has ended: the thread is leaving
  return true;
}

bool ServiceCaller::drain(double timeout, std::string* busy) {
  std::unique_lock<std::mutex> lock(state_->mutex);
  const auto idle = [this] {
    for (auto& [name, channel] : state_->channels) {
      if (!settle(channel)) return false;
    }
    return true;
  };
  if (state_->changed.wait_for(lock, std::chrono::duration<double>(timeout), idle)) return true;
  if (busy) {
    busy->clear();
    for (const auto& [name, channel] : state_->channels) {
      if (channel.in_flight) *busy += (busy->empty() ? "" : ", ") + name;
    }
  }
  return false;
}

ServiceCaller::~ServiceCaller() {
  (void)drain(1.0);
  const std::lock_guard<std::mutex> lock(state_->mutex);
  for (auto& [name, channel] : state_->channels) {
    if (channel.worker.joinable()) channel.worker.detach();  // still waiting on its server: it holds the state
  }
}

}  // namespace bimanual_skills::ros_layer
