#include "bimanual_skills/learning/rank_correlation.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

namespace bimanual_skills::learning {

namespace {

void check(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size() || x.size() < 2) {
    throw std::invalid_argument("spearman: needs two lists of the same length >= 2");
  }
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) throw std::invalid_argument("spearman: non-finite value");
  }
}

double pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  const double ma = std::accumulate(a.begin(), a.end(), 0.0) / n, mb = std::accumulate(b.begin(), b.end(), 0.0) / n;
  double sab = 0.0, saa = 0.0, sbb = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return saa > 0.0 && sbb > 0.0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

}  // namespace

std::vector<double> ranks(const std::vector<double>& values) {
  std::vector<std::size_t> order(values.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return values[a] < values[b]; });
  std::vector<double> out(values.size());
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i;
    while (j + 1 < order.size() && values[order[j + 1]] == values[order[i]]) ++j;
    const double rank = 0.5 * static_cast<double>(i + j) + 1.0;  // the mean of ranks i + 1 … j + 1
    for (std::size_t k = i; k <= j; ++k) out[order[k]] = rank;
    i = j + 1;
  }
  return out;
}

double spearman(const std::vector<double>& x, const std::vector<double>& y) {
  check(x, y);
  return pearson(ranks(x), ranks(y));
}

BootstrapInterval bootstrapSpearman(const std::vector<double>& x, const std::vector<double>& y, int resamples,
                                    std::uint32_t seed) {
  check(x, y);
  if (resamples < 100) throw std::invalid_argument("bootstrapSpearman: needs at least 100 resamples");
  BootstrapInterval out;
  out.estimate = spearman(x, y);
  out.resamples = resamples;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, x.size() - 1);
  std::vector<double> estimates, xs(x.size()), ys(y.size());
  estimates.reserve(static_cast<std::size_t>(resamples));
  for (int r = 0; r < resamples; ++r) {
    for (std::size_t i = 0; i < x.size(); ++i) {
      const std::size_t k = pick(rng);
      xs[i] = x[k];
      ys[i] = y[k];
    }
    estimates.push_back(pearson(ranks(xs), ranks(ys)));
  }
  std::sort(estimates.begin(), estimates.end());
  const auto quantile = [&](double p) {
    const double at = p * static_cast<double>(estimates.size() - 1);
    const auto below = static_cast<std::size_t>(std::floor(at));
    const std::size_t above = std::min(below + 1, estimates.size() - 1);
    return estimates[below] + (at - static_cast<double>(below)) * (estimates[above] - estimates[below]);
  };
  out.low = quantile(0.025);
  out.high = quantile(0.975);
  return out;
}

}  // namespace bimanual_skills::learning
