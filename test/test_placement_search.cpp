// The placement searches of thesis Sec. 3.2.4 on a known objective: a smooth bump whose maximum (1 at (0.5, -0.3))
// lies inside the bounds. The genetic algorithm spends exactly generations x population evaluations and repeats
// itself for a seed; NLopt's algorithms stay within their budget and repeat themselves for a seed; all approach the
// maximum (ESCH the least: 0.86 in 200 evaluations).
#include "bimanual_skills/workspace/placement_search.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace bw = bimanual_skills::workspace;

namespace {

double bump(const Eigen::VectorXd& x) {
  return std::exp(-4.0 * (std::pow(x[0] - 0.5, 2) + std::pow(x[1] + 0.3, 2)));
}

bw::SearchBounds square() {
  bw::SearchBounds b;
  b.lower = Eigen::Vector2d(-1.2, -1.2);
  b.upper = Eigen::Vector2d(1.2, 1.2);
  return b;
}

void expectMonotone(const bw::SearchResult& r) {
  ASSERT_EQ(static_cast<int>(r.best_after.size()), r.evaluations);
  for (std::size_t k = 1; k < r.best_after.size(); ++k) EXPECT_GE(r.best_after[k], r.best_after[k - 1]);
  EXPECT_EQ(r.best_after.back(), r.quality);
  EXPECT_DOUBLE_EQ(bump(r.best), r.quality);
}

}  // namespace

TEST(PlacementSearch, GeneticAlgorithmFindsTheBumpAndRepeatsItself) {
  bw::GeneticSettings settings;
  settings.seed = 5;
  const bw::SearchResult a = bw::geneticSearch(square(), bump, settings);
  EXPECT_EQ(a.evaluations, 200);
  expectMonotone(a);
  EXPECT_GT(a.quality, 0.95);
  EXPECT_TRUE((a.best.array() >= square().lower.array()).all() && (a.best.array() <= square().upper.array()).all());
  const bw::SearchResult b = bw::geneticSearch(square(), bump, settings);
  EXPECT_EQ(a.best, b.best);
  EXPECT_EQ(a.best_after, b.best_after);
  // The evaluation that first reached the best: the curve reaches it there and not before.
  const int reach = a.evaluationsToReach(a.quality);
  ASSERT_GE(reach, 1);
  ASSERT_LE(reach, a.evaluations);
  EXPECT_EQ(a.best_after[static_cast<std::size_t>(reach - 1)], a.quality);
  if (reach > 1) {
    EXPECT_LT(a.best_after[static_cast<std::size_t>(reach - 2)], a.quality);
  }
  EXPECT_EQ(a.evaluationsToReach(2.0), -1);
  settings.population = 5;
  EXPECT_THROW(bw::geneticSearch(square(), bump, settings), std::invalid_argument);
}

TEST(PlacementSearch, NloptAlgorithmsStayWithinTheirBudget) {
  for (const std::string& name : bw::nloptPlacementAlgorithms()) {
    const bw::SearchResult r = bw::nloptSearch(name, square(), bump, 200, 3);
    EXPECT_LE(r.evaluations, 200) << name;
    EXPECT_GT(r.evaluations, 10) << name;
    expectMonotone(r);
    EXPECT_GT(r.quality, 0.8) << name;
    const bw::SearchResult again = bw::nloptSearch(name, square(), bump, 200, 3);
    EXPECT_EQ(again.best_after, r.best_after) << name << ": seeded";
  }
  EXPECT_THROW(bw::nloptSearch("COBYLA", square(), bump, 100, 1), std::invalid_argument);
  bw::SearchBounds inverted = square();
  inverted.lower[0] = 2.0;
  EXPECT_THROW(bw::nloptSearch("ESCH", inverted, bump, 100, 1), std::invalid_argument);
}
