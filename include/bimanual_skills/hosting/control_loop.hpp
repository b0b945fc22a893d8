/// \file
/// The loop a robot's driver runs to host the arms' controllers (ros_control's hardware loop without ros_control).
/// Each cycle it reads every arm's joint state from a LoopRobot, hands the states out, runs each hosted
/// controller (control::RealtimeArmController) or takes the newest torque command of an arm commanded from outside
/// (through a sim::TorqueCommandGate that brakes when commands stop), writes the torques and lets the robot advance
/// (a simulator steps its physics; a driver sends the torques and waits for the next sample). It paces itself on the
/// wall clock at a real-time factor, or in lockstep waits for each outside command that answers the state it read.
/// It can be paused, stepped a number of cycles and stopped by the robot (a diverged simulation, an emergency stop),
/// and it runs requests of other threads (a reset, a scheduled gripper command) between two cycles. The cycle is
/// real-time safe: no allocation, lock, exception or logging; other threads reach it only through lock-free
/// handoffs and a request mailbox it polls without waiting.
#pragma once

#include "bimanual_skills/control/realtime_arm_controller.hpp"
#include "bimanual_skills/realtime/cycle_probe.hpp"
#include "bimanual_skills/realtime/loop_pacer.hpp"
#include "bimanual_skills/realtime/period_recorder.hpp"
#include "bimanual_skills/realtime/triple_buffer.hpp"
#include "bimanual_skills/sim/robot_interface.hpp"
#include "bimanual_skills/sim/torque_command_gate.hpp"

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <iosfwd>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bimanual_skills::hosting {

/// A robot as the loop drives it: joint states and torques (sim::RobotInterface), its clock, and what it does after
/// the torques are written. All calls come from the loop thread and must be real-time safe.
class LoopRobot : public sim::RobotInterface {
 public:
  /// The robot's clock [s]: the stamp of the states readJointState gives now.
  virtual double time() const noexcept = 0;
  /// After the torques of a cycle are written: a simulator steps, a driver sends and waits for the next sample.
  /// Returns false when the robot stopped and cannot go on (the loop then stops until restart()).
  virtual bool advance() noexcept = 0;
  /// Why advance() returned false (a static string).
  virtual const char* stopReason() const noexcept { return "the robot stopped"; }
  /// At the start of every cycle that runs, before the states are read: actions scheduled for time t (a gripper).
  virtual void due(double /*t*/) noexcept {}

 protected:
  LoopRobot() = default;
};

/// Who receives the states the loop reads (a publisher thread's handoff). Called on the loop thread; real-time safe.
class StateSink {
 public:
  virtual ~StateSink() = default;
  /// The states of every arm at robot time t. `forced`: the end of a step() (the moment a stepping client observes:
  /// send everything, images too). While the robot is stopped, the last states again every 0.1 s, t frozen.
  virtual void states(double t, const std::vector<sim::JointState>& states, bool forced) noexcept = 0;

 protected:
  StateSink() = default;
  StateSink(const StateSink&) = default;
  StateSink& operator=(const StateSink&) = default;
};

struct LoopSettings {
  double period = 0.001;          ///< The robot's step [s of its clock].
  double realtime_factor = 1.0;   ///< Free-running: robot seconds per wall second (0: as fast as it goes).
  double max_drift = 0.05;        ///< Wall seconds behind or ahead before the schedule restarts (LoopPacer).
  bool lockstep = false;          ///< Each cycle waits for the outside commands that answer its states.
  double lockstep_timeout = 0.2;  ///< Wall seconds a lockstep cycle waits before braking the arms that did not answer.
  bool paused = false;            ///< Start paused.
  /// Whether pause() and step() may hold the robot's clock: a simulator's can stand still, a robot's cannot (a
  /// driver sets false; pause(true) and step() then fail saying so, and the loop never stops writing torques).
  bool pausable = true;
  std::size_t statistics_capacity = 200000;  ///< Periods and cycle times kept (the newest).

  /// \throws std::invalid_argument naming the bad setting.
  void validate() const;
};

/// An outside torque command [N m] for one arm, answering the state stamped `answers` (NaN: unstamped).
struct TorqueCommand {
  Eigen::VectorXd torque;
  /// With `impedance`: the joint impedance the robot closes between commands (sim::TorqueCommandGate), each sized
  /// like `torque`.
  Eigen::VectorXd position, velocity, stiffness, damping;
  bool impedance = false;
  double answers = std::numeric_limits<double>::quiet_NaN();
  bool well_formed = false;
};

/// A torque command's joint impedance as arrays of the command's size (TorqueCommand).
struct CommandImpedance {
  const double* position = nullptr;
  const double* velocity = nullptr;
  const double* stiffness = nullptr;
  const double* damping = nullptr;
};

/// How a request of another thread ended.
struct LoopOutcome {
  bool success = false;
  std::string message;
  double time = 0.0;  ///< The robot's clock when it ended.
};

/// What the loop counted (any thread may read it).
struct LoopCounts {
  long cycles = 0, control_allocations = 0, control_cycles_that_allocated = 0, robot_steps_that_allocated = 0;
  long rejected_commands = 0;  ///< Outside commands of a wrong size or with NaN/Inf.
  long late_commands = 0;      ///< Lockstep: outside commands answering an older state (dropped).
  long lockstep_timeouts = 0;  ///< Lockstep cycles that went on without every answer.
  long schedule_restarts = 0;  ///< LoopPacer slips.
  long faulted_states = 0;     ///< Arm states the robot could not read (readJointState not Ok): the arm held.
  long unusable_states = 0;    ///< States a hosted controller refused (stale stamp, NaN/Inf): the arm held.
};

class ControlLoop {
 public:
  /// For `robot`'s arms (none hosted or commanded yet); `probe` (may be null) brackets the cycle's parts. Keeps
  /// references to robot, sink and probe. \throws std::invalid_argument for bad settings.
  ControlLoop(LoopRobot& robot, StateSink& sink, LoopSettings settings, realtime::CycleProbe* probe = nullptr);
  ~ControlLoop();
  ControlLoop(const ControlLoop&) = delete;
  ControlLoop& operator=(const ControlLoop&) = delete;

  // ---- Set-up, before run() ----
  /// Arm `arm` is driven by `controller` in the loop; `stopped` is told why when the loop stops (not when paused).
  /// Each cycle the controller gets the state's own stamp (sim::JointState::time, on the robot's clock): a state
  /// that stopped changing is stale. While the robot cannot read the arm's state, or the controller refuses it
  /// (stale, NaN/Inf), the arm gets the gravity torque at its last valid posture
  /// (RealtimeArmController::holdingTorque), never zero torque, and the loop counts it (LoopCounts).
  void host(int arm, control::RealtimeArmController& controller, std::function<void(const std::string&)> stopped);
  /// Arm `arm` takes torque commands from outside (torqueCommand()): stale after `timeout` robot seconds, then
  /// braked with `damping` [N m s/rad per joint]; with `lockstep_waits`, a lockstep cycle waits for its answer.
  /// An arm neither hosted nor commanded gets zero torque. \throws std::invalid_argument for a bad arm or damping.
  void commandFromOutside(int arm, double timeout, const Eigen::VectorXd& damping, bool lockstep_waits);

  // ---- The loop thread ----
  /// Runs the loop on the calling thread until `keep_running` returns false (asked between cycles), then ends the
  /// requests still waiting with "shutting down".
  void run(const std::function<bool()>& keep_running);
  /// From a request (call()) after the robot was reset: forgets outside commands, clears a stop, reads and hands out
  /// the states, restarts the schedule; a step() in progress ends with `why`.
  void restart(const std::string& why);
  /// The states read last (loop thread, or a request).
  const std::vector<sim::JointState>& states() const noexcept { return states_; }

  // ---- Other threads ----
  /// Runs `request` on the loop thread between two cycles and returns its outcome: waits at most `wait` wall seconds
  /// for the loop to take it (then an outcome saying so), then until it ran.
  LoopOutcome call(std::function<LoopOutcome()> request, double wait = 5.0);
  /// Pauses (true) or resumes the loop; the message gives the robot time of the last states handed out ("paused at
  /// t = 1.234000 s"). A paused loop lets the hosted controllers receive their commands (RealtimeArmController::idle).
  LoopOutcome pause(bool paused, double wait = 5.0);
  /// A paused loop runs `cycles` cycles (as fast as it goes, serving requests in between; at the real-time factor
  /// when an arm is commanded from outside without lockstep, so that its controller keeps up), hands out the last
  /// states as forced and answers; fails at once when running, stopped, or another step() runs.
  LoopOutcome step(std::uint32_t cycles, double wait = 5.0);
  /// An outside command for arm `arm` (one writer thread per arm): `answers` is the stamp of the state it answers
  /// (NaN: unstamped); `impedance`, if any, the joint impedance the robot closes until the next command. Sizes and
  /// values are checked by the loop (rejected_commands).
  void torqueCommand(int arm, double answers, const double* torque, std::size_t size,
                     const CommandImpedance* impedance = nullptr);

  double time() const noexcept { return time_.load(std::memory_order_relaxed); }
  bool paused() const noexcept { return paused_.load(std::memory_order_relaxed); }
  /// Whether the robot stopped the loop (advance() returned false), and its reason then.
  bool stopped() const noexcept { return stopped_.load(std::memory_order_acquire); }
  const char* stopReason() const noexcept { return robot_.stopReason(); }
  /// Robot time when it stopped.
  double stopTime() const noexcept { return stop_time_.load(std::memory_order_relaxed); }
  const LoopSettings& settings() const noexcept { return settings_; }
  LoopCounts counts() const noexcept;
  /// The newest wall periods of paced, consecutive cycles [s] (allocates).
  void periods(std::vector<double>& out) const { periods_.snapshot(out); }
  /// Periods, cycle times, the times the hosted controllers took commands and the counts, as CSV "series,value".
  void writeStatistics(std::ostream& out) const;

 private:
  struct Arm;
  struct Request;
  bool cycle() noexcept;
  void waitForAnswers(double t) noexcept;
  void handOut(double t, bool forced) noexcept;
  void endStep(bool success, const std::string& why);
  /// Ends a step() in progress, unsuccessfully, with `why` (nothing without one).
  void interruptStep(const std::string& why);
  LoopOutcome notPausable() const;
  std::vector<std::shared_ptr<Request>> takeRequests();

  LoopRobot& robot_;
  StateSink& sink_;
  realtime::CycleProbe* probe_;
  LoopSettings settings_;
  realtime::LoopPacer pacer_;
  std::vector<std::unique_ptr<Arm>> arms_;
  std::vector<sim::JointState> states_;
  realtime::PeriodRecorder periods_, cycle_times_, command_times_;
  std::mutex requests_mutex_;
  std::deque<std::shared_ptr<Request>> requests_;
  std::shared_ptr<Request> stepping_;  ///< Loop thread only.
  std::uint32_t stepped_ = 0;
  bool outside_unlocked_ = false;  ///< An arm is commanded from outside and no lockstep cycle waits for it.
  std::atomic<bool> paused_{false}, stopped_{false};
  bool stop_told_ = false;  ///< The hosted controllers were told of the stop.
  std::atomic<double> time_{0.0}, stop_time_{0.0};
  double handed_out_ = std::numeric_limits<double>::quiet_NaN();  ///< Stamp of the last states handed out.
  double next_stopped_hand_out_ = 0.0;
  std::atomic<long> cycles_{0}, control_allocations_{0}, control_cycles_that_allocated_{0},
      robot_steps_that_allocated_{0}, rejected_{0}, late_{0}, lockstep_timeouts_{0}, slips_{0}, faulted_{0},
      unusable_{0};
};

}  // namespace bimanual_skills::hosting
