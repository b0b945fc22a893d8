// Friction models (thesis 2.13, 2.14, 4.16) against their equations written out here, the coupled-pair switching
// with its dead band, the filtered acceleration sign, bad input and allocation-free evaluation.
#include "bimanual_skills/dynamics/friction_model.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>

namespace bd = bimanual_skills::dynamics;
using bd::FrictionModelType;
using bimanual_skills::testing::NoAllocGuard;

namespace {

double sgn(double x) {
  return (x > 0) - (x < 0);
}

bd::JointFriction randomJoint(FrictionModelType type, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  bd::JointFriction joint;
  joint.type = type;
  Eigen::VectorXd b(bd::linearParameterCount(type));
  for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = u(rng);
  joint.b = std::move(b);  // a move, not a resize: GCC 12 misreports Eigen's realloc path (use-after-free)
  joint.s = 5.0 + 10.0 * std::abs(u(rng));
  joint.z = u(rng);
  joint.h = 0.5 + std::abs(u(rng));
  return joint;
}

}  // namespace

TEST(FrictionModel, EachModelIsItsEquation) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int trial = 0; trial < 200; ++trial) {
    const double q = u(rng), qd = u(rng), sigma = sgn(u(rng));
    const bd::JointFriction viscous = randomJoint(FrictionModelType::Viscous, rng);
    EXPECT_DOUBLE_EQ(bd::frictionTorque(viscous, q, qd, sigma), viscous.b[0] * qd);
    const bd::JointFriction initial = randomJoint(FrictionModelType::Initial, rng);
    EXPECT_NEAR(bd::frictionTorque(initial, q, qd, sigma), initial.b[0] * std::atan(initial.s * qd) + initial.b[1] * qd,
                1e-14);  // (2.13)
    const bd::JointFriction basic = randomJoint(FrictionModelType::Basic, rng);
    EXPECT_NEAR(bd::frictionTorque(basic, q, qd, sigma),
                basic.b[0] * std::atan(basic.s * qd + basic.z * sigma) + basic.b[1] * qd, 1e-14);  // (2.14)
    const bd::JointFriction adv = randomJoint(FrictionModelType::Advanced, rng);
    double expected = adv.b[0] * q + adv.b[1] * qd + adv.b[2] * std::atan(adv.s * qd + adv.z * sigma);  // (4.16)
    for (int j = 1; j <= 5; ++j) {
      const double f = 4.0 * std::sin((2 * j - 1) * adv.h * q) / (M_PI * (2 * j - 1));
      expected += 0.5 * (1 + sgn(qd)) * adv.b[2 + j] * f + 0.5 * (1 - sgn(qd)) * adv.b[7 + j] * f;
    }
    EXPECT_NEAR(bd::frictionTorque(adv, q, qd, sigma), expected, 1e-13);
  }
}

TEST(FrictionModel, HysteresisSeparatesAccelerationAndDeceleration) {
  bd::JointFriction basic;
  basic.type = FrictionModelType::Basic;
  basic.b = Eigen::Vector2d(1.5, 0.3);
  basic.s = 10.0;
  basic.z = 0.8;
  // Same velocity, opposite acceleration signs: the loop has a width; at q̇ = 0 the friction is ±b1 atan(z).
  EXPECT_GT(bd::frictionTorque(basic, 0.0, 0.05, 1.0), bd::frictionTorque(basic, 0.0, 0.05, -1.0));
  EXPECT_NEAR(bd::frictionTorque(basic, 0.0, 0.0, 1.0), 1.5 * std::atan(0.8), 1e-15);
  EXPECT_NEAR(bd::frictionTorque(basic, 0.0, 0.0, -1.0), -1.5 * std::atan(0.8), 1e-15);
}

TEST(FrictionModel, CoupledPairSwitchesWithADeadBand) {
  std::mt19937 rng(2);
  bd::FrictionModel model;
  for (int i = 0; i < 3; ++i) model.joints.push_back(randomJoint(FrictionModelType::Basic, rng));
  bd::CoupledPair pair;
  pair.first = 1;
  pair.second = 2;
  pair.reduced_first = randomJoint(FrictionModelType::Basic, rng);
  pair.reduced_second = randomJoint(FrictionModelType::Basic, rng);
  pair.epsilon = 0.1;
  model.pairs.push_back(pair);
  model.validate();
  bd::FrictionState state(model);
  const Eigen::Vector3d q(0.1, 0.2, 0.3), sigma(1.0, 1.0, -1.0);
  Eigen::Vector3d tau;
  const auto step = [&](double v1, double v2) {
    const Eigen::Vector3d qd(0.4, v1, v2);
    EXPECT_EQ(bd::frictionTorques(model, state, q, qd, sigma, tau), bd::DynamicsStatus::Success);
    return std::pair<bool, bool>{state.reduced[1] != 0, state.reduced[2] != 0};
  };
  EXPECT_EQ(step(0.5, 0.5), (std::pair<bool, bool>{false, false}));  // within ε: both keep A
  EXPECT_EQ(step(0.2, 0.5), (std::pair<bool, bool>{true, false}));   // joint 2 slower by more than ε: B
  EXPECT_EQ(step(0.45, 0.5), (std::pair<bool, bool>{true, false}));  // back inside the band: keeps B
  EXPECT_EQ(step(0.7, 0.5), (std::pair<bool, bool>{false, true}));   // now joint 3 is the slower one
  EXPECT_NEAR(tau[1], bd::frictionTorque(model.joints[1], 0.2, 0.7, 1.0), 1e-15);
  EXPECT_NEAR(tau[2], bd::frictionTorque(pair.reduced_second, 0.3, 0.5, -1.0), 1e-15);
  EXPECT_NEAR(tau[0], bd::frictionTorque(model.joints[0], 0.1, 0.4, 1.0), 1e-15);
}

TEST(FrictionModel, BadInputIsRejected) {
  bd::JointFriction joint;
  joint.type = FrictionModelType::Advanced;
  EXPECT_THROW(joint.validate(), std::invalid_argument);  // 1 coefficient for a 13-coefficient model
  bd::FrictionModel model;
  model.joints.assign(2, bd::JointFriction());
  model.pairs.push_back(bd::CoupledPair{0, 5, {}, {}, 0.1});
  EXPECT_THROW(model.validate(), std::invalid_argument);
  model.pairs.clear();
  bd::FrictionState state(model);
  Eigen::Vector2d tau(7.0, 7.0);
  EXPECT_NE(bd::frictionTorques(model, state, Eigen::Vector2d(0, std::nan("")), Eigen::Vector2d::Zero(),
                                Eigen::Vector2d::Zero(), tau),
            bd::DynamicsStatus::Success);
  EXPECT_NE(
      bd::frictionTorques(model, state, Eigen::Vector3d::Zero(), Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), tau),
      bd::DynamicsStatus::Success);
  EXPECT_EQ(tau, Eigen::Vector2d(7.0, 7.0));
  bd::FrictionModelType type;
  EXPECT_TRUE(bd::parseFrictionModelType("advanced", type));
  EXPECT_EQ(type, FrictionModelType::Advanced);
  EXPECT_FALSE(bd::parseFrictionModelType("dahl", type));
}

TEST(FrictionModel, EvaluationDoesNotAllocate) {
  std::mt19937 rng(4);
  bd::FrictionModel model;
  for (auto type : {FrictionModelType::Viscous, FrictionModelType::Initial, FrictionModelType::Basic,
                    FrictionModelType::Advanced, FrictionModelType::Advanced}) {
    model.joints.push_back(randomJoint(type, rng));
  }
  model.pairs.push_back(bd::CoupledPair{3, 4, randomJoint(FrictionModelType::Advanced, rng),
                                        randomJoint(FrictionModelType::Advanced, rng), 0.05});
  bd::FrictionState state(model);
  const Eigen::VectorXd q = Eigen::VectorXd::Constant(5, 0.3);
  Eigen::VectorXd qd = Eigen::VectorXd::Constant(5, -0.2);
  Eigen::VectorXd sigma = Eigen::VectorXd::Ones(5);
  Eigen::VectorXd tau(5);
  NoAllocGuard guard;
  for (int k = 0; k < 10; ++k) {
    qd[3] += 0.01 * k;
    sigma[k % 5] = -sigma[k % 5];
    EXPECT_EQ(bd::frictionTorques(model, state, q, qd, sigma, tau), bd::DynamicsStatus::Success);
  }
}
