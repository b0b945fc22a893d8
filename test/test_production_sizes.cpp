// Every real-time call of the library at the sizes users run: the WAM chain (7 DoF), 14 DoF (both arms' worth of
// joints), 20–30 kernels per DoF. Each call runs under NoAllocGuard, which fails the test on any heap allocation.
#include "test_support.hpp"

#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/control/disturbance_observer.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/clik.hpp"
#include "bimanual_skills/learning/locally_weighted_regression.hpp"
#include "bimanual_skills/primitives/cartesian_dmp.hpp"
#include "bimanual_skills/primitives/dmp.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/primitives/dr_promp.hpp"
#include "bimanual_skills/primitives/dr_promp_controller.hpp"
#include "bimanual_skills/primitives/promp.hpp"
#include "bimanual_skills/primitives/promp_controller.hpp"
#include "bimanual_skills/signal/acceleration_sign.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace bc = bimanual_skills::control;
namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
namespace bl = bimanual_skills::learning;
namespace bp = bimanual_skills::primitives;
namespace bs = bimanual_skills::signal;
using bimanual_skills::test_support::lowGains;
using bimanual_skills::test_support::randomWithinLimits;
using bimanual_skills::test_support::twoWamsInSeries;
using bimanual_skills::test_support::wamWithRotors;
using bimanual_skills::testing::NoAllocGuard;

namespace {

/// The WAM and the 14-joint chain.
std::vector<bk::ChainModel> chains() {
  return {wamWithRotors(), twoWamsInSeries()};
}

/// A basic hysteretic friction model on every joint, with the WAM's coupled pairs in each arm.
bd::FrictionModel friction(int n) {
  bd::FrictionModel model;
  for (int j = 0; j < n; ++j) {
    bd::JointFriction f;
    f.type = bd::FrictionModelType::Advanced;
    f.b = Eigen::VectorXd::LinSpaced(13, 0.1, 0.5);
    f.s = 20.0;
    f.z = 0.5;
    model.joints.push_back(f);
  }
  for (int arm = 0; arm < n / 7; ++arm) {
    for (auto [a, b] : {std::pair{1, 2}, std::pair{4, 5}}) {
      model.pairs.push_back(bd::CoupledPair{7 * arm + a, 7 * arm + b, model.joints[1], model.joints[2], 0.05});
    }
  }
  return model;
}

bc::ComputedTorqueGains gains(int n) {
  const bc::ComputedTorqueGains seven = lowGains();
  bc::ComputedTorqueGains out;
  out.kp = seven.kp.replicate(n / 7, 1);
  out.kv = seven.kv.replicate(n / 7, 1);
  return out;
}

/// A smooth demonstration of `dofs` joints, `samples` rows.
Eigen::MatrixXd demonstration(int dofs, int samples, double phase = 0.0) {
  Eigen::MatrixXd y(samples, dofs);
  for (int r = 0; r < samples; ++r) {
    const double s = r / double(samples - 1);
    for (int j = 0; j < dofs; ++j) y(r, j) = 0.1 * j + 0.3 * std::sin(M_PI * s * (1 + j % 3) + phase) * s;
  }
  return y;
}

}  // namespace

TEST(ProductionSizes, KinematicsDoNotAllocate) {
  for (const bk::ChainModel& model : chains()) {
    bk::ChainData data(model);
    std::mt19937 rng(1);
    const Eigen::VectorXd q = randomWithinLimits(model, rng);
    bk::Matrix6Xd J(6, model.nq());
    NoAllocGuard guard;
    EXPECT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
    EXPECT_EQ(bk::computeJacobian(model, data, q, bk::JacobianFrame::Tip), bk::KinematicsStatus::Success);
    EXPECT_EQ(bk::frameJacobian(model, data, model.nq() / 2, bk::JacobianFrame::Base, J),
              bk::KinematicsStatus::Success);
    EXPECT_GT(bk::manipulability(data), 0.0);
    EXPECT_GT(bk::conditionNumber(data), 1.0);
  }
}

TEST(ProductionSizes, ClikStepAndSolveDoNotAllocate) {
  for (const bk::ChainModel& model : chains()) {
    std::mt19937 rng(2);
    const Eigen::VectorXd q0 = randomWithinLimits(model, rng);
    Eigen::VectorXd q1 = q0;
    q1.array() += 0.2;
    const Eigen::Isometry3d target = bimanual_skills::test_support::tipPose(model, q1);
    for (const std::string& name : bk::methodNames()) {
      bk::ClikParameters parameters;
      ASSERT_TRUE(bk::parseMethodName(name, parameters.inverse, parameters.limits)) << name;
      parameters.max_iterations = 30;
      bk::ClikData data(model, parameters);
      Eigen::VectorXd q = q0;
      NoAllocGuard guard;
      EXPECT_EQ(bk::step(model, parameters, data, q, target), bk::IkStatus::StepComputed) << name;
      EXPECT_NE(bk::solve(model, parameters, data, q, target).status, bk::IkStatus::NumericalFailure) << name;
    }
  }
}

TEST(ProductionSizes, DynamicsAndFrictionDoNotAllocate) {
  for (const bk::ChainModel& model : chains()) {
    const int n = model.nq();
    bd::DynamicsData data(model);
    const bd::FrictionModel f = friction(n);
    bd::FrictionState state(f);
    std::mt19937 rng(3);
    const Eigen::VectorXd q = randomWithinLimits(model, rng);
    const Eigen::VectorXd qd = Eigen::VectorXd::LinSpaced(n, -1.0, 1.0);
    const Eigen::VectorXd sign = Eigen::VectorXd::Ones(n);
    Eigen::VectorXd tau(n), qdd(n);
    const bd::Payload payload{1.5, Eigen::Vector3d(0.0, 0.0, 0.1)};
    NoAllocGuard guard;
    EXPECT_EQ(bd::inverseDynamics(model, data, q, qd, qd, tau, payload), bd::DynamicsStatus::Success);
    EXPECT_EQ(bd::massMatrix(model, data, q, payload), bd::DynamicsStatus::Success);
    EXPECT_EQ(bd::coriolisTorques(model, data, q, qd, tau, payload), bd::DynamicsStatus::Success);
    EXPECT_EQ(bd::gravityTorques(model, data, q, tau, payload), bd::DynamicsStatus::Success);
    EXPECT_EQ(bd::forwardDynamics(model, data, q, qd, tau, qdd, payload), bd::DynamicsStatus::Success);
    EXPECT_EQ(bd::frictionTorques(f, state, q, qd, sign, tau), bd::DynamicsStatus::Success);
  }
}

TEST(ProductionSizes, ControllerObserverAndLearnedModelDoNotAllocate) {
  for (const bk::ChainModel& model : chains()) {
    const int n = model.nq();
    const bd::FrictionModel f = friction(n);
    bc::ComputedTorqueController controller(model, f, gains(n));
    bc::DisturbanceObserver observer(model, f, bc::ObserverGains::diagonal(n, 10.0, 0.0, 100.0, 0.0, 10.0));
    bs::AccelerationSign sign(n, 0.002);
    bl::LwrParameters lwr_parameters;
    lwr_parameters.width = Eigen::VectorXd::Constant(2 * n, 0.5);
    bl::LocallyWeightedRegression lwr(2 * n, n, lwr_parameters);
    std::mt19937 rng(4);
    const Eigen::VectorXd q = randomWithinLimits(model, rng);
    Eigen::VectorXd qd = Eigen::VectorXd::LinSpaced(n, -0.5, 0.5), u(n), x(2 * n);
    x << q, qd;
    NoAllocGuard guard;
    for (const bool learned : {false, true}) {
      if (learned) {
        controller.setLearnedModel(bc::LearnedDynamics(lwr));
        observer.setLearnedModel(bc::LearnedDynamics(lwr));
      }
      for (int k = 0; k < 5; ++k) {
        qd *= 0.99;
        EXPECT_EQ(sign.update(qd), bs::SignalStatus::Success);
        EXPECT_NE(controller.update(q, qd, q, qd, qd, u), bc::ControlStatus::InvalidInput);
        EXPECT_EQ(observer.update(q, qd, u, sign.sign()), bc::ObserverStatus::Success);
        EXPECT_EQ(lwr.update(x, u), bl::LwrStatus::Success);
        EXPECT_EQ(lwr.predict(x, u), bl::LwrStatus::Success);
      }
    }
  }
}

TEST(ProductionSizes, DmpStepsDoNotAllocate) {
  for (const int dofs : {7, 14}) {
    for (const int kernels : {20, 30}) {
      bp::DmpParameters parameters;
      parameters.kernels = kernels;
      const bp::Dmp dmp = bp::Dmp::fit(parameters, demonstration(dofs, 500), 0.002);
      bp::DmpState state = dmp.initialState();
      NoAllocGuard guard;
      for (int k = 0; k < 10; ++k) EXPECT_EQ(dmp.step(state, 0.002), bp::DmpStatus::Success);
    }
  }
  for (const auto encoding : {bp::OrientationEncoding::UnitQuaternion, bp::OrientationEncoding::QuaternionVector}) {
    bp::DmpParameters parameters;
    parameters.kernels = 30;
    std::vector<bp::Pose> poses;
    for (int k = 0; k < 500; ++k) {
      const double s = k / 499.0;
      poses.push_back(
          {Eigen::Vector3d(0.5 * s, 0.1, 0.3), Eigen::Quaterniond(Eigen::AngleAxisd(s, Eigen::Vector3d::UnitZ()))});
    }
    const bp::CartesianDmp dmp = bp::CartesianDmp::fit(parameters, encoding, poses, 0.002);
    bp::CartesianDmpState state = dmp.initialState();
    const Eigen::VectorXd forcing = Eigen::VectorXd::Constant(12, 0.5);  // a coordinated DMP's, as the fold task
    NoAllocGuard guard;
    for (int k = 0; k < 10; ++k) EXPECT_EQ(dmp.step(state, 0.002), bp::DmpStatus::Success);
    for (int k = 0; k < 10; ++k) EXPECT_EQ(dmp.step(state, 0.002, forcing.segment<6>(6)), bp::DmpStatus::Success);
  }
}

TEST(ProductionSizes, ProMpEvaluationAndControlDoNotAllocate) {
  for (const int dofs : {7, 14}) {
    for (const int kernels : {20, 30}) {
      bp::ProMpParameters parameters;
      parameters.kernels = kernels;
      std::vector<Eigen::MatrixXd> demos;
      for (int d = 0; d < 6; ++d) demos.push_back(demonstration(dofs, 200, 0.1 * d));
      const bp::ProMp promp = bp::ProMp::fit(parameters, demos, 2.0);
      bp::ProMpData data(promp);
      Eigen::VectorXd position(dofs), velocity(dofs);
      Eigen::MatrixXd covariance(dofs, dofs), state_covariance(2 * dofs, 2 * dofs);
      {
        NoAllocGuard guard;
        for (const double z : {0.0, 0.3, 1.0}) {
          EXPECT_EQ(promp.blockBasis(data, z), bp::ProMpStatus::Success);
          EXPECT_EQ(promp.mean(data, z, position, velocity), bp::ProMpStatus::Success);
          EXPECT_EQ(promp.covariance(data, z, covariance), bp::ProMpStatus::Success);
          EXPECT_EQ(promp.stateCovariance(data, z, state_covariance), bp::ProMpStatus::Success);
        }
      }
      if (kernels != 20) continue;  // the controller's offline schedule is the slow part: one size suffices
      const bp::ProMpController controller(promp, {bp::LinearisedSystem::doubleIntegrator(dofs)}, 0.01);
      Eigen::VectorXd state = Eigen::VectorXd::Zero(2 * dofs), u(dofs);
      std::mt19937 rng(5);
      NoAllocGuard guard;
      EXPECT_EQ(controller.command(3, state, u), bp::ProMpControlStatus::Success);
      EXPECT_EQ(controller.command(3, state, rng, u), bp::ProMpControlStatus::Success);
    }
  }
}

TEST(ProductionSizes, DrDmpStepsDoNotAllocate) {
  constexpr int dofs = 14, kernels = 20, latent = 4;
  for (const int matrices : {1, 3}) {
    bp::DrDmpParameters parameters;
    parameters.dmp.kernels = kernels;
    parameters.matrices = matrices;
    const bp::DrDmpFit fit = bp::DrDmp::fit(parameters, {demonstration(dofs, 500)}, 0.002, latent);
    bp::DrDmpState state = fit.dmp.initialState();
    state.exploration.setConstant(0.1);
    NoAllocGuard guard;
    for (int k = 0; k < 10; ++k) EXPECT_EQ(fit.dmp.step(state, 0.002), bp::DmpStatus::Success);
  }
}

TEST(ProductionSizes, DrProMpEvaluationAndLatentControlDoNotAllocate) {
  constexpr int dofs = 14, kernels = 20, latent = 4;
  bp::DrProMpParameters parameters;
  parameters.promp.kernels = kernels;
  parameters.latent_dims = latent;
  parameters.em.max_iterations = 5;
  std::vector<Eigen::MatrixXd> demos;
  for (int d = 0; d < 6; ++d) demos.push_back(demonstration(dofs, 200, 0.1 * d));
  const bp::DrProMp promp = bp::DrProMp::fit(parameters, demos, 2.0);
  bp::DrProMpData data(promp);
  Eigen::VectorXd position(dofs), velocity(dofs);
  Eigen::MatrixXd state_covariance(2 * dofs, 2 * dofs);
  {
    NoAllocGuard guard;
    for (const double z : {0.0, 0.3, 1.0}) {
      EXPECT_EQ(promp.mean(data, z, position, velocity), bp::ProMpStatus::Success);
      EXPECT_EQ(promp.stateCovariance(data, z, state_covariance), bp::ProMpStatus::Success);
    }
  }
  const bp::DrProMpController controller(promp, {bp::LinearisedSystem::doubleIntegrator(dofs)}, 0.01, 0.01);
  bp::DrProMpControllerData scratch(controller);
  Eigen::VectorXd state = Eigen::VectorXd::Zero(2 * dofs), u(dofs);
  std::mt19937 rng(6);
  NoAllocGuard guard;
  EXPECT_EQ(controller.command(scratch, 3, state, u), bp::ProMpControlStatus::Success);
  EXPECT_EQ(controller.command(scratch, 3, state, rng, u), bp::ProMpControlStatus::Success);
}
