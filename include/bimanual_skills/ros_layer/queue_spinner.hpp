#pragma once
// Threads that serve a callback queue, as ros::AsyncSpinner does, without its spin at shutdown.

#include <ros/callback_queue.h>

#include <atomic>
#include <thread>
#include <vector>

namespace bimanual_skills::ros_layer {

/// Serves `queue` (the global one if null) on `threads` threads from start() to stop() or the node's shutdown.
/// ros::AsyncSpinner's threads call a disabled queue, which returns at once, until ros::ok() turns false: roscpp
/// disables the global queue at the start of its shutdown and then unregisters everything from the master, so they
/// spin meanwhile. In a process at SCHED_FIFO (sim.launch process_priority) that spin starved the master's answers
/// on both cores and no controller stopped on SIGINT. These threads wait on a disabled queue instead.
class QueueSpinner {
 public:
  explicit QueueSpinner(int threads, ros::CallbackQueue* queue = nullptr);
  ~QueueSpinner();
  QueueSpinner(const QueueSpinner&) = delete;
  QueueSpinner& operator=(const QueueSpinner&) = delete;

  void start();
  /// Joins the threads (each within one wait of 0.1 s).
  void stop();

 private:
  void serve();

  int count_;
  ros::CallbackQueue* queue_;
  std::atomic<bool> running_{false};
  std::vector<std::thread> threads_;
};

}  // namespace bimanual_skills::ros_layer
