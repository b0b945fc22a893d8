#pragma once
/// The simulation as a hosting::ControlLoop's robot: what bullet_sim hosts its controllers on, and what a test of the
/// loop over real physics uses without ROS. advance() steps the physics (stopping on an arm's divergence, freezing a
/// diverged cloth); due() runs the grippers' commands scheduled for a time of the robot's clock.
#include "bimanual_skills/hosting/control_loop.hpp"
#include "bimanual_skills/realtime/seqlock.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"

#include <atomic>
#include <cstdint>
#include <limits>
#include <vector>

namespace bimanual_skills::hosting {

/// When a scheduled gripper command was done (−t − 1 when it failed at t; NaN: none yet) and for when it was
/// scheduled.
struct GripperDone {
  double at, due;
};

class SimulatedRobot final : public LoopRobot {
 public:
  static constexpr double kNever = std::numeric_limits<double>::infinity();  ///< No gripper command scheduled.

  explicit SimulatedRobot(sim::BimanualSimulation& simulation);

  int armCount() const noexcept override { return simulation_.armCount(); }
  int jointCount(int arm) const noexcept override { return simulation_.jointCount(arm); }
  /// The arm's state stamped on the robot's clock (time()).
  sim::RobotStatus readJointState(int arm, sim::JointState& state) noexcept override {
    const sim::RobotStatus status = simulation_.readJointState(arm, state);
    state.time += offset_;
    return status;
  }
  sim::RobotStatus writeJointTorques(int arm, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept override {
    return simulation_.writeJointTorques(arm, torque);
  }
  /// The robot's clock: the simulation's time plus the clock offset (0 unless setClockOffset()).
  double time() const noexcept override { return offset_ + simulation_.time(); }
  /// Loop thread (a request, or before the loop runs): the robot's clock is `offset` + the simulation's time (the
  /// robot's time before a reset, for a clock that never goes back).
  void setClockOffset(double offset) noexcept { offset_ = offset; }
  /// Before the loop runs: with `on`, the robot's clock is the wall's (the system clock, as a robot's driver stamps
  /// its samples): after each step it catches up with the wall clock when it fell behind (a stalled loop), and it
  /// never goes back.
  void followWallClock(bool on) noexcept { wall_clock_ = on; }
  bool advance() noexcept override;
  const char* stopReason() const noexcept override {
    return "the simulation diverged (a state became non-finite or faster than 100 rad/s); call ~reset";
  }
  void due(double t) noexcept override;

  /// Loop thread (a request): a gripper command for arm `a` at time `at` (kNever: none, one scheduled is dropped).
  void schedule(int a, double at, bool grasp);
  /// Loop thread (a request), after the simulation's reset: drops what was scheduled on the old clock.
  void reset();
  /// Any thread: the cloth diverged in the last step (the simulation froze it), and how.
  bool clothDiverged() const noexcept { return cloth_diverged_; }
  sim::ClothDivergence clothDivergence() const noexcept {
    return static_cast<sim::ClothDivergence>(cloth_divergence_.load());
  }
  /// Any thread: when arm a's last scheduled command was done, and how many were done so far.
  GripperDone done(std::size_t a) const noexcept { return grippers_[a].done.read(); }
  std::uint64_t doneCount(std::size_t a) const noexcept { return grippers_[a].done.writes(); }

 private:
  struct Gripper {
    double due = kNever;
    bool grasp = false;
    realtime::SeqLock<GripperDone> done{
        GripperDone{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()}};
  };
  sim::BimanualSimulation& simulation_;
  std::vector<Gripper> grippers_;
  std::atomic<bool> cloth_diverged_{false};
  std::atomic<int> cloth_divergence_{0};
  double offset_ = 0.0;
  bool wall_clock_ = false;
};

}  // namespace bimanual_skills::hosting
