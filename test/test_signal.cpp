#include "bimanual_skills/signal/acceleration_sign.hpp"
#include "bimanual_skills/signal/fir_filter.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <limits>
#include <random>

namespace bs = bimanual_skills::signal;
using bimanual_skills::testing::NoAllocGuard;

namespace {

double sgn(double x) {
  return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : 0.0;
}

}  // namespace

TEST(Fir, LinearPhaseUnitDcGainAndStopBand) {
  const Eigen::VectorXd h = bs::designLowPassFir(31, 40.0, 500.0);
  EXPECT_NEAR(h.sum(), 1.0, 1e-12);
  EXPECT_LE((h - h.reverse()).cwiseAbs().maxCoeff(), 1e-15);  // symmetric: linear phase
  const auto gain = [&](double f) {
    std::complex<double> H = 0.0;
    for (int k = 0; k < h.size(); ++k) H += h[k] * std::exp(std::complex<double>(0.0, -2.0 * M_PI * f / 500.0 * k));
    return std::abs(H);
  };
  EXPECT_GT(gain(10.0), 0.95);
  EXPECT_LT(gain(200.0), 1e-3);  // > 60 dB down well inside the stop band
  // Filtering: a constant passes unchanged; a slow sine comes out delayed by (N − 1)/2 samples.
  bs::FirFilter filter(h, 2);
  for (int k = 0; k < 100; ++k) ASSERT_EQ(filter.filter(Eigen::Vector2d(1.5, -2.0)), bs::SignalStatus::Success);
  EXPECT_LE((filter.output() - Eigen::Vector2d(1.5, -2.0)).cwiseAbs().maxCoeff(), 1e-12);
  bs::FirFilter sine(h, 1);
  double out = 0.0;
  const int n = 400;
  for (int k = 0; k <= n; ++k) {
    ASSERT_EQ(sine.filter(Eigen::VectorXd::Constant(1, std::sin(2 * M_PI * 2.0 * k / 500.0))),
              bs::SignalStatus::Success);
    out = sine.output()[0];
  }
  EXPECT_NEAR(out, std::sin(2 * M_PI * 2.0 * (n - sine.delay()) / 500.0), 1e-3);
  EXPECT_THROW(bs::designLowPassFir(30, 40.0, 500.0), std::invalid_argument);
  EXPECT_THROW(bs::designLowPassFir(31, 300.0, 500.0), std::invalid_argument);
}

TEST(AccelerationSign, IgnoresNoiseAroundZero) {
  // q̇ = 0.5 sin(2π 0.5 t) + noise at 500 Hz for 4 s: q̈ changes sign 4 times; the raw finite difference changes
  // sign hundreds of times, the filtered sign exactly 4 times, with 2 and with 5 mrad/s of noise.
  constexpr double period = 0.002;
  for (double sigma : {0.002, 0.005}) {
    bs::AccelerationSign filter(1, period);
    std::mt19937 rng(3);
    std::normal_distribution<double> noise(0.0, sigma);
    int raw_flips = 0, filtered_flips = 0;
    double previous_raw = 0.0, previous_sign = 0.0, previous_qd = 0.0;
    for (int k = 0; k < 2000; ++k) {
      const double qd = 0.5 * std::sin(2 * M_PI * 0.5 * k * period) + noise(rng);
      const double raw = sgn(qd - previous_qd);
      if (k > 1 && raw != previous_raw) ++raw_flips;
      previous_raw = raw;
      previous_qd = qd;
      ASSERT_EQ(filter.update(Eigen::VectorXd::Constant(1, qd)), bs::SignalStatus::Success);
      const double s = filter.sign()[0];
      if (previous_sign != 0.0 && s != previous_sign) ++filtered_flips;
      previous_sign = s;
    }
    EXPECT_GT(raw_flips, 100) << sigma;
    EXPECT_EQ(filtered_flips, 4) << sigma;
  }
}

TEST(Signal, BadSamplesAreRejectedAndChangeNothing) {
  EXPECT_THROW(bs::AccelerationSign(2, 0.0), std::invalid_argument);
  bs::FirFilter filter(bs::designLowPassFir(15, 40.0, 500.0), 2);
  ASSERT_EQ(filter.filter(Eigen::Vector2d(1.0, 2.0)), bs::SignalStatus::Success);
  const Eigen::Vector2d before = filter.output();
  EXPECT_EQ(filter.filter(Eigen::Vector3d::Zero()), bs::SignalStatus::WrongSize);
  EXPECT_EQ(filter.filter(Eigen::Vector2d(0.0, std::numeric_limits<double>::quiet_NaN())), bs::SignalStatus::NotFinite);
  EXPECT_EQ(filter.output(), before);
  ASSERT_EQ(filter.filter(Eigen::Vector2d(1.0, 2.0)), bs::SignalStatus::Success);
  EXPECT_EQ(filter.output(), before);  // the rejected samples did not enter the history
  bs::AccelerationSign sign(2, 0.002);
  EXPECT_EQ(sign.update(Eigen::Vector3d::Zero()), bs::SignalStatus::WrongSize);
  EXPECT_EQ(sign.update(Eigen::Vector2d(std::numeric_limits<double>::infinity(), 0.0)), bs::SignalStatus::NotFinite);
  EXPECT_EQ(std::string(bs::toString(bs::SignalStatus::NotFinite)), "a sample contains NaN or Inf");
}

TEST(Signal, FilteringDoesNotAllocateAtProductionSizes) {
  for (const int channels : {7, 14}) {
    bs::FirFilter filter(bs::designLowPassFir(31, 40.0, 500.0), channels);
    bs::AccelerationSign sign(channels, 0.002);
    Eigen::VectorXd qd = Eigen::VectorXd::LinSpaced(channels, -1.0, 1.0);
    NoAllocGuard guard;
    for (int k = 0; k < 50; ++k) {
      qd *= 0.99;
      EXPECT_EQ(filter.filter(qd), bs::SignalStatus::Success);
      EXPECT_EQ(sign.update(filter.output()), bs::SignalStatus::Success);
    }
  }
}

TEST(Signal, SignWithDeadBand) {
  const Eigen::VectorXd values = (Eigen::VectorXd(6) << -2.0, -1e-3, -1e-4, 0.0, 5e-4, 0.3).finished();
  const Eigen::VectorXd banded = (Eigen::VectorXd(6) << -1, 0, 0, 0, 0, 1).finished();
  const Eigen::VectorXd exact = (Eigen::VectorXd(6) << -1, -1, -1, 0, 1, 1).finished();
  Eigen::VectorXd sign(6);
  {
    NoAllocGuard guard;
    bs::signWithDeadBand(values, 1e-3, sign);
  }
  EXPECT_EQ(sign, banded);
  bs::signWithDeadBand(values, 0.0, sign);
  EXPECT_EQ(sign, exact);
}
