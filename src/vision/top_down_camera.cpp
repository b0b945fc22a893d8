#include "bimanual_skills/vision/top_down_camera.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::vision {

namespace {

[[noreturn]] void fail(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}

}  // namespace

TopDownCamera TopDownCamera::covering(int columns, int rows, double field_width, const Eigen::Vector2d& centre,
                                      double height) {
  TopDownCamera camera;
  camera.columns = columns;
  camera.rows = rows;
  camera.pixel_size = columns > 0 ? field_width / columns : 0.0;
  camera.centre = centre;
  camera.height = height;
  camera.validate("TopDownCamera::covering");
  return camera;
}

void TopDownCamera::validate(const char* where) const {
  if (columns < 8 || rows < 8) fail(where, "camera columns and rows must be at least 8");
  if (columns > 8192 || rows > 8192) fail(where, "camera columns and rows must be at most 8192");
  if (!std::isfinite(pixel_size) || pixel_size <= 0.0) fail(where, "camera pixel_size must be finite and > 0");
  if (!centre.allFinite()) fail(where, "camera centre must be finite");
  if (!std::isfinite(height)) fail(where, "camera height must be finite");
}

}  // namespace bimanual_skills::vision
