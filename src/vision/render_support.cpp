#include "render_support.hpp"

#include <cmath>

namespace bimanual_skills::vision {

// Newton's method on Φ(x) = erfc(−x/√2)/2 for each quantile of the upper half, mirrored.
std::vector<float> normalQuantiles() {
  constexpr int kCount = 1 << 16;
  std::vector<double> x(kCount);
  const double sqrt2 = std::sqrt(2.0), inv_sqrt_2pi = 1.0 / std::sqrt(2.0 * std::acos(-1.0));
  for (int i = kCount / 2; i < kCount; ++i) {
    const double p = (i + 0.5) / kCount;
    double q = 0.0;
    for (int iteration = 0; iteration < 100; ++iteration) {
      const double step = (0.5 * std::erfc(-q / sqrt2) - p) / (inv_sqrt_2pi * std::exp(-0.5 * q * q));
      q -= step;
      if (std::abs(step) < 1e-13) break;
    }
    x[i] = q;
    x[kCount - 1 - i] = -q;
  }
  double second_moment = 0.0;
  for (const double q : x) second_moment += q * q / kCount;
  std::vector<float> quantiles(kCount);
  for (int i = 0; i < kCount; ++i) quantiles[i] = static_cast<float>(x[i] / std::sqrt(second_moment));
  return quantiles;
}
}  // namespace bimanual_skills::vision
