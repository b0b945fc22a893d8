/// \file
/// A top-down orthographic camera over the table, the geometry of every image of the vision module.
///
/// Frames: the camera looks straight down the world's −z axis from the height `height` [m]. Its optical frame has
/// x_c = world x, y_c = world −y, z_c = world −z (right-handed), so image columns grow with world x and image rows
/// with world −y: the image is the table seen from above with world +y up. A world point p maps to the continuous
/// image coordinates (pixel (u, v) covers [u, u+1) × [v, v+1), its centre is (u + ½, v + ½))
///   X = (p_x − c_x) / s + W/2,   Y = −(p_y − c_y) / s + H/2,   depth = h − p_z  (distance along the optical axis),
/// with c the world xy of the image centre, s the pixel size [m] and h the camera height.
///
/// Why orthographic: the reward measures the cloth's shape on the table. Under orthographic projection a pixel is
/// the same patch of table wherever it is and whatever the cloth's height, so the pixel count is an area, a
/// rectangle stays a rectangle anywhere in the image and the depth gradient is a true slope (m/m). A pinhole over
/// the table (the thesis' rooftop Kinect, ~1.5 m above a 0.6 m cloth, ±11° off axis at the cloth's edge) would add
/// perspective of a few per cent that the reward would have to undo.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::vision {

struct TopDownCamera {
  int columns = 320;                                   ///< Image width W [pixels], ≥ 8.
  int rows = 240;                                      ///< Image height H [pixels], ≥ 8.
  double pixel_size = 0.003125;                        ///< Side s of a pixel's square on the table [m], > 0.
  Eigen::Vector2d centre = Eigen::Vector2d(0.5, 0.0);  ///< World xy under the image centre [m].
  double height = 1.5;                                 ///< Camera plane's world z [m].

  /// A camera of `columns` × `rows` pixels whose image covers `field_width` [m] of table across.
  static TopDownCamera covering(int columns, int rows, double field_width, const Eigen::Vector2d& centre,
                                double height);

  /// Continuous image coordinates (X, Y) of a world point (no bounds check).
  Eigen::Vector2d project(const Eigen::Vector3d& p) const noexcept {
    return {(p.x() - centre.x()) / pixel_size + 0.5 * columns, -(p.y() - centre.y()) / pixel_size + 0.5 * rows};
  }
  /// World xy of the centre of pixel (u, v).
  Eigen::Vector2d pixelCentre(int u, int v) const noexcept {
    return {centre.x() + (u + 0.5 - 0.5 * columns) * pixel_size, centre.y() - (v + 0.5 - 0.5 * rows) * pixel_size};
  }
  /// Table area one pixel covers [m²].
  double pixelArea() const noexcept { return pixel_size * pixel_size; }

  /// Throws std::invalid_argument naming `where` and the member that is out of range.
  void validate(const char* where) const;
};

}  // namespace bimanual_skills::vision
