#include "bimanual_skills/ros_layer/queue_spinner.hpp"

#include <ros/ros.h>

#include <chrono>
#include <stdexcept>

namespace bimanual_skills::ros_layer {

QueueSpinner::QueueSpinner(int threads, ros::CallbackQueue* queue)
    : count_(threads), queue_(queue ? queue : ros::getGlobalCallbackQueue()) {
  if (threads < 1) throw std::invalid_argument("QueueSpinner: at least one thread is needed");
}

QueueSpinner::~QueueSpinner() {
  stop();
}

void QueueSpinner::start() {
  if (running_.exchange(true)) return;
  for (int k = 0; k < count_; ++k) threads_.emplace_back([this] { serve(); });
}

void QueueSpinner::stop() {
  running_ = false;
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
}

void QueueSpinner::serve() {
  const ros::WallDuration wait(0.1);
  while (running_ && ros::ok()) {
    if (!queue_->isEnabled()) {  // shutting down: nothing will be called any more
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    queue_->callAvailable(wait);
  }
}

}  // namespace bimanual_skills::ros_layer
