#include "bimanual_skills/sim/sim_status.hpp"

namespace bimanual_skills::sim {

const char* toString(SimStatus status) noexcept {
  switch (status) {
    case SimStatus::Ok:
      return "Ok";
    case SimStatus::InvalidArgument:
      return "InvalidArgument";
    case SimStatus::UnknownArm:
      return "UnknownArm";
    case SimStatus::UnknownLink:
      return "UnknownLink";
    case SimStatus::NoCloth:
      return "NoCloth";
    case SimStatus::ClothDiverged:
      return "ClothDiverged";
    case SimStatus::ArmDiverged:
      return "ArmDiverged";
  }
  return "Unknown";
}

}  // namespace bimanual_skills::sim
