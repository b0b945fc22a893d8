// Cartesian DMPs: both orientation encodings reproduce an analytic pose trajectory and reach its goal, the quaternion
// stays unit, the unit-quaternion DMP follows a rotation of more than π where the quaternion-vector encoding cannot,
// goal changes while running, the clamp of ‖v‖ > 1, bad input, allocation-free steps, and the log/exp maps against
// Eigen's angle-axis.
// The demonstration recorder trims, resamples and fits what a person taught.
#include "bimanual_skills/primitives/cartesian_dmp.hpp"
#include "bimanual_skills/primitives/demonstration_recorder.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace bp = bimanual_skills::primitives;
using bimanual_skills::testing::NoAllocGuard;

namespace {

constexpr double kDt = 0.002;
constexpr double kDuration = 2.0;

double minimumJerk(double s) {
  return 10 * std::pow(s, 3) - 15 * std::pow(s, 4) + 6 * std::pow(s, 5);
}

/// Start orientation of the demonstrations: not the identity, so the encodings' "relative to the start" matters.
Eigen::Quaterniond startOrientation() {
  return Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()));
}

/// Minimum-jerk position with a bump; orientation q_s ∗ R(θ(s), u(s)): `angle` [rad] along minimum jerk, about an
/// axis that turns by `axis_turn` [rad] during the movement (0: a fixed axis).
std::vector<bp::Pose> demonstration(double angle, double axis_turn) {
  const int samples = static_cast<int>(std::round(kDuration / kDt)) + 1;
  std::vector<bp::Pose> poses(samples);
  for (int k = 0; k < samples; ++k) {
    const double s = k * kDt / kDuration;
    const double m = minimumJerk(s);
    poses[k].position = Eigen::Vector3d(0.4, -0.1, 0.3) + m * Eigen::Vector3d(0.2, 0.3, -0.1) +
                        0.05 * std::sin(M_PI * s) * Eigen::Vector3d(std::sin(M_PI * s), 1.0, -0.5);
    const Eigen::Vector3d axis(std::cos(axis_turn * s), std::sin(axis_turn * s), 0.6);
    poses[k].orientation = startOrientation() * Eigen::Quaterniond(Eigen::AngleAxisd(angle * m, axis.normalized()));
  }
  return poses;
}

double angleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b);
}

struct Rollout {
  std::vector<bp::Pose> poses;
  double worst_norm_error = 0.0;  ///< max |‖q‖ − 1|
  int clamped = 0;
};

/// Steps a DMP for `seconds`; the first pose is the start. At t = goal_change_at the goal becomes `new_goal`.
Rollout rollout(const bp::CartesianDmp& dmp, double seconds, double goal_change_at = -1.0,
                const bp::Pose& new_goal = bp::Pose()) {
  Rollout r;
  bp::CartesianDmpState state = dmp.initialState();
  r.poses.push_back(state.pose());
  const int steps = static_cast<int>(std::round(seconds / kDt));
  for (int k = 1; k <= steps; ++k) {
    if (goal_change_at >= 0.0 && std::abs(state.position.t - goal_change_at) < 0.5 * kDt) state.setGoal(new_goal);
    const bp::DmpStatus status = dmp.step(state, kDt);
    EXPECT_NE(status, bp::DmpStatus::InvalidInput);
    r.clamped += status == bp::DmpStatus::VectorClamped;
    r.poses.push_back(state.pose());
    r.worst_norm_error = std::max(r.worst_norm_error, std::abs(state.orientation.norm() - 1.0));
  }
  return r;
}

struct Errors {
  double position_rmse = 0.0;  ///< [m]
  double angle_rms = 0.0;      ///< [rad]
  double angle_max = 0.0;      ///< [rad]
};

Errors compare(const std::vector<bp::Pose>& reference, const std::vector<bp::Pose>& poses) {
  Errors e;
  for (std::size_t k = 0; k < reference.size(); ++k) {
    e.position_rmse += (poses[k].position - reference[k].position).squaredNorm();
    const double angle = angleBetween(poses[k].orientation, reference[k].orientation);
    e.angle_rms += angle * angle;
    e.angle_max = std::max(e.angle_max, angle);
  }
  const auto n = static_cast<double>(reference.size());
  e.position_rmse = std::sqrt(e.position_rmse / n);
  e.angle_rms = std::sqrt(e.angle_rms / n);
  return e;
}

const char* name(bp::OrientationEncoding encoding) {
  return encoding == bp::OrientationEncoding::UnitQuaternion ? "unit quaternion" : "quaternion vector";
}

class CartesianDmpEncodings : public ::testing::TestWithParam<bp::OrientationEncoding> {};

}  // namespace

TEST(QuaternionMaps, LogAndExpAgreeWithAngleAxis) {
  for (const double angle : {0.0, 1e-9, 0.3, 2.0, 3.0, 4.0, 6.0}) {
    const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
    const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, axis));  // w < 0 beyond π: no canonicalisation
    EXPECT_LE((2.0 * bp::quaternionLog(q) - angle * axis).norm(), 1e-12) << angle;
    EXPECT_LE((bp::quaternionExp(0.5 * angle * axis).coeffs() - q.coeffs()).norm(), 1e-12) << angle;
  }
  const Eigen::Quaterniond q(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(bp::nearestSign(Eigen::Quaterniond(-q.coeffs()), q).coeffs().dot(q.coeffs()), 1.0, 1e-15);
  EXPECT_NEAR(bp::nearestSign(q, q).coeffs().dot(q.coeffs()), 1.0, 1e-15);
}

TEST_P(CartesianDmpEncodings, ReproducesADemonstrationAndReachesTheGoal) {
  const std::vector<bp::Pose> demo = demonstration(75.0 * M_PI / 180.0, 1.5);  // < 90°, axis turning by 1.5 rad
  const bp::CartesianDmp dmp = bp::CartesianDmp::fit(bp::DmpParameters(), GetParam(), demo, kDt);
  EXPECT_NEAR(dmp.duration(), kDuration, 1e-12);
  // As for the joint-space DMP, the forcing term fades with the phase: the goal is checked at 3τ.
  const Rollout r = rollout(dmp, 3.0 * kDuration);
  const Errors e = compare(demo, r.poses);
  std::printf("Cartesian DMP (%s), 25 kernels: position RMSE %.2e m, angle error RMS %.2e rad, max %.2e rad\n",
              name(GetParam()), e.position_rmse, e.angle_rms, e.angle_max);
  EXPECT_LE(e.position_rmse, 2e-3);
  EXPECT_LE(e.angle_rms, 5e-3);
  EXPECT_LE(e.angle_max, 1e-2);
  EXPECT_LE((r.poses.back().position - demo.back().position).norm(), 1e-3);
  EXPECT_LE(angleBetween(r.poses.back().orientation, demo.back().orientation), 1e-3);
  EXPECT_LE(r.worst_norm_error, 1e-12);
  EXPECT_EQ(r.clamped, 0);
}

TEST_P(CartesianDmpEncodings, GoalChangeWhileRunningConverges) {
  const bp::CartesianDmp dmp =
      bp::CartesianDmp::fit(bp::DmpParameters(), GetParam(), demonstration(75.0 * M_PI / 180.0, 1.5), kDt);
  bp::Pose new_goal = dmp.goal();
  new_goal.position += Eigen::Vector3d(0.1, -0.05, 0.08);
  new_goal.orientation =
      bp::nearestSign(dmp.goal().orientation * Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1.0, -0.3).normalized()),
                      dmp.goal().orientation);
  const Rollout r = rollout(dmp, 3.0 * kDuration, 0.5 * kDuration, new_goal);
  double largest_turn = 0.0;
  for (std::size_t k = 1; k < r.poses.size(); ++k)
    largest_turn = std::max(largest_turn, angleBetween(r.poses[k].orientation, r.poses[k - 1].orientation));
  EXPECT_LE(largest_turn, 0.01);  // < 5 rad/s at 2 ms: no jump at the switch
  EXPECT_LE((r.poses.back().position - new_goal.position).norm(), 1e-3);
  EXPECT_LE(angleBetween(r.poses.back().orientation, new_goal.orientation), 1e-3);
  EXPECT_LE(r.worst_norm_error, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(BothEncodings, CartesianDmpEncodings,
                         ::testing::Values(bp::OrientationEncoding::UnitQuaternion,
                                           bp::OrientationEncoding::QuaternionVector));

TEST_P(CartesianDmpEncodings, GivenForcingEqualToTheWeightsGivesTheSameSteps) {
  // The weights' own forcing terms W g(x), passed to step(state, dt, forcing), reproduce step(state, dt) exactly.
  const bp::CartesianDmp dmp =
      bp::CartesianDmp::fit(bp::DmpParameters(), GetParam(), demonstration(75.0 * M_PI / 180.0, 1.5), kDt);
  bp::CartesianDmpState own = dmp.initialState(), given = dmp.initialState();
  Eigen::VectorXd g(dmp.parameters().kernels), forcing(6);
  for (int k = 0; k < 300; ++k) {
    dmp.position().basis(given.position.x, g);
    forcing << dmp.positionWeights() * g, dmp.orientationWeights() * g;
    ASSERT_NE(dmp.step(own, kDt), bp::DmpStatus::InvalidInput);
    ASSERT_NE(dmp.step(given, kDt, forcing), bp::DmpStatus::InvalidInput);
    ASSERT_LE((own.position.y - given.position.y).norm(), 1e-12) << k;
    ASSERT_LE((own.orientation.coeffs() - given.orientation.coeffs()).norm(), 1e-12) << k;
  }
  // A forcing of the wrong size or not finite is refused and leaves the state as it was.
  const bp::CartesianDmpState before = given;
  EXPECT_EQ(dmp.step(given, kDt, Eigen::VectorXd::Zero(5)), bp::DmpStatus::InvalidInput);
  EXPECT_EQ(dmp.step(given, kDt, Eigen::VectorXd::Constant(6, NAN)), bp::DmpStatus::InvalidInput);
  EXPECT_EQ(given.position.y, before.position.y);
  EXPECT_EQ(given.position.t, before.position.t);
}

TEST(CartesianDmp, OnlyTheUnitQuaternionDmpFollowsARotationBeyondPi) {
  const std::vector<bp::Pose> demo = demonstration(270.0 * M_PI / 180.0, 0.0);  // 270° about a fixed axis
  // The encoding itself: v = vec(q_s⁻¹ ∗ q) with w ≥ 0 jumps from u to −u as the rotation passes π.
  double largest_jump = 0.0;
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  for (const bp::Pose& pose : demo) {
    const Eigen::Vector3d v =
        bp::nearestSign(startOrientation().conjugate() * pose.orientation, Eigen::Quaterniond::Identity()).vec();
    largest_jump = std::max(largest_jump, (v - previous).norm());
    previous = v;
  }
  EXPECT_GT(largest_jump, 1.9);

  const bp::CartesianDmp unit =
      bp::CartesianDmp::fit(bp::DmpParameters(), bp::OrientationEncoding::UnitQuaternion, demo, kDt);
  const bp::CartesianDmp vector =
      bp::CartesianDmp::fit(bp::DmpParameters(), bp::OrientationEncoding::QuaternionVector, demo, kDt);
  const Rollout ru = rollout(unit, 3.0 * kDuration);
  const Rollout rv = rollout(vector, 3.0 * kDuration);
  const Errors eu = compare(demo, ru.poses);
  const Errors ev = compare(demo, rv.poses);
  std::printf(
      "270 deg rotation: angle error max %.2e rad (unit quaternion), %.2e rad (quaternion vector, %d clamped)\n",
      eu.angle_max, ev.angle_max, rv.clamped);
  EXPECT_LE(eu.angle_max, 2e-2);
  EXPECT_LE(angleBetween(ru.poses.back().orientation, demo.back().orientation), 1e-3);
  // The quaternion-vector DMP reaches the same final orientation (270° = −90°) by another path, far from the demo.
  EXPECT_GT(ev.angle_max, 0.5);
  EXPECT_LE(angleBetween(rv.poses.back().orientation, demo.back().orientation), 1e-3);
  EXPECT_LE(ru.worst_norm_error, 1e-12);
  EXPECT_LE(rv.worst_norm_error, 1e-12);
}

TEST(CartesianDmp, VectorBeyondTheUnitBallIsClamped) {
  bp::DmpParameters parameters;
  parameters.kernels = 5;
  const Eigen::MatrixXd position_weights = Eigen::MatrixXd::Zero(3, 5);
  Eigen::MatrixXd orientation_weights = Eigen::MatrixXd::Zero(3, 5);
  orientation_weights.row(2).setConstant(2000.0);  // a large push of v_z
  const bp::Pose start, goal;
  const bp::CartesianDmp dmp(parameters, bp::OrientationEncoding::QuaternionVector, position_weights,
                             orientation_weights, start, goal, 1.0);
  const Rollout r = rollout(dmp, 3.0);
  EXPECT_GT(r.clamped, 0);
  EXPECT_LE(r.worst_norm_error, 1e-12);
  EXPECT_LE(angleBetween(r.poses.back().orientation, goal.orientation), 1e-3);  // back to the goal after the push
}

TEST(CartesianDmp, BadInputIsRefused) {
  std::vector<bp::Pose> demo = demonstration(0.5, 0.0);
  for (const bp::OrientationEncoding encoding :
       {bp::OrientationEncoding::UnitQuaternion, bp::OrientationEncoding::QuaternionVector}) {
    const bp::CartesianDmp dmp = bp::CartesianDmp::fit(bp::DmpParameters(), encoding, demo, kDt);
    const bp::CartesianDmpState good = dmp.initialState();
    bp::CartesianDmpState state = good;
    EXPECT_EQ(dmp.step(state, 0.0), bp::DmpStatus::InvalidInput);
    EXPECT_EQ(dmp.step(state, std::nan("")), bp::DmpStatus::InvalidInput);
    // α_z dt/τ = 2: the transformation system's steps would diverge (DmpParameters::stableStep).
    EXPECT_EQ(dmp.step(state, 2.0 * dmp.duration() / bp::DmpParameters().alpha_z), bp::DmpStatus::InvalidInput);
    EXPECT_EQ(state.position.t, 0.0);
    EXPECT_EQ(dmp.step(state, 0.5 * dmp.duration() / bp::DmpParameters().alpha_z), bp::DmpStatus::Success);
    state = good;
    state.position.y[1] = std::nan("");
    EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    EXPECT_TRUE(std::isnan(state.position.y[1]));  // unchanged
    state = good;
    state.orientation.coeffs() *= 1.01;  // not unit
    EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    EXPECT_EQ(state.orientation.coeffs(), good.orientation.coeffs() * 1.01);
    EXPECT_EQ(state.position.t, 0.0);
    state = good;
    state.goal_orientation.coeffs().setZero();
    EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    state = good;
    state.goal_orientation.x() = std::nan("");
    EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    state = good;
    state.angular_velocity[0] = INFINITY;
    EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    state = good;
    state.position.goal = Eigen::VectorXd::Zero(7);
    EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    if (encoding == bp::OrientationEncoding::QuaternionVector) {
      state = good;
      state.orientation_vector.y.resize(0);
      EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::InvalidInput);
    }
    bp::Pose not_unit = dmp.goal();
    not_unit.orientation.coeffs() *= 2.0;
    EXPECT_THROW(dmp.withGoal(not_unit), std::invalid_argument);
    EXPECT_THROW(bp::CartesianDmp(dmp.parameters(), encoding, dmp.positionWeights(),
                                  Eigen::MatrixXd::Zero(2, dmp.parameters().kernels), dmp.start(), dmp.goal(), 1.0),
                 std::invalid_argument);
    EXPECT_THROW(dmp.withDuration(0.0), std::invalid_argument);
  }
  std::vector<bp::Pose> bad = demo;
  bad[10].orientation.coeffs() *= 0.5;
  EXPECT_THROW(bp::CartesianDmp::fit(bp::DmpParameters(), bp::OrientationEncoding::UnitQuaternion, bad, kDt),
               std::invalid_argument);
  bad = demo;
  bad[3].position.z() = std::nan("");
  EXPECT_THROW(bp::CartesianDmp::fit(bp::DmpParameters(), bp::OrientationEncoding::UnitQuaternion, bad, kDt),
               std::invalid_argument);
  bad.resize(5);
  EXPECT_THROW(bp::CartesianDmp::fit(bp::DmpParameters(), bp::OrientationEncoding::QuaternionVector, bad, kDt),
               std::invalid_argument);
}

TEST(CartesianDmp, StepsDoNotAllocate) {
  const std::vector<bp::Pose> demo = demonstration(1.0, 1.0);
  for (const bp::OrientationEncoding encoding :
       {bp::OrientationEncoding::UnitQuaternion, bp::OrientationEncoding::QuaternionVector}) {
    bp::DmpParameters parameters;
    parameters.goal_scaled_forcing = true;
    const bp::CartesianDmp dmp = bp::CartesianDmp::fit(parameters, encoding, demo, kDt);
    bp::CartesianDmpState state = dmp.initialState();
    NoAllocGuard guard;
    for (int k = 0; k < 200; ++k) EXPECT_EQ(dmp.step(state, kDt), bp::DmpStatus::Success);
  }
}

// A taught demonstration of two tools, sampled at irregular times with a duplicate and a reordered message among
// them: the still parts are trimmed, the recorder keeps the movement, and the DMPs fitted to it reproduce each
// tool's path; a recording in which nothing moved is refused.
TEST(DemonstrationRecorder, TrimsResamplesAndFitsWhatWasTaught) {
  bp::DemonstrationRecorder recorder(2);
  const auto pose = [](int tool, double t) {
    const double s = std::clamp((t - 0.5) / 2.0, 0.0, 1.0), m = s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
    bp::Pose p;
    p.position = Eigen::Vector3d(0.8 - 0.3 * m, tool == 0 ? 0.3 : -0.3, 0.2 + 0.15 * std::sin(M_PI * m));
    p.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI - 0.4 * std::sin(M_PI * m), Eigen::Vector3d::UnitY()));
    return p;
  };
  double t = 0.0;
  int k = 0;
  while (t < 3.0) {
    ASSERT_TRUE(recorder.add(t, {pose(0, t), pose(1, t)}));
    EXPECT_FALSE(recorder.add(t, {pose(0, t), pose(1, t)}));          // duplicate
    EXPECT_FALSE(recorder.add(t - 0.002, {pose(0, t), pose(1, t)}));  // reordered
    t += 0.004 + 0.002 * ((k++ * 7) % 5) / 4.0;                       // 4–6 ms apart
  }
  EXPECT_FALSE(recorder.add(t, {pose(0, t)}));  // one pose for two tools
  bp::Pose bad = pose(0, t);
  bad.position.x() = NAN;
  EXPECT_FALSE(recorder.add(t, {bad, pose(1, t)}));
  const std::vector<std::vector<bp::Pose>> paths = recorder.resampled(0.01, 0.002);
  ASSERT_EQ(paths.size(), 2u);
  // The movement (0.5 s to 2.5 s, its first and last 2 mm slow) and none of the still parts around it.
  const double taught = 0.01 * (paths[0].size() - 1);
  EXPECT_GT(taught, 1.5);
  EXPECT_LT(taught, 2.0);
  bp::DmpParameters parameters;
  parameters.kernels = 20;
  const std::vector<bp::CartesianDmp> dmps = recorder.fit(parameters, 0.01, 0.002);
  ASSERT_EQ(dmps.size(), 2u);
  for (int tool = 0; tool < 2; ++tool) {
    const bp::CartesianDmp& dmp = dmps[static_cast<std::size_t>(tool)];
    EXPECT_NEAR(dmp.duration(), taught, 1e-9);
    EXPECT_LT((dmp.start().position - paths[tool].front().position).norm(), 1e-9);
    EXPECT_LT((dmp.start().position - pose(tool, 0.0).position).norm(), 0.004);
    EXPECT_LT((dmp.goal().position - pose(tool, 3.0).position).norm(), 0.005);
    bp::CartesianDmpState state = dmp.initialState();
    double worst = 0.0;
    for (std::size_t i = 1; i < paths[tool].size(); ++i) {
      ASSERT_NE(dmp.step(state, 0.01), bp::DmpStatus::InvalidInput);
      worst = std::max(worst, (state.position.y - paths[tool][i].position).norm());
    }
    EXPECT_LT(worst, 0.01) << "tool " << tool;
  }
  EXPECT_THROW(recorder.resampled(0.0, 0.002), std::invalid_argument);
  bp::DemonstrationRecorder idle(1);
  for (int i = 0; i < 100; ++i) idle.add(0.01 * i, {pose(0, 0.0)});
  EXPECT_THROW(idle.resampled(0.01, 0.002), std::invalid_argument);
  EXPECT_THROW(bp::DemonstrationRecorder(0), std::invalid_argument);
}
