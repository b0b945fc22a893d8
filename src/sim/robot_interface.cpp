#include "bimanual_skills/sim/robot_interface.hpp"

namespace bimanual_skills::sim {

const char* toString(RobotStatus status) noexcept {
  switch (status) {
    case RobotStatus::Ok:
      return "Ok";
    case RobotStatus::InvalidCommand:
      return "InvalidCommand";
    case RobotStatus::WrongSize:
      return "WrongSize";
    case RobotStatus::UnknownArm:
      return "UnknownArm";
    case RobotStatus::Fault:
      return "Fault";
  }
  return "Unknown";
}

}  // namespace bimanual_skills::sim
