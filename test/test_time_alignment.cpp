// Time alignment by gradient descent (thesis Fig. 6.9) against independent references: the gradient against finite
// differences, a known warp recovered, a one-coefficient warp against a brute-force grid, warped copies aligned back
// onto the curve they came from.
#include "bimanual_skills/learning/time_alignment.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace bl = bimanual_skills::learning;

namespace {

/// An S in the plane, the shape the guided runs share: x from 0 to 1, y = −0.15 sin(2π x) with a slow start.
Eigen::RowVector2d sShape(double s) {
  const double x = s * s * (3.0 - 2.0 * s);
  return {x, -0.15 * std::sin(2.0 * M_PI * x)};
}

Eigen::MatrixXd sampled(int rows) {
  Eigen::MatrixXd c(rows, 2);
  for (int i = 0; i < rows; ++i) c.row(i) = sShape(static_cast<double>(i) / (rows - 1));
  return c;
}

/// The curve c with c(u(s)) = r(s) for the S: c(v) = r(u⁻¹(v)), u inverted on a dense table.
Eigen::MatrixXd warpedS(const bl::TimeWarp& u, int rows) {
  const int table = 20001;
  Eigen::VectorXd us(table);
  for (int i = 0; i < table; ++i) us[i] = u(static_cast<double>(i) / (table - 1));
  Eigen::MatrixXd c(rows, 2);
  int j = 0;
  for (int i = 0; i < rows; ++i) {
    const double v = static_cast<double>(i) / (rows - 1);
    while (j < table - 2 && us[j + 1] < v) ++j;
    const double f = std::clamp((v - us[j]) / (us[j + 1] - us[j]), 0.0, 1.0);
    c.row(i) = sShape((j + f) / (table - 1));
  }
  return c;
}

bl::TimeWarp warpOf(std::initializer_list<double> a) {
  bl::TimeWarp w;
  w.a.resize(static_cast<Eigen::Index>(a.size()));
  int k = 0;
  for (double x : a) w.a[k++] = x;
  return w;
}

}  // namespace

TEST(TimeWarp, FixesTheEndsAndItsSlopeIsTheDerivative) {
  const bl::TimeWarp w = warpOf({0.1, -0.05, 0.02});
  EXPECT_DOUBLE_EQ(w(0.0), 0.0);
  EXPECT_NEAR(w(1.0), 1.0, 1e-15);
  EXPECT_DOUBLE_EQ(bl::TimeWarp{}(0.37), 0.37);
  for (double s : {0.05, 0.3, 0.71, 0.96}) {
    const double h = 1e-6;
    EXPECT_NEAR(w.slope(s), (w(s + h) - w(s - h)) / (2.0 * h), 1e-8) << "s " << s;
  }
  EXPECT_GT(w.minSlope(), 0.0);
  EXPECT_LT(warpOf({0.5}).minSlope(), 0.0);  // 1 − 0.5 π < 0: not monotone
}

TEST(TimeAlignment, TheCostIsZeroForTheCurveItselfAndItsGradientMatchesFiniteDifferences) {
  const Eigen::MatrixXd r = sampled(2001);
  EXPECT_NEAR(bl::alignmentCost(r, r, bl::TimeWarp{}, 300), 0.0, 1e-20);
  const Eigen::MatrixXd c = warpedS(warpOf({0.06, 0.03}), 2001);
  for (const bl::TimeWarp& w : {warpOf({-0.05, 0.0, 0.01}), warpOf({0.0, 0.0, 0.0}), warpOf({0.04, -0.02, 0.03})}) {
    const Eigen::VectorXd g = bl::alignmentGradient(c, r, w, 300);
    for (int k = 0; k < 3; ++k) {
      // A step of 1e-6 stays between the fine curve's samples for almost every phase: the cost is smooth there.
      const double h = 1e-6;
      bl::TimeWarp plus = w, minus = w;
      plus.a[k] += h;
      minus.a[k] -= h;
      const double fd = (bl::alignmentCost(c, r, plus, 300) - bl::alignmentCost(c, r, minus, 300)) / (2.0 * h);
      EXPECT_NEAR(g[k], fd, 2e-3 * std::max(1e-3, std::abs(fd))) << "a_" << k + 1 << " at " << w.a.transpose();
    }
  }
}

TEST(TimeAlignment, RecoversAKnownWarp) {
  const bl::TimeWarp truth = warpOf({0.08, -0.04, 0.02, 0.0});
  const Eigen::MatrixXd r = sampled(1001), c = warpedS(truth, 1001);
  bl::TimeAlignmentOptions o;
  o.iterations = 2000;
  o.samples = 400;
  const double before = bl::alignmentCost(c, r, bl::TimeWarp{}, o.samples);
  const bl::TimeWarp found = bl::alignToReference(c, r, o);
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(found.a[k], truth.a[k], 3e-3) << "a_" << k + 1;
  const double after = bl::alignmentCost(c, r, found, o.samples);
  EXPECT_LT(after, 1e-3 * before) << "before " << before << " after " << after;
  EXPECT_GE(found.minSlope(), o.min_slope);
}

TEST(TimeAlignment, OneCoefficientMatchesABruteForceGrid) {
  const Eigen::MatrixXd r = sampled(1001), c = warpedS(warpOf({-0.11}), 1001);
  bl::TimeAlignmentOptions o;
  o.harmonics = 1;
  o.iterations = 1000;
  o.samples = 200;
  double best = std::numeric_limits<double>::infinity(), best_a = 0.0;
  for (double a = -0.25; a <= 0.25; a += 0.0005) {
    const double cost = bl::alignmentCost(c, r, warpOf({a}), o.samples);
    if (cost < best) best = cost, best_a = a;
  }
  const bl::TimeWarp found = bl::alignToReference(c, r, o);
  EXPECT_NEAR(found.a[0], best_a, 1e-3);
  EXPECT_LE(bl::alignmentCost(c, r, found, o.samples), best + 1e-9);
}

TEST(TimeAlignment, WarpedCopiesAlignBackOntoTheirCurve) {
  // Five copies of the S at warps whose coefficients average to zero: aligned to each other, their mean is the S.
  const std::vector<bl::TimeWarp> truths = {warpOf({0.08, 0.02}), warpOf({-0.06, 0.03}), warpOf({0.03, -0.04}),
                                            warpOf({-0.09, -0.02}), warpOf({0.04, 0.01})};
  std::vector<Eigen::MatrixXd> curves;
  for (const bl::TimeWarp& t : truths) curves.push_back(warpedS(t, 801));
  bl::TimeAlignmentOptions o;
  o.harmonics = 3;
  o.iterations = 500;
  o.passes = 8;
  const bl::TimeAlignment result = bl::alignCurves(curves, o);
  ASSERT_EQ(result.aligned.size(), curves.size());
  EXPECT_LT(result.cost_after, 0.01 * result.cost_before)
      << "before " << result.cost_before << " after " << result.cost_after;
  const Eigen::MatrixXd truth = sampled(o.samples);
  EXPECT_LT((result.mean - truth).rowwise().norm().maxCoeff(), 5e-3);
  // The linear-time mean is blurred: far from the S.
  Eigen::MatrixXd linear = Eigen::MatrixXd::Zero(o.samples, 2);
  for (const Eigen::MatrixXd& c : curves) linear += bl::warpCurve(c, bl::TimeWarp{}, o.samples);
  linear /= static_cast<double>(curves.size());
  EXPECT_GT((linear - truth).rowwise().norm().maxCoeff(), 0.01);
  for (const bl::TimeWarp& w : result.warps) EXPECT_GE(w.minSlope(), o.min_slope);
}

TEST(TimeAlignment, KeepsTheWarpMonotoneWhereTheBestFitIsNot) {
  // The reference dwells at its start for half its time: the best warp would stop; it keeps du/ds >= min_slope.
  Eigen::MatrixXd r(201, 2), c = sampled(201);
  for (int i = 0; i < 201; ++i) r.row(i) = sShape(std::max(0.0, (i / 200.0 - 0.5) * 2.0));
  bl::TimeAlignmentOptions o;
  o.min_slope = 0.3;
  const bl::TimeWarp found = bl::alignToReference(c, r, o);
  EXPECT_GE(found.minSlope(), 0.3);
  EXPECT_LT(bl::alignmentCost(c, r, found, o.samples), bl::alignmentCost(c, r, bl::TimeWarp{}, o.samples));
}

TEST(RewardWeights, NormalisedExponentialOfTheRewardsRange) {
  const Eigen::VectorXd w = bl::rewardWeights(Eigen::Vector3d(-1.0, -3.0, -2.0), 10.0);
  EXPECT_NEAR(w.sum(), 1.0, 1e-15);
  EXPECT_NEAR(w[0] / w[1], std::exp(10.0), 1e-6 * std::exp(10.0));
  EXPECT_NEAR(w[2] / w[1], std::exp(5.0), 1e-9 * std::exp(5.0));
  EXPECT_TRUE(bl::rewardWeights(Eigen::Vector2d(-1.0, -1.0), 10.0).isApproxToConstant(0.5));
  EXPECT_TRUE(bl::rewardWeights(Eigen::Vector3d(1.0, 2.0, 3.0), 0.0).isApproxToConstant(1.0 / 3.0));
  EXPECT_THROW(bl::rewardWeights(Eigen::VectorXd(), 10.0), std::invalid_argument);
  EXPECT_THROW(bl::rewardWeights(Eigen::Vector2d(0.0, std::nan("")), 10.0), std::invalid_argument);
  EXPECT_THROW(bl::rewardWeights(Eigen::Vector2d(0.0, 1.0), -1.0), std::invalid_argument);
}

TEST(TimeAlignment, BadInputIsAClearError) {
  const Eigen::MatrixXd r = sampled(50);
  bl::TimeAlignmentOptions o;
  EXPECT_THROW(bl::alignToReference(r, Eigen::MatrixXd::Zero(50, 3), o), std::invalid_argument);
  EXPECT_THROW(bl::alignToReference(Eigen::MatrixXd::Zero(1, 2), r, o), std::invalid_argument);
  Eigen::MatrixXd bad = r;
  bad(7, 1) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(bl::alignToReference(bad, r, o), std::invalid_argument);
  EXPECT_THROW(bl::alignCurves({}, o), std::invalid_argument);
  EXPECT_THROW(bl::alignCurves({r, Eigen::MatrixXd::Zero(50, 1)}, o), std::invalid_argument);
  EXPECT_THROW(bl::alignToReference(r, r, o, warpOf({0.5, 0, 0, 0})), std::invalid_argument);  // not monotone
  EXPECT_THROW(bl::alignToReference(r, r, o, warpOf({0.01})), std::invalid_argument);          // wrong size
  o.harmonics = 0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.min_slope = 0.0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.samples = 1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
}
