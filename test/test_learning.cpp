// Incremental locally weighted regression: a noisy 1-D function, and the thesis' use (Sec. 2.3.1): learning
// n(q, q̇) = u − M(q_d) q̈_d along a task on a simulated WAM, then controlling with it instead of C q̇ + G + F_f.
// Spearman's rank correlation against scipy and its bootstrap interval.
#include "test_support.hpp"

#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/control/disturbance_observer.hpp"
#include "bimanual_skills/learning/locally_weighted_regression.hpp"
#include "bimanual_skills/learning/rank_correlation.hpp"
#include "bimanual_skills/learning/student_t.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace bc = bimanual_skills::control;
namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
namespace bl = bimanual_skills::learning;
using bimanual_skills::test_support::hystereticFriction;
using bimanual_skills::test_support::lowGains;
using bimanual_skills::test_support::wamWithRotors;
using bimanual_skills::testing::NoAllocGuard;

TEST(LocallyWeightedRegression, FitsANoisyFunction) {
  bl::LwrParameters parameters;
  parameters.width = Eigen::VectorXd::Constant(1, 0.2);
  bl::LocallyWeightedRegression lwr(1, 1, parameters);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::normal_distribution<double> noise(0.0, 0.05);
  for (int k = 0; k < 5000; ++k) {
    const double x = u(rng);
    ASSERT_EQ(lwr.update(Eigen::VectorXd::Constant(1, x), Eigen::VectorXd::Constant(1, std::sin(2 * x) + noise(rng))),
              bl::LwrStatus::Success);
  }
  double squared = 0.0;
  int count = 0;
  Eigen::VectorXd y(1);
  for (double x = -1.9; x <= 1.9; x += 0.01) {
    ASSERT_EQ(lwr.predict(Eigen::VectorXd::Constant(1, x), y), bl::LwrStatus::Success);
    squared += std::pow(y[0] - std::sin(2 * x), 2);
    ++count;
  }
  EXPECT_LE(std::sqrt(squared / count), 0.03);
  EXPECT_LE(lwr.fields(), 100);
  EXPECT_NE(lwr.predict(Eigen::VectorXd::Constant(1, 10.0), y), bl::LwrStatus::Success);  // nothing learned there
  EXPECT_NE(lwr.update(Eigen::VectorXd::Constant(1, std::nan("")), Eigen::VectorXd::Zero(1)), bl::LwrStatus::Success);
  bl::LwrParameters bad = parameters;
  bad.forgetting = 1.5;
  EXPECT_THROW(bl::LocallyWeightedRegression(1, 1, bad), std::invalid_argument);
}

TEST(LocallyWeightedRegression, LearnedDynamicsTrackLikeTheAnalyticModel) {
  const bk::ChainModel model = wamWithRotors();
  const bk::ChainModel inertial = model.withGravity(Eigen::Vector3d::Zero());
  const bd::FrictionModel friction = hystereticFriction();
  const bc::ComputedTorqueGains gains = lowGains();
  bc::ComputedTorqueController controller(model, friction, gains);
  bc::DisturbanceObserver observer(model, friction, bc::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0));
  std::vector<double> force_learned;
  bl::LwrParameters parameters;
  parameters.width =
      (Eigen::VectorXd(14) << Eigen::VectorXd::Constant(7, 0.1), Eigen::VectorXd::Constant(7, 0.15)).finished();
  parameters.max_fields = 2000;
  bl::LocallyWeightedRegression lwr(14, 7, parameters);
  const double T = 0.002, dt = 0.0002, w = 2.0 * M_PI * 0.25;
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.2, 0.6, -0.3, 1.7, 0.3, -0.4, 0.2).finished();
  Eigen::VectorXd q = q0, qd = Eigen::VectorXd::Zero(7), qdd = Eigen::VectorXd::Zero(7), u(7), f(7);
  Eigen::VectorXd q_des(7), qd_des(7), qdd_des(7), inertia_torque(7), x(14);
  bd::DynamicsData plant(model), data(inertial);
  bd::FrictionState plant_friction(friction);
  double max_error_analytic = 0.0, max_error_learned = 0.0;
  for (int k = 0; k < 8000; ++k) {  // 16 s: learn during 4–12 s (two periods), control with it during 12–16 s
    const double t = k * T;
    for (int j = 0; j < 7; ++j) {
      q_des[j] = q0[j] + 0.3 * std::sin(w * t);
      qd_des[j] = 0.3 * w * std::cos(w * t);
      qdd_des[j] = -0.3 * w * w * std::sin(w * t);
    }
    if (k == 6000) {
      controller.setLearnedModel(bc::LearnedDynamics(lwr));
      observer.setLearnedModel(bc::LearnedDynamics(lwr));
    }
    ASSERT_NE(controller.update(q, qd, q_des, qd_des, qdd_des, u), bc::ControlStatus::InvalidInput);
    const Eigen::VectorXd desired_sign = qdd_des.unaryExpr([](double a) { return (a > 0) - (a < 0) + 0.0; });
    ASSERT_EQ(observer.update(q, qd, u, desired_sign), bc::ObserverStatus::Success);
    if (t >= 12.5) force_learned.push_back(observer.wrench().head<3>().norm());
    const double error = (q_des - q).cwiseAbs().maxCoeff();
    if (t >= 8.0 && t < 12.0) max_error_analytic = std::max(max_error_analytic, error);
    if (t >= 12.0) max_error_learned = std::max(max_error_learned, error);
    if (t >= 4.0 && t < 12.0) {
      // Training target n = u − M(q_d) q̈_d at the measured state (thesis Sec. 2.3.1).
      ASSERT_EQ(bd::inverseDynamics(inertial, data, q_des, Eigen::VectorXd::Zero(7), qdd_des, inertia_torque),
                bd::DynamicsStatus::Success);
      x << q, qd;
      ASSERT_EQ(lwr.update(x, u - inertia_torque), bl::LwrStatus::Success);
    }
    for (int s = 0; s < 10; ++s) {
      const Eigen::VectorXd sign = qdd.unaryExpr([](double a) { return (a > 0) - (a < 0) + 0.0; });
      ASSERT_EQ(bd::frictionTorques(friction, plant_friction, q, qd, sign, f), bd::DynamicsStatus::Success);
      ASSERT_EQ(bd::forwardDynamics(model, plant, q, qd, u - f, qdd), bd::DynamicsStatus::Success);
      qd += dt * qdd;
      q += dt * qd;
    }
  }
  std::printf("tracking: analytic model %.4f rad, learned model %.4f rad (%d fields)\n", max_error_analytic,
              max_error_learned, lwr.fields());
  // Measured 0.0091 rad with the analytic model, 0.0134 rad with the learned one.
  EXPECT_LE(max_error_analytic, 0.015);
  EXPECT_LE(max_error_learned, 2.0 * max_error_analytic);
  // Without contact, the observer on the learned model sees no external force.
  std::nth_element(force_learned.begin(), force_learned.begin() + static_cast<long>(force_learned.size() / 2),
                   force_learned.end());
  const double median_force = force_learned[force_learned.size() / 2];
  std::printf("observer on the learned model, no contact: median |f| = %.3f N\n", median_force);
  EXPECT_LE(median_force, 0.5);
  // Update and prediction are real-time safe.
  Eigen::VectorXd y(7);
  x << q, qd;
  NoAllocGuard guard;
  EXPECT_EQ(lwr.update(x, u), bl::LwrStatus::Success);
  EXPECT_EQ(lwr.predict(x, y), bl::LwrStatus::Success);
  EXPECT_NE(controller.update(q, qd, q_des, qd_des, qdd_des, u), bc::ControlStatus::InvalidInput);
}

// Student's t quantiles against tables (and scipy.stats.t.ppf(0.975, ν) beyond them), and the interval they give.
TEST(StudentT, QuantilesAndIntervals) {
  EXPECT_DOUBLE_EQ(bl::studentT975(1), 12.706);
  EXPECT_DOUBLE_EQ(bl::studentT975(2), 4.303);
  EXPECT_DOUBLE_EQ(bl::studentT975(4), 2.776);
  EXPECT_DOUBLE_EQ(bl::studentT975(9), 2.262);
  EXPECT_NEAR(bl::studentT975(40), 2.021075, 1e-4);
  EXPECT_NEAR(bl::studentT975(60), 2.000298, 1e-4);
  EXPECT_NEAR(bl::studentT975(120), 1.979930, 1e-4);
  EXPECT_NEAR(bl::studentT975(100000), 1.959985, 1e-4);
  EXPECT_THROW(bl::studentT975(0), std::invalid_argument);
  // 1, 2, 3, 4, 5: mean 3, s = √2.5, t_{0.975,4} = 2.776: half-width 2.776 · √2.5 / √5 = 1.96292.
  const bl::MeanInterval m = bl::meanInterval95({1, 2, 3, 4, 5});
  EXPECT_EQ(m.n, 5);
  EXPECT_DOUBLE_EQ(m.mean, 3.0);
  EXPECT_NEAR(m.std_dev, std::sqrt(2.5), 1e-12);
  EXPECT_NEAR(m.half_width, 2.776 * std::sqrt(2.5 / 5.0), 1e-12);
  EXPECT_EQ(bl::meanInterval95({7.0}).half_width, 0.0);
  EXPECT_THROW(bl::meanInterval95({}), std::invalid_argument);
}

// Ranks with ties and Spearman's ρ against scipy.stats.rankdata and spearmanr; the bootstrap interval holds the
// estimate, is seeded, and narrows with more pairs.
TEST(RankCorrelation, SpearmanAgainstScipyAndItsBootstrap) {
  EXPECT_EQ(bl::ranks({3, 1, 4, 1, 5, 9, 2, 6}), (std::vector<double>{4, 1.5, 5, 1.5, 6, 8, 3, 7}));
  EXPECT_NEAR(bl::spearman({1, 2, 3, 4, 5}, {5, 6, 7, 8, 7}), 0.8207826816681233, 1e-14);
  EXPECT_NEAR(bl::spearman({0.3, 0.1, 0.4, 0.1, 0.5, 0.9, 0.2, 0.6}, {2, 7, 1, 8, 2, 8, 1, 8}), 0.19885368120992467,
              1e-14);
  EXPECT_DOUBLE_EQ(bl::spearman({1, 2, 3}, {-1, -5, -9}), -1.0);
  EXPECT_DOUBLE_EQ(bl::spearman({1, 2, 3}, {4, 4, 4}), 0.0);
  EXPECT_THROW(bl::spearman({1, 2}, {1, 2, 3}), std::invalid_argument);
  EXPECT_THROW(bl::spearman({1}, {1}), std::invalid_argument);
  EXPECT_THROW(bl::spearman({1, NAN}, {1, 2}), std::invalid_argument);

  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> x, y;
  for (int i = 0; i < 200; ++i) {
    x.push_back(noise(rng));
    y.push_back(x.back() + noise(rng));
  }
  const bl::BootstrapInterval all = bl::bootstrapSpearman(x, y, 1000, 7);
  EXPECT_EQ(all.estimate, bl::spearman(x, y));
  EXPECT_LT(all.low, all.estimate);
  EXPECT_GT(all.high, all.estimate);
  const bl::BootstrapInterval again = bl::bootstrapSpearman(x, y, 1000, 7);
  EXPECT_EQ(again.low, all.low);
  EXPECT_EQ(again.high, all.high);
  const bl::BootstrapInterval few = bl::bootstrapSpearman(std::vector<double>(x.begin(), x.begin() + 20),
                                                          std::vector<double>(y.begin(), y.begin() + 20), 1000, 7);
  EXPECT_GT(few.high - few.low, all.high - all.low);
  EXPECT_THROW(bl::bootstrapSpearman(x, y, 10, 7), std::invalid_argument);
}
