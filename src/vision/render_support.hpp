/// \file
/// What the renderers share (private to the vision module): the noise draws (SplitMix64 words seeded per image from
/// the caller's generator, and the 2^16 equiprobable quantiles of N(0, 1) that 16 of their bits pick) and shading.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace bimanual_skills::vision {

/// SplitMix64 (Steele, Lea & Flood 2014): one 64-bit draw per call in about a nanosecond, seeded per render from the
/// caller's generator; its four 16-bit quarters pick four normal quantiles.
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t operator()() noexcept {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
};

/// The 2^16 equiprobable quantiles Φ⁻¹((i + ½) / 2^16) of the standard normal distribution, scaled to unit variance:
/// a draw is one quantile picked by 16 uniform bits.
std::vector<float> normalQuantiles();

/// Colour in BGR bytes of an RGB colour in [0, 1] times a shading factor.
inline cv::Vec3b shade(const Eigen::Vector3d& rgb, double factor) noexcept {
  const auto byte = [factor](double c) {
    return static_cast<unsigned char>(std::clamp(std::lround(255.0 * c * factor), 0L, 255L));
  };
  return {byte(rgb.z()), byte(rgb.y()), byte(rgb.x())};
}

}  // namespace bimanual_skills::vision
