// The true plant in joint space (no Bullet): rotor inertia and payload against the project's forward dynamics,
// stick-slip, hysteresis, viscous and ripple friction, the cable-differential coupling, and the sensors.
#include "bimanual_skills/sim/arm_plant.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace bs = bimanual_skills;
using bs::sim::ArmPlant;
using bs::sim::ArmPlantParameters;
using bs::sim::Drive;
using bs::sim::FrictionLaw;
using bs::sim::SimStatus;

namespace {

constexpr double kDt = 0.001;

/// n revolute joints about vertical axes (gravity along the axes: no gravity torque), links 0.3 m long, each a
/// 1 kg body 0.1 m out along x. Joint 1 alone has inertia 0.02 kg m² about its axis.
bs::kinematics::ChainModel verticalChain(int n) {
  std::vector<bs::kinematics::ChainJoint> joints;
  for (int i = 0; i < n; ++i) {
    bs::kinematics::ChainJoint joint;
    joint.name = "joint" + std::to_string(i + 1);
    joint.child_link = "link" + std::to_string(i + 1);
    joint.origin.translation() = Eigen::Vector3d(i == 0 ? 0.0 : 0.3, 0.0, 0.0);
    joint.body.mass = 1.0;
    joint.body.com = Eigen::Vector3d(0.1, 0.0, 0.0);
    joint.body.inertia = 0.01 * Eigen::Matrix3d::Identity();
    joint.effort = 100.0;
    joints.push_back(joint);
  }
  Eigen::Isometry3d tip = Eigen::Isometry3d::Identity();
  tip.translation().x() = 0.3;
  return bs::kinematics::ChainModel("base", "tip", joints, tip);
}

FrictionLaw coulombLaw(double fs, double fc) {
  FrictionLaw law;
  law.static_friction = fs;
  law.coulomb = fc;
  law.stribeck_velocity = 0.02;
  return law;
}

ArmPlantParameters directDrives(int n, const FrictionLaw& law) {
  ArmPlantParameters p = ArmPlantParameters::ideal();
  for (int i = 0; i < n; ++i) p.drives.push_back(Drive{i, -1, 1.0, law});
  return p;
}

/// Semi-implicit Euler with the plant's accelerations, as Bullet integrates them.
struct Integrator {
  explicit Integrator(ArmPlant& plant)
      : plant(plant),
        q(Eigen::VectorXd::Zero(plant.nq())),
        qd(Eigen::VectorXd::Zero(plant.nq())),
        qdd(Eigen::VectorXd::Zero(plant.nq())),
        rigid(Eigen::VectorXd::Zero(plant.nq())),
        ext(Eigen::VectorXd::Zero(plant.nq())) {}

  void step(const Eigen::VectorXd& tau) {
    ASSERT_EQ(plant.step(q, qd, tau, ext, {}, kDt, qdd, rigid), SimStatus::Ok);
    qd += kDt * qdd;
    q += kDt * qd;
  }

  ArmPlant& plant;
  Eigen::VectorXd q, qd, qdd, rigid, ext;
};

}  // namespace

TEST(SimArmPlant, RotorInertiaPayloadAndExternalTorqueMatchForwardDynamics) {
  const bs::kinematics::ChainModel wam = bs::test_support::wam();
  const bs::kinematics::ChainModel reference = bs::test_support::wamWithRotors();  // independent J_m path
  ArmPlantParameters parameters = ArmPlantParameters::ideal();
  parameters.rotor_inertia = reference.rotorInertia();
  ArmPlant plant(wam, parameters);
  bs::dynamics::DynamicsData data(reference);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Eigen::VectorXd qdd(7), rigid(7), expected(7), check(7);
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::VectorXd q = bs::test_support::randomWithinLimits(wam, rng);
    const Eigen::VectorXd qd = Eigen::VectorXd::NullaryExpr(7, [&] { return 1.5 * uniform(rng); });
    const Eigen::VectorXd tau = Eigen::VectorXd::NullaryExpr(7, [&] { return 20.0 * uniform(rng); });
    const Eigen::VectorXd ext = Eigen::VectorXd::NullaryExpr(7, [&] { return 5.0 * uniform(rng); });
    bs::dynamics::Payload payload;
    if (trial % 2 == 1) payload = {1.3, Eigen::Vector3d(0.02, -0.01, 0.08)};
    ASSERT_EQ(plant.step(q, qd, tau, ext, payload, kDt, qdd, rigid), SimStatus::Ok);
    ASSERT_EQ(bs::dynamics::forwardDynamics(reference, data, q, qd, tau + ext, expected, payload),
              bs::dynamics::DynamicsStatus::Success);
    EXPECT_LT((qdd - expected).norm(), 1e-9 * (1.0 + expected.norm())) << "trial " << trial;
    // The rigid-body torque gives the same acceleration on the model without rotors and payload (Bullet's).
    ASSERT_EQ(bs::dynamics::forwardDynamics(wam, data, q, qd, rigid, check), bs::dynamics::DynamicsStatus::Success);
    EXPECT_LT((check - qdd).norm(), 1e-9 * (1.0 + qdd.norm())) << "trial " << trial;
  }
}

TEST(SimArmPlant, SticksBelowStaticFrictionAndSlipsAbove) {
  const double fs = 1.0, fc = 0.7;
  ArmPlant plant(verticalChain(1), directDrives(1, coulombLaw(fs, fc)));
  Integrator stick(plant);
  for (int k = 0; k < 2000; ++k) stick.step(Eigen::VectorXd::Constant(1, 0.98 * fs));
  EXPECT_LT(std::abs(stick.qd[0]), 1e-12);  // zero up to the rounding of the impulse solve
  EXPECT_LT(std::abs(stick.q[0]), 1e-12);
  EXPECT_TRUE(plant.channelSticks(0));
  EXPECT_NEAR(plant.frictionTorque()[0], 0.98 * fs, 1e-9);  // friction balances the torque exactly

  ArmPlant plant2(verticalChain(1), directDrives(1, coulombLaw(fs, fc)));
  Integrator slip(plant2);
  for (int k = 0; k < 200; ++k) slip.step(Eigen::VectorXd::Constant(1, 1.02 * fs));
  EXPECT_GT(slip.qd[0], 0.05);
  EXPECT_FALSE(plant2.channelSticks(0));
  // Sliding well above the Stribeck velocity: friction at the Coulomb level, so q̈ = (τ − F_c) / I.
  EXPECT_NEAR(slip.qdd[0], (1.02 * fs - fc) / 0.02, 1e-6);
}

TEST(SimArmPlant, StaticFrictionExceedsCoulombOnceSliding) {
  const double fs = 1.0, fc = 0.6, tau_mid = 0.8;
  ArmPlant plant(verticalChain(1), directDrives(1, coulombLaw(fs, fc)));
  Integrator sim(plant);
  for (int k = 0; k < 500; ++k) sim.step(Eigen::VectorXd::Constant(1, tau_mid));
  EXPECT_LT(std::abs(sim.qd[0]), 1e-12) << "between Coulomb and static friction a resting joint does not start";
  for (int k = 0; k < 20; ++k) sim.step(Eigen::VectorXd::Constant(1, 1.5));  // breakaway pulse
  for (int k = 0; k < 1000; ++k) sim.step(Eigen::VectorXd::Constant(1, tau_mid));
  EXPECT_GT(sim.qd[0], 1.0) << "the same torque keeps a sliding joint accelerating: friction fell to Coulomb";
}

TEST(SimArmPlant, ViscousFrictionSetsTheTerminalVelocity) {
  FrictionLaw law = coulombLaw(0.5, 0.4);
  law.viscous = 0.2;
  ArmPlant plant(verticalChain(1), directDrives(1, law));
  Integrator sim(plant);
  for (int k = 0; k < 8000; ++k) sim.step(Eigen::VectorXd::Constant(1, 1.0));
  EXPECT_NEAR(sim.qd[0], (1.0 - 0.4) / 0.2, 1e-6);
}

TEST(SimArmPlant, HysteresisMoreFrictionSpeedingUpThanSlowingDown) {
  FrictionLaw law = coulombLaw(1.0, 0.8);
  law.hysteresis = 0.2;
  law.viscous = 0.05;
  ArmPlant plant(verticalChain(1), directDrives(1, law));
  Integrator sim(plant);
  double up_sum = 0.0, down_sum = 0.0;
  int up = 0, down = 0;
  double previous_speed = 0.0;
  for (int k = 0; k < 6000; ++k) {
    const double t = k * kDt;
    sim.step(Eigen::VectorXd::Constant(1, 3.0 * std::sin(2.0 * M_PI * t)));
    const double speed = std::abs(sim.qd[0]);
    const double coulomb_part = std::abs(plant.frictionTorque()[0]) - law.viscous * speed;
    if (t > 1.0 && speed > 1.0 && speed < 4.0) {
      if (speed > previous_speed) {
        up_sum += coulomb_part;
        ++up;
      } else {
        down_sum += coulomb_part;
        ++down;
      }
    }
    previous_speed = speed;
  }
  ASSERT_GT(up, 100);
  ASSERT_GT(down, 100);
  EXPECT_NEAR(up_sum / up - down_sum / down, 2.0 * law.hysteresis * law.coulomb, 0.02);
}

TEST(SimArmPlant, RippleDependsOnPositionAndDirection) {
  FrictionLaw law = coulombLaw(1.0, 1.0);
  law.stribeck_velocity = 1e-3;
  law.ripple = 0.2;
  law.ripple_frequency = 3.0;
  law.ripple_phase_positive = 0.0;
  law.ripple_phase_negative = M_PI / 2.0;
  ArmPlant plant(verticalChain(1), directDrives(1, law));
  Eigen::VectorXd qdd(1), rigid(1), zero = Eigen::VectorXd::Zero(1);
  for (const double direction : {1.0, -1.0}) {
    double largest_error = 0.0;
    for (int k = 0; k < 50; ++k) {
      const double q = -1.0 + 0.04 * k;
      const Eigen::VectorXd qd = Eigen::VectorXd::Constant(1, direction * 0.5);
      // Sliding (it moved in the previous call), torque pushing along the motion: F = ρ(q, ±) F_c.
      ASSERT_EQ(plant.step(Eigen::VectorXd::Constant(1, q), qd, Eigen::VectorXd::Constant(1, direction * 5.0), zero, {},
                           kDt, qdd, rigid),
                SimStatus::Ok);
      const double phase = direction > 0 ? law.ripple_phase_positive : law.ripple_phase_negative;
      const double expected = direction * (1.0 + law.ripple * std::sin(law.ripple_frequency * q + phase));
      if (k > 0) largest_error = std::max(largest_error, std::abs(plant.frictionTorque()[0] - expected));
    }
    EXPECT_LT(largest_error, 1e-9) << "direction " << direction;
  }
}

TEST(SimArmPlant, CableDifferentialCouplesTheFrictionOfItsJoints) {
  const double fs = 0.5, fc = 0.4, k = 0.6;
  const auto plantWith = [&] {
    ArmPlantParameters p = ArmPlantParameters::ideal();
    p.drives.push_back(Drive{0, 1, k, coulombLaw(fs, fc)});
    return ArmPlant(verticalChain(2), p);
  };
  // Joint 1 alone breaks away at 2 F_s (both motors), joint 2 alone at 2 k F_s.
  for (const auto& [joint, breakaway] : {std::pair{0, 2.0 * fs}, std::pair{1, 2.0 * k * fs}}) {
    for (const double factor : {0.97, 1.03}) {
      ArmPlant plant = plantWith();
      Integrator sim(plant);
      Eigen::VectorXd tau = Eigen::VectorXd::Zero(2);
      tau[joint] = factor * breakaway;
      for (int s = 0; s < 300; ++s) sim.step(tau);
      if (factor < 1.0) {
        EXPECT_LT(sim.qd.norm(), 1e-12) << "joint " << joint + 1 << " below breakaway";
      } else {
        EXPECT_GT(std::abs(sim.qd[joint]), 0.01) << "joint " << joint + 1 << " above breakaway";
      }
    }
  }
  // Sliding friction on joint 1 (thesis Sec. 4.2.2: reduced while the other joint of the pair moves faster): both
  // motors slide; when k |q̇2| > |q̇1| they turn in opposite directions and their friction on joint 1 cancels.
  struct Case {
    double qd1, qd2, friction1, friction2;  // expected |F_f| on joints 1 and 2
  };
  for (const Case& c : {Case{0.5, 0.0, 2.0 * fc, 0.0}, Case{0.5, 0.5, 2.0 * fc, 0.0}, Case{0.5, 2.0, 0.0, 2.0 * k * fc},
                        Case{-0.4, 3.0, 0.0, 2.0 * k * fc}}) {
    ArmPlant plant = plantWith();
    const Eigen::VectorXd q = Eigen::VectorXd::Zero(2), qd = Eigen::Vector2d(c.qd1, c.qd2);
    Eigen::VectorXd qdd(2), rigid(2);
    plant.resetFriction(qd);  // sliding
    ASSERT_EQ(plant.step(q, qd, Eigen::VectorXd::Zero(2), Eigen::VectorXd::Zero(2), {}, kDt, qdd, rigid),
              SimStatus::Ok);
    EXPECT_NEAR(std::abs(plant.frictionTorque()[0]), c.friction1, 1e-9) << c.qd1 << ", " << c.qd2;
    EXPECT_NEAR(std::abs(plant.frictionTorque()[1]), c.friction2, 1e-9) << c.qd1 << ", " << c.qd2;
  }
  // Held joint 1 (torque below its breakaway) stays put while joint 2 rests.
  ArmPlant plant = plantWith();
  Integrator sim(plant);
  for (int s = 0; s < 300; ++s) sim.step(Eigen::Vector2d(0.75 * 2.0 * fs, 0.0));
  EXPECT_LT(sim.qd.norm(), 1e-12);
  EXPECT_NEAR(plant.frictionTorque()[0], 0.75 * 2.0 * fs, 1e-9);
}

TEST(SimArmPlant, JointLimitsStopTheJointExactlyAtTheLimit) {
  std::vector<bs::kinematics::ChainJoint> joints = verticalChain(2).joints();
  joints[0].lower = -0.5;
  joints[0].upper = 0.4;
  Eigen::Isometry3d tip = Eigen::Isometry3d::Identity();
  tip.translation().x() = 0.3;
  ArmPlantParameters p = directDrives(2, coulombLaw(0.05, 0.04));
  p.rotor_inertia = Eigen::Vector2d(0.1, 0.0);
  ArmPlant plant(bs::kinematics::ChainModel("base", "tip", joints, tip), p);
  Integrator sim(plant);
  double highest = 0.0;
  for (int k = 0; k < 1500; ++k) {
    sim.step(Eigen::Vector2d(2.0, 0.0));
    highest = std::max(highest, sim.q[0]);
  }
  EXPECT_LE(highest, 0.4 + 1e-12);
  EXPECT_NEAR(sim.q[0], 0.4, 1e-12);
  EXPECT_LT(std::abs(sim.qd[0]), 1e-9);
  for (int k = 0; k < 1500; ++k) sim.step(Eigen::Vector2d(-2.0, 0.0));
  EXPECT_NEAR(sim.q[0], -0.5, 1e-12);
}

TEST(SimArmPlant, SensorsQuantiseAndAddNoiseWithTheConfiguredStatistics) {
  ArmPlantParameters p = ArmPlantParameters::ideal();
  p.encoder_resolution = Eigen::Vector2d(1e-3, 0.0);
  p.velocity_noise = Eigen::Vector2d(0.0, 0.02);
  ArmPlant plant(verticalChain(2), p);
  std::mt19937 rng(5), positions(9);
  std::uniform_real_distribution<double> uniform(-3.0, 3.0);
  const int samples = 20000;
  double q_error_sum = 0.0, q_error_square = 0.0, q_error_max = 0.0, noise_sum = 0.0, noise_square = 0.0;
  Eigen::VectorXd q(2), qd(2), qm(2), qdm(2);
  for (int s = 0; s < samples; ++s) {
    q << uniform(positions), uniform(positions);
    qd << uniform(positions), uniform(positions);
    plant.measure(q, qd, rng, qm, qdm);
    const double e = qm[0] - q[0];
    q_error_sum += e;
    q_error_square += e * e;
    q_error_max = std::max(q_error_max, std::abs(e));
    EXPECT_NEAR(std::remainder(qm[0], 1e-3), 0.0, 1e-12);
    EXPECT_EQ(qm[1], q[1]);    // no quantisation configured
    EXPECT_EQ(qdm[0], qd[0]);  // no noise configured
    const double n = qdm[1] - qd[1];
    noise_sum += n;
    noise_square += n * n;
  }
  EXPECT_LE(q_error_max, 0.5e-3 + 1e-15);
  EXPECT_NEAR(q_error_sum / samples, 0.0, 1e-5);
  EXPECT_NEAR(std::sqrt(q_error_square / samples), 1e-3 / std::sqrt(12.0), 0.02 * 1e-3 / std::sqrt(12.0));
  const double mean = noise_sum / samples;
  EXPECT_NEAR(mean, 0.0, 4.0 * 0.02 / std::sqrt(samples));
  EXPECT_NEAR(std::sqrt(noise_square / samples - mean * mean), 0.02, 0.02 * 0.03);

  // The same generator state gives the same draws.
  std::mt19937 a(77), b(77);
  Eigen::VectorXd qd1(2), qd2(2);
  plant.resetNoise();
  plant.measure(q, qd, a, qm, qd1);
  plant.resetNoise();
  plant.measure(q, qd, b, qm, qd2);
  EXPECT_EQ(qd1, qd2);
}

TEST(SimArmPlant, RejectsBadInputAndValidatesParameters) {
  ArmPlant plant(verticalChain(2), directDrives(2, coulombLaw(1.0, 0.5)));
  Eigen::VectorXd ok = Eigen::VectorXd::Zero(2), qdd(2), rigid(2), wrong(3);
  Eigen::VectorXd bad = ok;
  bad[1] = std::nan("");
  EXPECT_EQ(plant.step(ok, ok, bad, ok, {}, kDt, qdd, rigid), SimStatus::InvalidArgument);
  EXPECT_EQ(plant.step(ok, ok, wrong, ok, {}, kDt, qdd, rigid), SimStatus::InvalidArgument);
  EXPECT_EQ(plant.step(ok, ok, ok, ok, {}, 0.0, qdd, rigid), SimStatus::InvalidArgument);
  EXPECT_EQ(plant.step(ok, ok, ok, ok, {std::nan(""), Eigen::Vector3d::Zero()}, kDt, qdd, rigid),
            SimStatus::InvalidArgument);

  ArmPlantParameters missing = directDrives(1, coulombLaw(1.0, 0.5));  // joint 2 has no drive
  EXPECT_THROW(ArmPlant(verticalChain(2), missing), std::invalid_argument);
  ArmPlantParameters twice = directDrives(2, coulombLaw(1.0, 0.5));
  twice.drives.push_back(Drive{1, -1, 1.0, coulombLaw(1.0, 0.5)});
  EXPECT_THROW(ArmPlant(verticalChain(2), twice), std::invalid_argument);
  ArmPlantParameters inverted = directDrives(2, coulombLaw(0.4, 0.5));  // static < Coulomb
  EXPECT_THROW(ArmPlant(verticalChain(2), inverted), std::invalid_argument);
  ArmPlantParameters rotor = directDrives(2, coulombLaw(1.0, 0.5));
  rotor.rotor_inertia = Eigen::VectorXd::Ones(3);
  try {
    ArmPlant(verticalChain(2), rotor);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rotor_inertia"), std::string::npos) << e.what();
  }
}

TEST(SimArmPlant, StepAndMeasureDoNotAllocate) {
  ArmPlantParameters p = ArmPlantParameters::ideal();
  p.drives = {Drive{0, -1, 1.0, coulombLaw(1.0, 0.5)}, Drive{1, 2, 0.6, coulombLaw(0.3, 0.2)}};
  p.rotor_inertia = Eigen::Vector3d(0.1, 0.05, 0.01);
  p.velocity_noise = Eigen::Vector3d::Constant(0.01);
  p.encoder_resolution = Eigen::Vector3d::Constant(1e-4);
  ArmPlant plant(verticalChain(3), p);
  Eigen::VectorXd q = Eigen::VectorXd::Constant(3, 0.1), qd = Eigen::VectorXd::Constant(3, 0.2);
  Eigen::VectorXd tau = Eigen::VectorXd::Constant(3, 1.0), ext = Eigen::VectorXd::Zero(3), qdd(3), rigid(3), qm(3),
                  qdm(3);
  std::mt19937 rng(1);
  SimStatus status = SimStatus::InvalidArgument;
  {
    bs::testing::NoAllocGuard guard;
    status = plant.step(q, qd, tau, ext, {0.5, Eigen::Vector3d::Zero()}, kDt, qdd, rigid);
    plant.measure(q, qd, rng, qm, qdm);
  }
  EXPECT_EQ(status, SimStatus::Ok);
}

TEST(SimArmPlant, WithoutFrictionItFollowsTheProjectsForwardDynamics) {
  // An ideal plant's step (its own M(q) + h solve) against dynamics::forwardDynamics, with a payload and on a chain
  // with a prismatic joint.
  std::vector<bs::kinematics::ChainModel> models = {bs::test_support::wam()};
  {
    std::vector<bs::kinematics::ChainJoint> joints = verticalChain(3).joints();
    joints[1].type = bs::kinematics::JointType::Prismatic;
    joints[1].axis = Eigen::Vector3d(0.3, 0.5, 0.8).normalized();
    joints[2].axis = Eigen::Vector3d(1.0, 0.0, 0.2).normalized();
    joints[2].origin.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    models.emplace_back("base", "tip", joints, Eigen::Isometry3d(Eigen::Translation3d(0.1, 0.2, 0.3)));
  }
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (const bs::kinematics::ChainModel& model : models) {
    const int n = model.nq();
    ArmPlant plant(model, ArmPlantParameters::ideal());
    bs::dynamics::DynamicsData data(model);
    Eigen::VectorXd qdd(n), rigid(n), expected(n);
    for (int trial = 0; trial < 20; ++trial) {
      // Well inside the limits (a crossing limit would add its stop to the step).
      Eigen::VectorXd q = Eigen::VectorXd::NullaryExpr(n, [&] { return 2.0 * uniform(rng); });
      for (int i = 0; i < n; ++i) q[i] = std::clamp(q[i], model.lowerLimits()[i] + 0.1, model.upperLimits()[i] - 0.1);
      const Eigen::VectorXd qd = Eigen::VectorXd::NullaryExpr(n, [&] { return uniform(rng); });
      const Eigen::VectorXd tau = Eigen::VectorXd::NullaryExpr(n, [&] { return 3.0 * uniform(rng); });
      const bs::dynamics::Payload payload{1.5, Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)) * 0.1};
      ASSERT_EQ(plant.step(q, qd, tau, Eigen::VectorXd::Zero(n), payload, kDt, qdd, rigid), SimStatus::Ok);
      ASSERT_EQ(bs::dynamics::forwardDynamics(model, data, q, qd, tau, expected, payload),
                bs::dynamics::DynamicsStatus::Success);
      EXPECT_LT((qdd - expected).norm(), 1e-9 * (1.0 + expected.norm())) << "n = " << n << ", trial " << trial;
    }
  }
}
