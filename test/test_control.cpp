// Computed-torque control and the disturbance observer in closed loop with a simulated WAM (rigid-body model with
// rotor inertias, hysteretic "true" friction driven by the true acceleration, a constant tool wrench), plus the FIR
// design, gain validation and allocation-free updates.
#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/control/disturbance_observer.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <kdl/chainexternalwrenchestimator.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace bc = bimanual_skills::control;
namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
using bimanual_skills::testing::NoAllocGuard;

using bimanual_skills::test_support::hystereticFriction;
using bimanual_skills::test_support::kWamUrdf;
using bimanual_skills::test_support::lowGains;
using bimanual_skills::test_support::wamWithRotors;

namespace {

struct LoopResult {
  double max_tracking_error_free = 0.0;                        ///< t ∈ [0.5, 2) s, no wrench
  double force_error_median_early = 0.0;                       ///< t ∈ [2.2, 2.5) s, 0.2 s after the wrench step
  double force_error_median = 0.0, moment_error_median = 0.0;  ///< t ∈ [2.5, 5) s
  double kdl_force_error_median = 0.0;    ///< KDL's momentum observer on the same run, t ∈ [2.5, 5) s
  double ours_vs_kdl_force_median = 0.0;  ///< |ours − KDL|, t ∈ [2.5, 5) s
};

/// KDL's chain of the same arm (without rotor inertias: its dynamics-parameter solver rejects joint inertias).
KDL::Chain kdlWam() {
  KDL::Tree tree;
  KDL::Chain chain;
  if (!kdl_parser::treeFromFile(kWamUrdf, tree) || !tree.getChain("wam_base", "wam_tool", chain)) {
    throw std::runtime_error("KDL cannot load the WAM");
  }
  return chain;
}

/// 5 s at 500 Hz (plant at 5 kHz, semi-implicit Euler): sinusoidal reference on every joint, the wrench F applied
/// to the tool from t = 2 s, velocity measurements with 1 mrad/s noise.
LoopResult runLoop(bool friction_compensation) {
  const bk::ChainModel model = wamWithRotors();
  const bd::FrictionModel friction = hystereticFriction();
  bc::ComputedTorqueController controller(model, friction, lowGains());
  controller.setFrictionCompensation(friction_compensation);
  bc::DisturbanceObserver observer(model, friction, bc::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0));
  // KDL's momentum observer (Haddadin et al.) as a cross-check: it models neither friction nor rotor inertia, so it
  // is given u − F̂_f − J_m q̈_d.
  // The chain must outlive the estimator: its solvers keep references to the chain they were given.
  const KDL::Chain kdl_chain = kdlWam();
  KDL::ChainExternalWrenchEstimator kdl(kdl_chain, KDL::Vector(0, 0, -9.81), 500.0, 30.0, 0.5);
  bd::FrictionState kdl_friction_state(friction);
  KDL::JntArray kdl_q(7), kdl_qd(7), kdl_tau(7);
  KDL::Wrench kdl_wrench;
  std::vector<double> kdl_force, difference;
  const double T = 0.002, dt = 0.0002;
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.2, 0.6, -0.3, 1.7, 0.3, -0.4, 0.2).finished();
  Eigen::VectorXd q = q0, qd = Eigen::VectorXd::Zero(7), qdd = Eigen::VectorXd::Zero(7), u(7), friction_torque(7);
  Eigen::VectorXd q_des(7), qd_des(7), qdd_des(7), sign(7), tau_ext(7);
  bd::DynamicsData plant(model);
  bd::FrictionState plant_friction(friction);
  bk::ChainData kinematics(model);
  Eigen::Matrix<double, 6, 1> F;
  F << 5.0, -3.0, -10.0, 0.5, 0.0, 0.2;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.001);
  LoopResult result;
  std::vector<double> early, force, moment;
  for (int k = 0; k < 2500; ++k) {
    const double t = k * T;
    const double w = 2.0 * M_PI * 0.25;
    for (int j = 0; j < 7; ++j) {
      q_des[j] = q0[j] + 0.3 * std::sin(w * t);
      qd_des[j] = 0.3 * w * std::cos(w * t);
      qdd_des[j] = -0.3 * w * w * std::sin(w * t);
      sign[j] = (qdd_des[j] > 0) - (qdd_des[j] < 0);
    }
    Eigen::VectorXd qd_measured = qd;
    for (int j = 0; j < 7; ++j) qd_measured[j] += noise(rng);
    EXPECT_NE(controller.update(q, qd_measured, q_des, qd_des, qdd_des, u), bc::ControlStatus::InvalidInput);
    EXPECT_EQ(observer.update(q, qd_measured, u, sign), bc::ObserverStatus::Success);
    Eigen::VectorXd model_friction(7);
    EXPECT_EQ(bd::frictionTorques(friction, kdl_friction_state, q, qd_des, sign, model_friction),
              bd::DynamicsStatus::Success);
    kdl_q.data = q;
    kdl_qd.data = qd_measured;
    kdl_tau.data = u - model_friction - model.rotorInertia().cwiseProduct(qdd_des);
    if (k == 0) {
      EXPECT_GE(kdl.setInitialMomentum(kdl_q, kdl_qd), 0);
    }
    EXPECT_GE(kdl.JntToExtWrench(kdl_q, kdl_qd, kdl_tau, kdl_wrench), 0);
    if (t >= 0.5 && t < 2.0) {
      result.max_tracking_error_free = std::max(result.max_tracking_error_free, (q_des - q).cwiseAbs().maxCoeff());
    }
    const double force_error = (observer.wrench().head<3>() - F.head<3>()).norm();
    if (t >= 2.2 && t < 2.5) early.push_back(force_error);
    if (t >= 2.5) {
      force.push_back(force_error);
      moment.push_back((observer.wrench().tail<3>() - F.tail<3>()).norm());
      // KDL's wrench is in the tip frame: rotate ours and the truth into it.
      EXPECT_EQ(bk::forwardKinematics(model, kinematics, q), bk::KinematicsStatus::Success);
      const Eigen::Matrix3d Rt = kinematics.tipPose().linear().transpose();
      const Eigen::Vector3d kdl_f(kdl_wrench.force.x(), kdl_wrench.force.y(), kdl_wrench.force.z());
      kdl_force.push_back((kdl_f - Rt * F.head<3>()).norm());
      difference.push_back((kdl_f - Rt * observer.wrench().head<3>()).norm());
    }
    for (int s = 0; s < 10; ++s) {
      EXPECT_EQ(bk::computeJacobian(model, kinematics, q), bk::KinematicsStatus::Success);
      tau_ext.noalias() = kinematics.jacobian.transpose() * F;
      if (t < 2.0) tau_ext.setZero();
      const Eigen::VectorXd true_sign = qdd.unaryExpr([](double a) { return (a > 0) - (a < 0) + 0.0; });
      EXPECT_EQ(bd::frictionTorques(friction, plant_friction, q, qd, true_sign, friction_torque),
                bd::DynamicsStatus::Success);
      EXPECT_EQ(bd::forwardDynamics(model, plant, q, qd, u + tau_ext - friction_torque, qdd),
                bd::DynamicsStatus::Success);
      qd += dt * qdd;
      q += dt * qd;
    }
  }
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  result.force_error_median_early = median(early);
  result.force_error_median = median(force);
  result.moment_error_median = median(moment);
  result.kdl_force_error_median = median(kdl_force);
  result.ours_vs_kdl_force_median = median(difference);
  return result;
}

}  // namespace

/// The loop with friction compensation, run once for the three tests that look at it.
const LoopResult& compensatedLoop() {
  static const LoopResult result = runLoop(true);
  return result;
}

TEST(ComputedTorqueControl, TracksWithLowGainsAndFrictionCompensationMatters) {
  const LoopResult& with = compensatedLoop();
  const LoopResult without = runLoop(false);
  std::printf("tracking: max error %.4f rad with friction compensation, %.4f rad without\n",
              with.max_tracking_error_free, without.max_tracking_error_free);
  EXPECT_LE(with.max_tracking_error_free, 0.02);
  EXPECT_GT(without.max_tracking_error_free, 3.0 * with.max_tracking_error_free);
}

TEST(DisturbanceObserver, WrenchEstimateConvergesToTheAppliedWrench) {
  const LoopResult& result = compensatedLoop();
  std::printf("observer: force error median %.3f N 0.2-0.5 s after the step, %.3f N afterwards; moment %.3f N m\n",
              result.force_error_median_early, result.force_error_median, result.moment_error_median);
  // Applied: |f| = 11.6 N, |m| = 0.54 N m, while the arm tracks a 0.3 rad sinusoid on every joint.
  EXPECT_LE(result.force_error_median_early, 1.0);
  EXPECT_LE(result.force_error_median, 0.6);
  EXPECT_LE(result.moment_error_median, 0.1);
}

TEST(DisturbanceObserver, AgreesWithKdlsMomentumObserver) {
  const LoopResult& result = compensatedLoop();
  std::printf("KDL ChainExternalWrenchEstimator: force error median %.3f N; ours vs KDL %.3f N\n",
              result.kdl_force_error_median, result.ours_vs_kdl_force_median);
  EXPECT_LE(result.kdl_force_error_median, 1.0);
  EXPECT_LE(result.ours_vs_kdl_force_median, 1.0);
}

TEST(DisturbanceObserver, RejectsGainsThatDoNotConverge) {
  const bk::ChainModel model = wamWithRotors();
  const bd::FrictionModel friction = hystereticFriction();
  try {
    bc::DisturbanceObserver(model, friction, bc::ObserverGains::diagonal(7, -10.0, 0.0, 10.0, 0.0, 10.0));
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("not positive definite"), std::string::npos) << e.what();
  }
  // Poles at 1000 1/s cannot be discretised at 500 Hz.
  EXPECT_THROW(bc::DisturbanceObserver(model, friction, bc::ObserverGains::diagonal(7, 1000.0, 0.0, 0.0, 0.0, 1.0)),
               std::invalid_argument);
  EXPECT_THROW(bc::DisturbanceObserver(model, friction, bc::ObserverGains::diagonal(7, 10.0, 0.0, 10.0, -1.0, 1.0)),
               std::invalid_argument);  // Σ + K22 singular
  bc::ComputedTorqueGains gains = lowGains();
  gains.kp[2] = -1.0;
  EXPECT_THROW(bc::ComputedTorqueController(model, friction, gains), std::invalid_argument);
}

TEST(ComputedTorqueControl, BadInputAndSaturation) {
  const bk::ChainModel model = wamWithRotors();
  bc::ComputedTorqueController controller(model, hystereticFriction(), lowGains());
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(7);
  Eigen::VectorXd u = Eigen::VectorXd::Constant(7, 42.0);
  Eigen::VectorXd nan = zero;
  nan[1] = std::nan("");
  EXPECT_EQ(controller.update(nan, zero, zero, zero, zero, u), bc::ControlStatus::InvalidInput);
  EXPECT_EQ(u, Eigen::VectorXd::Constant(7, 42.0));
  const Eigen::VectorXd far = Eigen::VectorXd::Constant(7, 1.0);
  EXPECT_EQ(controller.update(zero, zero, far, zero, zero, u), bc::ControlStatus::Saturated);
  EXPECT_LE((u.cwiseAbs() - model.effortLimits()).maxCoeff(), 0.0);
}

TEST(Control, UpdatesDoNotAllocate) {
  const bk::ChainModel model = wamWithRotors();
  const bd::FrictionModel friction = hystereticFriction();
  bc::ComputedTorqueController controller(model, friction, lowGains());
  bc::DisturbanceObserver observer(model, friction, bc::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0));
  const Eigen::VectorXd q = Eigen::VectorXd::Constant(7, 0.3), qd = Eigen::VectorXd::Constant(7, 0.1);
  const Eigen::VectorXd sign = Eigen::VectorXd::Ones(7);
  Eigen::VectorXd u(7);
  NoAllocGuard guard;
  for (int k = 0; k < 5; ++k) {
    EXPECT_NE(controller.update(q, qd, q, qd, qd, u), bc::ControlStatus::InvalidInput);
    EXPECT_EQ(observer.update(q, qd, u, sign), bc::ObserverStatus::Success);
  }
}
