#include "bimanual_skills/signal/signal_status.hpp"

namespace bimanual_skills::signal {

const char* toString(SignalStatus status) noexcept {
  switch (status) {
    case SignalStatus::Success:
      return "success";
    case SignalStatus::WrongSize:
      return "a sample has the wrong size";
    case SignalStatus::NotFinite:
      return "a sample contains NaN or Inf";
  }
  return "unknown status";
}

}  // namespace bimanual_skills::signal
