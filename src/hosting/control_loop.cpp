#include "bimanual_skills/hosting/control_loop.hpp"

#include "bimanual_skills/realtime/clock.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace bimanual_skills::hosting {

namespace {

/// How close a command's stamp must be to the cycle's to answer it [s] (the stamps travel as ROS times, in ns).
constexpr double kStampTolerance = 1e-7;
/// Wall seconds between hand-outs of the last states while the robot is stopped.
constexpr double kStoppedHandOut = 0.1;

std::string fixed(double value) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(6) << value;
  return text.str();
}

}  // namespace

void LoopSettings::validate() const {
  if (!(period > 0.0) || !std::isfinite(period)) throw std::invalid_argument("loop period must be positive");
  if (!(realtime_factor >= 0.0) || !std::isfinite(realtime_factor)) {
    throw std::invalid_argument("real-time factor must be finite and >= 0");
  }
  if (!(max_drift > 0.0)) throw std::invalid_argument("max_drift must be positive");
  if (!(lockstep_timeout > 0.0) || !std::isfinite(lockstep_timeout)) {
    throw std::invalid_argument("lockstep_timeout must be positive and finite");
  }
  if (statistics_capacity == 0) throw std::invalid_argument("statistics_capacity must be positive");
  if (paused && !pausable)
    throw std::invalid_argument("a loop that cannot be paused (pausable false) cannot start paused");
}

/// One arm in the loop.
struct ControlLoop::Arm {
  int joints = 0;
  Eigen::VectorXd torque;
  sim::RobotStatus read = sim::RobotStatus::Ok;  ///< How this cycle's state read went.
  // Hosted.
  control::RealtimeArmController* controller = nullptr;
  std::function<void(const std::string&)> stopped;
  std::uint64_t commands_taken = 0;
  // Commanded from outside.
  std::unique_ptr<sim::TorqueCommandGate> gate;
  std::unique_ptr<realtime::TripleBuffer<TorqueCommand>> commands;
  const TorqueCommand* newest = nullptr;  ///< Loop side: the newest command read, not yet applied.
  bool lockstep_waits = false;
};

/// A request of another thread, run on the loop thread.
struct ControlLoop::Request {
  std::function<LoopOutcome()> run;  ///< Null for a step().
  std::uint32_t cycles = 0;          ///< step(): how many.
  LoopOutcome outcome;
  std::promise<void> done;
  bool finished = false;
  void finish() {
    if (finished) return;
    finished = true;
    done.set_value();
  }
};

ControlLoop::ControlLoop(LoopRobot& robot, StateSink& sink, LoopSettings settings, realtime::CycleProbe* probe)
    : robot_(robot),
      sink_(sink),
      probe_(probe),
      settings_((settings.validate(), settings)),
      pacer_(settings.period / (settings.realtime_factor > 0.0 ? settings.realtime_factor : 1.0), settings.max_drift),
      periods_(settings.statistics_capacity),
      cycle_times_(settings.statistics_capacity),
      command_times_(10000),
      paused_(settings.paused) {
  for (int a = 0; a < robot_.armCount(); ++a) {
    arms_.push_back(std::make_unique<Arm>());
    arms_.back()->joints = robot_.jointCount(a);
    arms_.back()->torque = Eigen::VectorXd::Zero(robot_.jointCount(a));
    states_.emplace_back(robot_.jointCount(a));
    robot_.readJointState(a, states_.back());
  }
  time_.store(robot_.time());
}

ControlLoop::~ControlLoop() = default;

void ControlLoop::host(int arm, control::RealtimeArmController& controller,
                       std::function<void(const std::string&)> stopped) {
  if (arm < 0 || arm >= static_cast<int>(arms_.size()))
    throw std::invalid_argument("host: no arm " + std::to_string(arm));
  Arm& a = *arms_[static_cast<std::size_t>(arm)];
  if (controller.joints() != a.joints) {
    throw std::invalid_argument("host: the controller drives " + std::to_string(controller.joints()) + " joints, arm " +
                                std::to_string(arm) + " has " + std::to_string(a.joints));
  }
  if (a.gate) throw std::invalid_argument("host: arm " + std::to_string(arm) + " is commanded from outside");
  a.controller = &controller;
  a.stopped = std::move(stopped);
}

void ControlLoop::commandFromOutside(int arm, double timeout, const Eigen::VectorXd& damping, bool lockstep_waits) {
  if (arm < 0 || arm >= static_cast<int>(arms_.size())) {
    throw std::invalid_argument("commandFromOutside: no arm " + std::to_string(arm));
  }
  Arm& a = *arms_[static_cast<std::size_t>(arm)];
  if (a.controller) throw std::invalid_argument("commandFromOutside: arm " + std::to_string(arm) + " is hosted");
  a.gate = std::make_unique<sim::TorqueCommandGate>(a.joints, timeout, damping);
  TorqueCommand initial;
  initial.torque = Eigen::VectorXd::Zero(a.joints);
  a.commands = std::make_unique<realtime::TripleBuffer<TorqueCommand>>(initial);
  a.lockstep_waits = lockstep_waits;
  outside_unlocked_ = outside_unlocked_ || !settings_.lockstep || !lockstep_waits;
}

void ControlLoop::torqueCommand(int arm, double answers, const double* torque, std::size_t size,
                                const CommandImpedance* impedance) {
  if (arm < 0 || arm >= static_cast<int>(arms_.size())) return;
  Arm& a = *arms_[static_cast<std::size_t>(arm)];
  if (!a.commands) return;
  TorqueCommand& command = a.commands->writeSlot();
  command.well_formed = size == static_cast<std::size_t>(a.joints);
  command.impedance = false;
  if (command.well_formed) command.torque = Eigen::Map<const Eigen::VectorXd>(torque, a.joints);
  if (command.well_formed && impedance != nullptr) {
    if (!impedance->position || !impedance->velocity || !impedance->stiffness || !impedance->damping) {
      command.well_formed = false;
    } else {
      command.position = Eigen::Map<const Eigen::VectorXd>(impedance->position, a.joints);
      command.velocity = Eigen::Map<const Eigen::VectorXd>(impedance->velocity, a.joints);
      command.stiffness = Eigen::Map<const Eigen::VectorXd>(impedance->stiffness, a.joints);
      command.damping = Eigen::Map<const Eigen::VectorXd>(impedance->damping, a.joints);
      command.impedance = true;
    }
  }
  command.answers = answers;
  a.commands->publish();
}

// ---------------------------------------------------------------- the loop thread

void ControlLoop::run(const std::function<bool()>& keep_running) {
  handOut(robot_.time(), true);
  bool consecutive = false;  // the previous cycle was paced and not interrupted: its period counts
  double last_start = 0.0;
  while (keep_running()) {
    for (auto& request : takeRequests()) {
      if (request->run) {
        request->outcome = request->run();
        request->finish();
      } else if (!paused_ || stopped_ || stepping_) {
        request->outcome.time = robot_.time();
        request->outcome.message = !paused_ ? "the loop is running; pause it first"
                                   : stopped_
                                       ? std::string("the robot stopped (") + robot_.stopReason() + "); restart it"
                                       : "another step is running";
        request->finish();
      } else if (request->cycles == 0) {
        request->outcome = {true, "stepped 0 of 0", robot_.time()};
        request->finish();
      } else {
        stepping_ = request;  // stepped one cycle per pass, serving other requests in between
        stepped_ = 0;
      }
    }
    const bool stepping = stepping_ != nullptr;
    if (stopped_ || (paused_ && !stepping)) {
      for (auto& arm : arms_) {
        if (!arm->controller) continue;
        if (!stopped_) {
          arm->controller->idle();  // paused: goals still reach the loop (and are accepted)
        } else if (!stop_told_ && arm->stopped) {
          arm->stopped(robot_.stopReason());  // not real-time any more: the robot stands
        }
      }
      stop_told_ = stopped_;
      if (stopped_ && realtime::monotonicSeconds() > next_stopped_hand_out_) {
        next_stopped_hand_out_ = realtime::monotonicSeconds() + kStoppedHandOut;
        sink_.states(stop_time_.load(), states_, false);  // the last valid states, stamp frozen
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      pacer_.reanchor();
      consecutive = false;
      continue;
    }
    // A step runs as fast as it goes, unless controllers outside follow the states without lockstep: they keep
    // up only at the pace they were given.
    const bool paced = (!stepping || outside_unlocked_) && settings_.realtime_factor > 0.0 && !settings_.lockstep;
    if (paced && !pacer_.waitUntilDue(0.005)) continue;  // short slices: requests are served meanwhile
    const double start = realtime::monotonicSeconds();
    if (paced && consecutive) periods_.record(start - last_start);
    last_start = start;
    const bool went_on = cycle();
    cycle_times_.record(realtime::monotonicSeconds() - start);
    if (paced) {
      const long slips = pacer_.slips();
      pacer_.advance();
      consecutive = pacer_.slips() == slips;
      slips_.store(pacer_.slips(), std::memory_order_relaxed);
    } else {
      pacer_.reanchor();
      consecutive = false;
    }
    if (stepping_ && (++stepped_ == stepping_->cycles || !went_on)) {
      // The states where the steps ended, handed out as forced: a client that stepped to a moment observes that
      // moment (the clock stands still there).
      for (std::size_t a = 0; a < arms_.size(); ++a) robot_.readJointState(static_cast<int>(a), states_[a]);
      handOut(robot_.time(), true);
      endStep(went_on, went_on ? "" : std::string(": ") + robot_.stopReason());
      pacer_.reanchor();
    }
  }
  for (auto& request : takeRequests()) {
    request->outcome = {false, "the loop is shutting down", robot_.time()};
    request->finish();
  }
  if (stepping_) endStep(false, ": the loop is shutting down");
}

void ControlLoop::endStep(bool success, const std::string& why) {
  stepping_->outcome.success = success;
  stepping_->outcome.message = "stepped " + std::to_string(stepped_) + " of " + std::to_string(stepping_->cycles) + why;
  stepping_->outcome.time = robot_.time();
  stepping_->finish();
  stepping_.reset();
}

void ControlLoop::interruptStep(const std::string& why) {
  if (!stepping_) return;
  stepping_->outcome = {
      false,
      "interrupted after " + std::to_string(stepped_) + " of " + std::to_string(stepping_->cycles) + " steps: " + why,
      robot_.time()};
  stepping_->finish();
  stepping_.reset();
}

void ControlLoop::restart(const std::string& why) {
  interruptStep(why);
  for (std::size_t a = 0; a < arms_.size(); ++a) {
    Arm& arm = *arms_[a];
    if (arm.gate) {
      arm.gate->clear();
      arm.newest = nullptr;
    }
    robot_.readJointState(static_cast<int>(a), states_[a]);
  }
  stopped_.store(false, std::memory_order_release);
  stop_told_ = false;
  time_.store(robot_.time(), std::memory_order_relaxed);
  handed_out_ = std::numeric_limits<double>::quiet_NaN();
  handOut(robot_.time(), true);
  pacer_.reanchor();
}

void ControlLoop::handOut(double t, bool forced) noexcept {
  if (!forced && t == handed_out_) return;  // no state twice with one stamp (the first cycle after a hand-out)
  handed_out_ = t;
  sink_.states(t, states_, forced);
}

/// One cycle: due actions, read, hand out, (lockstep: wait), control, write, advance. Returns false when the robot
/// stopped.
bool ControlLoop::cycle() noexcept {
  const double t = robot_.time();
  robot_.due(t);  // outside the probe: a simulated gripper attaches the cloth (Bullet allocates)
  if (probe_) probe_->begin();
  for (std::size_t a = 0; a < arms_.size(); ++a) {
    arms_[a]->read = robot_.readJointState(static_cast<int>(a), states_[a]);
    if (arms_[a]->read != sim::RobotStatus::Ok) faulted_.fetch_add(1, std::memory_order_relaxed);
  }
  handOut(t, false);
  if (settings_.lockstep) waitForAnswers(t);
  for (std::size_t a = 0; a < arms_.size(); ++a) {
    Arm& arm = *arms_[a];
    const sim::JointState& state = states_[a];
    if (arm.controller && arm.read != sim::RobotStatus::Ok) {
      (void)arm.controller->holdingTorque(arm.torque);  // no state this cycle: held where it was last seen
    } else if (arm.controller) {
      const auto status =
          arm.controller->update(t, state.time, state.position, state.velocity, state.effort, arm.torque);
      if (status == control::ControllerStatus::InvalidState || status == control::ControllerStatus::StaleState) {
        unusable_.fetch_add(1, std::memory_order_relaxed);
        (void)arm.controller->holdingTorque(arm.torque);
      }
      if (arm.controller->commandsTaken() != arm.commands_taken) {
        arm.commands_taken = arm.controller->commandsTaken();
        command_times_.record(arm.controller->lastCommandTaken());
      }
    } else if (arm.gate) {
      if (const TorqueCommand* command = arm.commands->readNew()) arm.newest = command;
      if (const TorqueCommand* command = arm.newest) {
        arm.newest = nullptr;
        // In lockstep a stamped command applies to the state it answers only; unstamped ones to the current state.
        if (settings_.lockstep && !std::isnan(command->answers) && std::abs(command->answers - t) > kStampTolerance) {
          late_.fetch_add(1, std::memory_order_relaxed);
        } else if (!command->well_formed ||
                   (command->impedance ? arm.gate->accept(t, command->torque, command->position, command->velocity,
                                                          command->stiffness, command->damping, command->answers)
                                       : arm.gate->accept(t, command->torque)) != sim::RobotStatus::Ok) {
          rejected_.fetch_add(1, std::memory_order_relaxed);
        }
      }
      arm.gate->torque(t, state.position, state.velocity, arm.torque);
    } else {
      arm.torque.setZero();
    }
    robot_.writeJointTorques(static_cast<int>(a), arm.torque);
  }
  if (probe_) {
    const auto allocations = static_cast<long>(probe_->end());
    if (allocations > 0) {
      control_cycles_that_allocated_.fetch_add(1, std::memory_order_relaxed);
      control_allocations_.fetch_add(allocations, std::memory_order_relaxed);
    }
    probe_->begin();
  }
  const bool went_on = robot_.advance();
  if (probe_ && probe_->end() > 0) robot_steps_that_allocated_.fetch_add(1, std::memory_order_relaxed);
  time_.store(robot_.time(), std::memory_order_relaxed);
  if (!went_on) {
    stop_time_.store(robot_.time(), std::memory_order_relaxed);
    stopped_.store(true, std::memory_order_release);
  }
  cycles_.fetch_add(1, std::memory_order_relaxed);
  return went_on;
}

/// Lockstep: waits (wall clock, bounded) until every arm that lockstep waits for has a command answering time t.
void ControlLoop::waitForAnswers(double t) noexcept {
  const double deadline = realtime::monotonicSeconds() + settings_.lockstep_timeout;
  for (;;) {
    bool all = true;
    for (auto& arm : arms_) {
      if (!arm->gate || !arm->lockstep_waits) continue;
      if (const TorqueCommand* command = arm->commands->readNew()) {
        if (arm->newest && !std::isnan(arm->newest->answers)) late_.fetch_add(1, std::memory_order_relaxed);
        arm->newest = command;
      }
      const TorqueCommand* newest = arm->newest;
      all = all && newest && (std::isnan(newest->answers) || std::abs(newest->answers - t) <= kStampTolerance);
    }
    if (all) return;
    if (realtime::monotonicSeconds() > deadline) {
      lockstep_timeouts_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
}

// ---------------------------------------------------------------- other threads

std::vector<std::shared_ptr<ControlLoop::Request>> ControlLoop::takeRequests() {
  std::vector<std::shared_ptr<Request>> taken;
  std::unique_lock<std::mutex> lock(requests_mutex_, std::try_to_lock);
  if (!lock.owns_lock() || requests_.empty()) return taken;
  taken.assign(requests_.begin(), requests_.end());
  requests_.clear();
  return taken;
}

namespace {

/// Queues `request` and waits: at most `wait` for the loop to take it, then until it is done.
template <typename Request>
LoopOutcome submit(std::mutex& mutex, std::deque<std::shared_ptr<Request>>& queue, std::shared_ptr<Request> request,
                   double wait) {
  std::future<void> done = request->done.get_future();
  {
    const std::lock_guard<std::mutex> lock(mutex);
    queue.push_back(request);
  }
  const auto taken_by = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait);
  while (done.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready) {
    const std::lock_guard<std::mutex> lock(mutex);
    const auto queued = std::find(queue.begin(), queue.end(), request);
    if (queued != queue.end() && std::chrono::steady_clock::now() > taken_by) {
      queue.erase(queued);
      LoopOutcome outcome;
      outcome.message = "the control loop did not take the request within " + fixed(wait) + " s";
      return outcome;
    }
  }
  return request->outcome;
}

}  // namespace

LoopOutcome ControlLoop::call(std::function<LoopOutcome()> request, double wait) {
  auto r = std::make_shared<Request>();
  r->run = std::move(request);
  return submit(requests_mutex_, requests_, r, wait);
}

LoopOutcome ControlLoop::notPausable() const {
  return {false,
          "this robot's clock cannot be held or stepped (LoopSettings::pausable is false: a robot's loop runs on)",
          robot_.time()};
}

LoopOutcome ControlLoop::pause(bool paused, double wait) {
  if (paused && !settings_.pausable) return notPausable();
  return call(
      [this, paused] {
        if (!paused) interruptStep("the loop was resumed");
        paused_ = paused;
        pacer_.reanchor();
        // The stamp of the last states handed out (a cycle hands out, then advances), to the microsecond: a client
        // may wait for its clock to get there.
        const double at = std::isnan(handed_out_) ? robot_.time() : handed_out_;
        return LoopOutcome{true, std::string(paused ? "paused" : "running") + " at t = " + fixed(at) + " s", at};
      },
      wait);
}

LoopOutcome ControlLoop::step(std::uint32_t cycles, double wait) {
  if (!settings_.pausable) return notPausable();
  auto r = std::make_shared<Request>();
  r->cycles = cycles;
  return submit(requests_mutex_, requests_, r, wait);
}

LoopCounts ControlLoop::counts() const noexcept {
  LoopCounts c;
  c.cycles = cycles_.load();
  c.control_allocations = control_allocations_.load();
  c.control_cycles_that_allocated = control_cycles_that_allocated_.load();
  c.robot_steps_that_allocated = robot_steps_that_allocated_.load();
  c.rejected_commands = rejected_.load();
  c.late_commands = late_.load();
  c.lockstep_timeouts = lockstep_timeouts_.load();
  c.schedule_restarts = slips_.load();
  c.faulted_states = faulted_.load();
  c.unusable_states = unusable_.load();
  return c;
}

void ControlLoop::writeStatistics(std::ostream& out) const {
  out << "series,value\n";
  periods_.writeCsv(out, "period");
  cycle_times_.writeCsv(out, "cycle_time");
  command_times_.writeCsv(out, "command_taken");
  const LoopCounts c = counts();
  out << "cycles," << c.cycles << "\ncontrol_allocations," << c.control_allocations
      << "\ncontrol_cycles_that_allocated," << c.control_cycles_that_allocated << "\nphysics_steps_that_allocated,"
      << c.robot_steps_that_allocated << "\nfaulted_states," << c.faulted_states << "\nunusable_states,"
      << c.unusable_states << '\n';
}

}  // namespace bimanual_skills::hosting
