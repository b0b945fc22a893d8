#include "bimanual_skills/dynamics/dynamics_status.hpp"

namespace bimanual_skills::dynamics {

const char* toString(DynamicsStatus status) noexcept {
  switch (status) {
    case DynamicsStatus::Success:
      return "success";
    case DynamicsStatus::WrongSize:
      return "a vector has the wrong size";
    case DynamicsStatus::NotFinite:
      return "a vector contains NaN or Inf";
    case DynamicsStatus::NotPositiveDefinite:
      return "the mass matrix is not positive definite";
  }
  return "unknown status";
}

}  // namespace bimanual_skills::dynamics
