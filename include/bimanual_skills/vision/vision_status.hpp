/// \file
/// Outcome of the vision module's calls (rendering, reward terms): bad input is reported here, never by a crash.
#pragma once

namespace bimanual_skills::vision {

enum class VisionStatus {
  Ok,
  EmptyMesh,        ///< No vertices or no triangles: only the table and floor were rendered.
  NonFiniteVertex,  ///< A vertex coordinate is NaN or infinite: only the table and floor were rendered.
  BadTriangle,      ///< A triangle index is negative or not below the vertex count: only the background was rendered.
  WrongImageSize,   ///< An image given to a reward term does not have the size and type the evaluator was built for.
  NoCloth,          ///< No cloth pixel in the image: the reward terms take their worst values.
  BadCameraPose,    ///< A camera pose that is not finite or not a rigid transform.
};

/// Name of a status ("Ok", "EmptyMesh", ...), for logs outside the real-time path.
const char* toString(VisionStatus status) noexcept;

}  // namespace bimanual_skills::vision
