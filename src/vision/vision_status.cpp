#include "bimanual_skills/vision/vision_status.hpp"

namespace bimanual_skills::vision {

const char* toString(VisionStatus status) noexcept {
  switch (status) {
    case VisionStatus::Ok:
      return "Ok";
    case VisionStatus::EmptyMesh:
      return "EmptyMesh";
    case VisionStatus::NonFiniteVertex:
      return "NonFiniteVertex";
    case VisionStatus::BadTriangle:
      return "BadTriangle";
    case VisionStatus::WrongImageSize:
      return "WrongImageSize";
    case VisionStatus::NoCloth:
      return "NoCloth";
    case VisionStatus::BadCameraPose:
      return "BadCameraPose";
  }
  return "Unknown";
}

}  // namespace bimanual_skills::vision
