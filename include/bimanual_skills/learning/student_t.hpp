/// \file
/// Student-t intervals for results over a few independent runs (house style item 18: never z = 1.96 on 3–20 runs).
#pragma once

#include <vector>

namespace bimanual_skills::learning {

/// The two-sided 95 % quantile t_{0.975, ν} of Student's t distribution with ν ≥ 1 degrees of freedom: tabulated
/// for ν ≤ 30, the Cornish–Fisher expansion in 1/ν beyond (error below 1e-4), 1.959964 as ν → ∞.
/// \throws std::invalid_argument for ν < 1.
double studentT975(int degrees_of_freedom);

/// Mean of n values and the half-width of its 95 % interval, t_{0.975, n−1} s / √n (s the sample standard
/// deviation; 0 for a single value).
struct MeanInterval {
  int n = 0;
  double mean = 0.0;
  double std_dev = 0.0;
  double half_width = 0.0;
};

/// \throws std::invalid_argument for no values.
MeanInterval meanInterval95(const std::vector<double>& values);

}  // namespace bimanual_skills::learning
