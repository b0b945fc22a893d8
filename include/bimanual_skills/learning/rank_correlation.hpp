/// \file
/// Spearman's rank correlation and its bootstrap interval: how well a proxy (a camera reward) orders what it stands
/// for (the fold quality), over items that are independent of each other (house style item 18: rollouts of one run
/// are not; resample runs, not rollouts, there).
#pragma once

#include <cstdint>
#include <vector>

namespace bimanual_skills::learning {

/// Ranks 1 … n of `values`, ties sharing the mean of their ranks.
std::vector<double> ranks(const std::vector<double>& values);

/// Spearman's ρ: Pearson's correlation of the ranks of x and y (ties averaged); 0 when either has no spread.
/// \throws std::invalid_argument for sizes that differ, fewer than 2 values or non-finite values.
double spearman(const std::vector<double>& x, const std::vector<double>& y);

struct BootstrapInterval {
  double estimate = 0.0;  ///< On all the items.
  double low = 0.0;       ///< 2.5 % quantile of the resampled estimates.
  double high = 0.0;      ///< 97.5 % quantile.
  int resamples = 0;
};

/// The percentile bootstrap 95 % interval of Spearman's ρ over the n pairs (x_i, y_i): `resamples` draws of n pairs
/// with replacement from a std::mt19937 seeded by `seed`. \throws std::invalid_argument as spearman(), or for
/// resamples < 100.
BootstrapInterval bootstrapSpearman(const std::vector<double>& x, const std::vector<double>& y, int resamples,
                                    std::uint32_t seed);

}  // namespace bimanual_skills::learning
