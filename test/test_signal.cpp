#include "bimanual_skills/signal/acceleration_sign.hpp"
#include "bimanual_skills/signal/fir_filter.hpp"
#include "bimanual_skills/signal/target_tracker.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <Eigen/QR>

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

// ---- the tracked target (constant-velocity Kalman filter) ----

namespace {

using Update = bs::TargetTracker::Update;

/// A target at p0 + v t seen at 30 Hz with noise σ per axis, a tenth of the frames dropped (seeded).
struct Track {
  Eigen::Vector3d p0{0.4, -0.1, 0.2}, v{0.2, 0.05, -0.03};
  double sigma = 0.005;
  std::mt19937 rng{11};
  Eigen::Vector3d at(double t) const { return p0 + v * t; }
  Eigen::Vector3d seen(double t) {
    std::normal_distribution<double> noise(0.0, sigma);
    return at(t) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  }
  Eigen::Matrix3d r() const { return Eigen::Matrix3d::Identity() * sigma * sigma; }
};

}  // namespace

// Against the truth: the filtered position is closer to the target than the camera's, the velocity found, and the
// filter consistent (its normalised innovations average χ²₃'s mean, 3); updates and predictions allocate nothing.
TEST(TargetTracker, FollowsAConstantVelocityTargetBetterThanItsMeasurements) {
  bs::TargetTrackerConfig config;
  config.acceleration_noise = 1e-4;
  bs::TargetTracker tracker(config);
  Track track;
  std::bernoulli_distribution dropped(0.1);
  bool first = true;
  double raw = 0.0, filtered = 0.0, nis = 0.0;
  int n = 0, accepted = 0;
  Eigen::Vector3d p, v;
  Eigen::Matrix3d c;
  for (int k = 0; k < 300; ++k) {
    const double t = k / 30.0;
    if (dropped(track.rng)) continue;
    const Eigen::Vector3d z = track.seen(t);
    Update u;
    {
      NoAllocGuard guard;
      u = tracker.update(t, z, track.r());
      ASSERT_TRUE(tracker.predict(t, p, v, c));
    }
    EXPECT_EQ(u, first ? Update::Started : Update::Accepted) << "frame " << k;
    first = false;
    if (t < 1.0) continue;  // the first second: the velocity is being found
    raw += (z - track.at(t)).squaredNorm();
    filtered += (p - track.at(t)).squaredNorm();
    nis += tracker.lastInnovation();
    ++n;
    accepted += u == Update::Accepted;
  }
  raw = std::sqrt(raw / n);
  filtered = std::sqrt(filtered / n);
  std::printf("over %d frames: camera %.2f mm rms, filtered %.2f mm rms; mean NIS %.2f (3 expected)\n", n, 1e3 * raw,
              1e3 * filtered, nis / n);
  EXPECT_LT(filtered, 0.5 * raw);
  EXPECT_LT((v - track.v).norm(), 0.01);
  EXPECT_NEAR(nis / n, 3.0, 0.6);
  EXPECT_EQ(accepted, n);
  // Predicted ahead (a control loop between frames): the target's own extrapolation, the uncertainty growing.
  Eigen::Vector3d p_ahead, v_ahead;
  Eigen::Matrix3d c_ahead;
  ASSERT_TRUE(tracker.predict(10.2, p_ahead, v_ahead, c_ahead));
  EXPECT_LT((p_ahead - track.at(10.2)).norm(), 0.005);
  EXPECT_GT(c_ahead.trace(), c.trace());
}

// An independent reference: with no process noise and a flat velocity prior, the Kalman filter's last estimate is the
// least-squares line through all the measurements (a brute-force fit here).
TEST(TargetTracker, WithoutProcessNoiseItIsTheLeastSquaresLine) {
  bs::TargetTrackerConfig config;
  config.acceleration_noise = 1e-12;
  config.initial_speed = 1e4;
  config.lost_after = 10.0;
  bs::TargetTracker tracker(config);
  Track track;
  std::vector<double> times;
  std::vector<Eigen::Vector3d> seen;
  for (int k = 0; k < 60; ++k) {
    const double t = 0.05 * k + (k % 3) * 0.01;  // irregular frames
    times.push_back(t);
    seen.push_back(track.seen(t));
    ASSERT_NE(tracker.update(t, seen.back(), track.r()), Update::Invalid);
  }
  Eigen::MatrixXd a(static_cast<Eigen::Index>(times.size()), 2);
  for (std::size_t i = 0; i < times.size(); ++i) a.row(static_cast<Eigen::Index>(i)) << 1.0, times[i] - times.back();
  Eigen::Vector3d p, v;
  Eigen::Matrix3d c;
  ASSERT_TRUE(tracker.predict(times.back(), p, v, c));
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::VectorXd b(static_cast<Eigen::Index>(seen.size()));
    for (std::size_t i = 0; i < seen.size(); ++i) b[static_cast<Eigen::Index>(i)] = seen[i][axis];
    const Eigen::Vector2d line = a.colPivHouseholderQr().solve(b);  // position at the last time, velocity
    EXPECT_NEAR(p[axis], line[0], 1e-6) << "axis " << axis;
    EXPECT_NEAR(v[axis], line[1], 1e-5) << "axis " << axis;
  }
}

// A jump is not followed; a target that stays away, or unseen for lost_after, is lost and the next frame starts anew.
// Bad input is refused without touching the track.
TEST(TargetTracker, RejectsJumpsLosesTheTargetAndRefusesBadInput) {
  bs::TargetTrackerConfig config;
  config.reject_limit = 3;
  bs::TargetTracker tracker(config);
  Track track;
  double t = 0.0;
  for (int k = 0; k < 60; ++k, t += 1.0 / 30.0) ASSERT_NE(tracker.update(t, track.seen(t), track.r()), Update::Invalid);
  // One outlier half a metre off: rejected, the track goes on.
  EXPECT_EQ(tracker.update(t, track.at(t) + Eigen::Vector3d(0.5, 0.0, 0.0), track.r()), Update::Rejected);
  EXPECT_GT(tracker.lastInnovation(), config.gate);
  t += 1.0 / 30.0;
  EXPECT_EQ(tracker.update(t, track.seen(t), track.r()), Update::Accepted);
  // The object moved (three frames in a row elsewhere): lost, then a new track where it is.
  const Eigen::Vector3d elsewhere(0.0, 0.5, 0.3);
  for (int k = 0; k < 3; ++k) {
    t += 1.0 / 30.0;
    EXPECT_EQ(tracker.update(t, elsewhere, track.r()), Update::Rejected);
  }
  EXPECT_FALSE(tracker.tracking(t));
  t += 1.0 / 30.0;
  EXPECT_EQ(tracker.update(t, elsewhere, track.r()), Update::Started);
  Eigen::Vector3d p, v;
  Eigen::Matrix3d c;
  ASSERT_TRUE(tracker.predict(t, p, v, c));
  EXPECT_EQ(p, elsewhere);
  // Unseen for longer than lost_after: lost.
  EXPECT_TRUE(tracker.tracking(t + 0.4));
  EXPECT_FALSE(tracker.tracking(t + 0.6));
  EXPECT_FALSE(tracker.predict(t + 0.6, p, v, c));
  // Bad input: NaN, a covariance that is not positive definite or not symmetric, a duplicate or reordered frame.
  const double last = t;
  EXPECT_EQ(tracker.update(t + 0.01, Eigen::Vector3d(std::nan(""), 0.0, 0.0), track.r()), Update::Invalid);
  EXPECT_EQ(tracker.update(t + 0.01, elsewhere, -track.r()), Update::Invalid);
  Eigen::Matrix3d skew = track.r();
  skew(0, 1) = 1e-6;
  EXPECT_EQ(tracker.update(t + 0.01, elsewhere, skew), Update::Invalid);
  EXPECT_EQ(tracker.update(last, elsewhere, track.r()), Update::Invalid);
  EXPECT_EQ(tracker.update(last - 0.1, elsewhere, track.r()), Update::Invalid);
  EXPECT_EQ(tracker.lastAccepted(), last);
  EXPECT_EQ(tracker.update(t + 0.02, elsewhere, track.r()), Update::Accepted);
  bs::TargetTrackerConfig bad;
  bad.gate = -1.0;
  EXPECT_THROW(bs::TargetTracker{bad}, std::invalid_argument);
  tracker.reset();
  EXPECT_FALSE(tracker.tracking(t));
}
