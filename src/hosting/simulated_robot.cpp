#include "bimanual_skills/hosting/simulated_robot.hpp"

#include <algorithm>
#include <chrono>

namespace bimanual_skills::hosting {

SimulatedRobot::SimulatedRobot(sim::BimanualSimulation& simulation)
    : simulation_(simulation), grippers_(static_cast<std::size_t>(simulation.armCount())) {}

bool SimulatedRobot::advance() noexcept {
  const sim::SimStatus status = simulation_.step();
  if (wall_clock_) {
    const double wall = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    offset_ = std::max(offset_, wall - simulation_.time());
  }
  cloth_diverged_ = status == sim::SimStatus::ClothDiverged;
  if (cloth_diverged_) cloth_divergence_.store(static_cast<int>(simulation_.cloth().divergence()));
  return status != sim::SimStatus::ArmDiverged;
}

void SimulatedRobot::due(double t) noexcept {
  for (std::size_t a = 0; a < grippers_.size(); ++a) {
    Gripper& g = grippers_[a];
    if (!(t >= g.due)) continue;
    int attached = 0;
    const sim::SimStatus status =
        g.grasp ? simulation_.grasp(static_cast<int>(a), &attached) : simulation_.release(static_cast<int>(a));
    g.done.write(GripperDone{status == sim::SimStatus::Ok ? t : -t - 1.0, g.due});
    g.due = kNever;
  }
}

void SimulatedRobot::schedule(int a, double at, bool grasp) {
  grippers_[static_cast<std::size_t>(a)].due = at;
  grippers_[static_cast<std::size_t>(a)].grasp = grasp;
}

void SimulatedRobot::reset() {
  for (Gripper& g : grippers_) g.due = kNever;  // scheduled on the old clock
  cloth_diverged_ = false;
}

}  // namespace bimanual_skills::hosting
