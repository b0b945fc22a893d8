// The cart-table's ZMP preview control (control/zmp_preview.hpp) against the batch least-squares optimum of the
// same cost and against the cart-table's own equation by finite differences; the NAO's leg kinematics against its
// mirror symmetry and its inverse; the generated walks (tasks/nao_walking.hpp) against their plan.
#include "bimanual_skills/control/zmp_preview.hpp"
#include "bimanual_skills/kinematics/pose_error.hpp"
#include "bimanual_skills/tasks/nao_walking.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <Eigen/QR>

#include <cmath>
#include <random>

namespace bc = bimanual_skills::control;
namespace bk = bimanual_skills::kinematics;
namespace bt = bimanual_skills::tasks;

namespace {

const std::string kNaoUrdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/nao_legs.urdf";

/// A ZMP reference of steps: 0, then 0.05 from `first` s, −0.05 half a second later, 0 after another half (samples
/// at T).
Eigen::VectorXd stepReference(int samples, double period, double first) {
  Eigen::VectorXd r(samples);
  for (int k = 0; k < samples; ++k) {
    const double t = k * period - first;
    r[k] = t < 0.0 ? 0.0 : t < 0.5 ? 0.05 : t < 1.0 ? -0.05 : 0.0;
  }
  return r;
}

/// Runs the controller over r (padded with its last value) from rest: the ZMP and the CoM at each sample.
void run(const bc::ZmpPreviewController& controller, const Eigen::VectorXd& r, Eigen::VectorXd& zmp,
         Eigen::VectorXd& com) {
  const int n = controller.parameters().preview_steps, samples = static_cast<int>(r.size());
  Eigen::VectorXd padded(samples + n);
  padded << r, Eigen::VectorXd::Constant(n, r[samples - 1]);
  bc::ZmpPreviewController::State state;
  zmp.resize(samples);
  com.resize(samples);
  for (int k = 0; k < samples; ++k) {
    zmp[k] = controller.zmp(state);
    com[k] = state.x[0];
    ASSERT_EQ(controller.step(state, padded.segment(k, n + 1)), bc::ZmpPreviewStatus::Success);
  }
}

}  // namespace

TEST(ZmpPreview, TheGainsSolveTheRiccatiEquation) {
  const bc::ZmpPreviewController controller(bc::ZmpPreviewParameters{});
  EXPECT_GT(controller.integralGain(), 0.0);
  EXPECT_DOUBLE_EQ(controller.previewGains()[0], -controller.integralGain());
  // The preview gains fade: what lies a second ahead hardly matters.
  const Eigen::VectorXd& g = controller.previewGains();
  EXPECT_LT(std::abs(g[g.size() - 1]), 1e-3 * std::abs(g[0]));
}

TEST(ZmpPreview, MatchesTheBatchOptimumOfTheSameCost) {
  // min Σ_k Q_e (C x_k − r_k)² + R (u_k − u_{k−1})² over u_0 … u_{K−1} from rest, solved as one least-squares
  // problem: the preview controller, optimal for an infinite horizon with a finite preview, must give the same ZMP
  // far from the horizon's end. The reference stays 0 through the first preview window (the controller's sum over
  // absolute references is the incremental optimum's from rest only then).
  const bc::ZmpPreviewParameters parameters;
  const bc::ZmpPreviewController controller(parameters);
  const int samples = 500;
  const Eigen::VectorXd r = stepReference(samples, parameters.period, 2.0);
  Eigen::VectorXd zmp, com;
  run(controller, r, zmp, com);
  const int horizon = samples + 200;
  Eigen::VectorXd rr(horizon);
  rr << r, Eigen::VectorXd::Zero(200);
  // p_k = C x_k = Σ_{i<k} C A^{k−1−i} B u_i.
  Eigen::MatrixXd pu = Eigen::MatrixXd::Zero(horizon, horizon);
  Eigen::Matrix3d power = Eigen::Matrix3d::Identity();
  std::vector<double> markov(static_cast<std::size_t>(horizon));
  for (int m = 0; m < horizon; ++m) {
    markov[static_cast<std::size_t>(m)] = controller.c() * power * controller.b();
    power = controller.a() * power;
  }
  for (int k = 1; k < horizon; ++k) {
    for (int i = 0; i < k; ++i) pu(k, i) = markov[static_cast<std::size_t>(k - 1 - i)];
  }
  Eigen::MatrixXd d = Eigen::MatrixXd::Identity(horizon, horizon);
  for (int i = 1; i < horizon; ++i) d(i, i - 1) = -1.0;
  Eigen::MatrixXd a(2 * horizon, horizon);
  a << std::sqrt(parameters.tracking_weight) * pu, std::sqrt(parameters.input_weight) * d;
  Eigen::VectorXd b(2 * horizon);
  b << std::sqrt(parameters.tracking_weight) * rr, Eigen::VectorXd::Zero(horizon);
  const Eigen::VectorXd u = a.colPivHouseholderQr().solve(b);
  const Eigen::VectorXd batch = pu * u;
  const double largest = (batch.head(samples) - zmp).cwiseAbs().maxCoeff();
  std::printf("preview against the batch optimum: ZMP differs by at most %.2e m (steps of 0.05 m)\n", largest);
  EXPECT_LT(largest, 3e-5);  // what the preview's 1.6 s leaves out
  // Both anticipate the step at 2 s: the ZMP moves away from it first (the cart's CoM has to get going).
  EXPECT_LT(zmp.segment(180, 20).minCoeff(), -1e-3);
  // And settle on the reference.
  EXPECT_NEAR(zmp[samples - 1], 0.0, 1e-4);
  EXPECT_NEAR(zmp[245], 0.05, 5e-3);
}

TEST(ZmpPreview, TheZmpIsTheCartTablesOwn) {
  // p = c − z_c/g c̈ with c̈ by central differences of the CoM it produced: the controller's C x is the cart-table's
  // ZMP, not a number of its own.
  const bc::ZmpPreviewParameters parameters;
  const bc::ZmpPreviewController controller(parameters);
  const Eigen::VectorXd r = stepReference(300, parameters.period, 1.0);
  Eigen::VectorXd zmp, com;
  run(controller, r, zmp, com);
  const double t = parameters.period, z = parameters.com_height / parameters.gravity;
  double largest = 0.0;
  for (int k = 1; k + 1 < com.size(); ++k) {
    const double accel = (com[k + 1] - 2.0 * com[k] + com[k - 1]) / (t * t);
    largest = std::max(largest, std::abs(com[k] - z * accel - zmp[k]));
  }
  EXPECT_LT(largest, 2e-3);
}

TEST(ZmpPreview, BadInputLeavesTheStateAndAllocatesNothing) {
  const bc::ZmpPreviewController controller(bc::ZmpPreviewParameters{});
  const int n = controller.parameters().preview_steps;
  bc::ZmpPreviewController::State state;
  state.x << 0.01, 0.02, 0.03;
  const Eigen::VectorXd reference = Eigen::VectorXd::Constant(n + 1, 0.02), short_one = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd bad = reference;
  bad[3] = std::nan("");
  const bc::ZmpPreviewController::State before = state;
  {
    bimanual_skills::testing::NoAllocGuard guard;
    EXPECT_EQ(controller.step(state, short_one), bc::ZmpPreviewStatus::WrongSize);
    EXPECT_EQ(controller.step(state, bad), bc::ZmpPreviewStatus::NotFinite);
    EXPECT_EQ(state.x, before.x);
    EXPECT_EQ(controller.step(state, reference), bc::ZmpPreviewStatus::Success);
  }
  EXPECT_NE(state.x, before.x);
  bc::ZmpPreviewParameters wrong;
  wrong.com_height = -1.0;
  EXPECT_THROW(bc::ZmpPreviewController{wrong}, std::invalid_argument);
}

TEST(NaoLegs, TheModelIsTheNaosAndMirrored) {
  const bt::NaoLegs legs = bt::NaoLegs::fromUrdfFile(kNaoUrdf);
  bk::ChainData left(legs.left), right(legs.right);
  ASSERT_EQ(bk::forwardKinematics(legs.left, left, Eigen::VectorXd::Zero(6)), bk::KinematicsStatus::Success);
  // Straight legs: the sole 85 + 100 + 102.9 + 45.11 mm under the torso, 50 mm to the side.
  EXPECT_TRUE(left.tipPose().translation().isApprox(Eigen::Vector3d(0.0, 0.05, -0.33301), 1e-12));
  // The right leg is the left one mirrored in the sagittal plane: rolls turn the other way, HipYawPitch (one motor)
  // the same.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(-0.3, 0.3);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd q(6);
    for (int j = 0; j < 6; ++j) q[j] = angle(rng);
    Eigen::VectorXd mirrored = q;
    mirrored[1] = -q[1];
    mirrored[5] = -q[5];
    ASSERT_EQ(bk::forwardKinematics(legs.left, left, q), bk::KinematicsStatus::Success);
    ASSERT_EQ(bk::forwardKinematics(legs.right, right, mirrored), bk::KinematicsStatus::Success);
    const Eigen::Matrix3d flip = Eigen::Vector3d(1.0, -1.0, 1.0).asDiagonal();
    EXPECT_TRUE((flip * left.tipPose().translation()).isApprox(right.tipPose().translation(), 1e-12));
    EXPECT_TRUE((flip * left.tipPose().linear() * flip).isApprox(right.tipPose().linear(), 1e-12));
  }
  EXPECT_THROW(bt::NaoLegs::fromUrdfFile(BIMANUAL_SKILLS_SOURCE_DIR "/urdf/wam.urdf"), std::invalid_argument);
}

TEST(NaoLegs, InverseKinematicsReachesWhatForwardKinematicsGives) {
  const bt::NaoLegs legs = bt::NaoLegs::fromUrdfFile(kNaoUrdf);
  bk::ChainData data(legs.left);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::VectorXd start(6);
  start << 0.0, 0.0, -0.4, 0.8, -0.4, 0.0;
  int reached = 0;
  for (int trial = 0; trial < 50; ++trial) {
    // Walking-like postures: the knee bent, the rest near the middle.
    Eigen::VectorXd q(6);
    q << -0.3 + 0.4 * unit(rng), -0.2 + 0.4 * unit(rng), -0.9 + 0.7 * unit(rng), 0.3 + 1.0 * unit(rng),
        -0.7 + 0.6 * unit(rng), -0.2 + 0.4 * unit(rng);
    ASSERT_EQ(bk::forwardKinematics(legs.left, data, q), bk::KinematicsStatus::Success);
    const Eigen::Isometry3d target = data.tipPose();
    Eigen::VectorXd solved = start;
    const std::string why = bt::solveNaoLeg(legs.left, data, target, false, solved);
    if (!why.empty()) continue;
    ++reached;
    ASSERT_EQ(bk::forwardKinematics(legs.left, data, solved), bk::KinematicsStatus::Success);
    Eigen::VectorXd e(6);
    bk::poseError(data.tipPose(), target, bk::TaskMode::Pose, e);
    EXPECT_LT(e.norm(), 1e-9);
  }
  EXPECT_GE(reached, 45);
  // With HipYawPitch fixed, the other five reach the position and keep the sole parallel to the target's.
  Eigen::VectorXd q(6);
  q << 0.15, 0.05, -0.5, 0.9, -0.4, -0.05;
  ASSERT_EQ(bk::forwardKinematics(legs.left, data, q), bk::KinematicsStatus::Success);
  Eigen::Isometry3d target = data.tipPose();
  target.linear() = Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::VectorXd fixed = start;
  fixed[0] = 0.1;
  ASSERT_EQ(bt::solveNaoLeg(legs.left, data, target, true, fixed), "");
  EXPECT_DOUBLE_EQ(fixed[0], 0.1);
  ASSERT_EQ(bk::forwardKinematics(legs.left, data, fixed), bk::KinematicsStatus::Success);
  EXPECT_LT((data.tipPose().translation() - target.translation()).norm(), 1e-9);
  EXPECT_GT(data.tipPose().linear().col(2).dot(Eigen::Vector3d::UnitZ()), 1.0 - 1e-12);
  // Out of reach: a reason, not a crash.
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(0.0, 0.05, -0.5);
  Eigen::VectorXd q_far = start;
  EXPECT_NE(bt::solveNaoLeg(legs.left, data, far, false, q_far).find("out of reach"), std::string::npos);
}

TEST(NaoWalking, TheSolesFollowThePlanAndTheZmpItsReference) {
  const bt::NaoLegs legs = bt::NaoLegs::fromUrdfFile(kNaoUrdf);
  for (const double turn : {0.0, 0.1}) {
    bt::NaoWalkParameters parameters;
    parameters.turn = turn;
    const bt::NaoWalk walk = bt::generateNaoWalk(legs, parameters);
    ASSERT_EQ(walk.joints.cols(), 12);
    ASSERT_EQ(walk.step_starts.size(), 8u);
    bk::ChainData left(legs.left), right(legs.right);
    double sole_error = 0.0, zmp_error = 0.0, yaw_pitch = 0.0;
    for (Eigen::Index k = 0; k < walk.time.size(); ++k) {
      Eigen::Isometry3d torso = Eigen::Isometry3d::Identity();
      torso.translation() = walk.torso.row(k).head(3).transpose();
      torso.linear() = Eigen::AngleAxisd(walk.torso(k, 3), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      ASSERT_EQ(bk::forwardKinematics(legs.left, left, walk.joints.row(k).head(6).transpose()),
                bk::KinematicsStatus::Success);
      ASSERT_EQ(bk::forwardKinematics(legs.right, right, walk.joints.row(k).tail(6).transpose()),
                bk::KinematicsStatus::Success);
      sole_error = std::max(
          {sole_error, ((torso * left.tipPose()).translation() - walk.left_foot.row(k).head(3).transpose()).norm(),
           ((torso * right.tipPose()).translation() - walk.right_foot.row(k).head(3).transpose()).norm()});
      EXPECT_DOUBLE_EQ(walk.joints(k, 0), walk.joints(k, 6)) << "HipYawPitch is one motor";
      EXPECT_TRUE(legs.left.withinLimits(walk.joints.row(k).head(6).transpose(), 1e-9));
      EXPECT_TRUE(legs.right.withinLimits(walk.joints.row(k).tail(6).transpose(), 1e-9));
      zmp_error = std::max(zmp_error, (walk.zmp.row(k) - walk.zmp_reference.row(k)).norm());
      yaw_pitch = std::max(yaw_pitch, std::abs(walk.joints(k, 0)));
    }
    std::printf(
        "turn %.2f: soles within %.1e m of the plan, ZMP within %.1f mm of its reference, right sole's "
        "heading within %.4f rad, |HipYawPitch| up to %.3f rad\n",
        turn, sole_error, 1e3 * zmp_error, walk.right_heading_error, yaw_pitch);
    EXPECT_LT(sole_error, 1e-8);
    EXPECT_LT(zmp_error, 0.02);  // the ZMP runs ahead of its steps by design (preview), within the foot (~5 cm)
    // The walk ends where it started moving sideways: the CoM back between the feet.
    const Eigen::Index last = walk.time.size() - 1;
    EXPECT_LT(
        (walk.com.row(last) - 0.5 * (walk.left_foot.row(last).head(2) + walk.right_foot.row(last).head(2))).norm(),
        0.01);
    if (turn == 0.0) {
      EXPECT_LT(yaw_pitch, 1e-8);
      EXPECT_LT(walk.right_heading_error, 1e-8);
    } else {
      EXPECT_GT(yaw_pitch, 0.02);
      EXPECT_LT(walk.right_heading_error, 0.02);
    }
    const Eigen::MatrixXd stride = bt::naoStride(walk, 3, 100);
    EXPECT_EQ(stride.rows(), 100);
    EXPECT_THROW(bt::naoStride(walk, 8, 100), std::invalid_argument);
  }
}

TEST(NaoWalking, WalksTheLegsCannotFollowAreRefused) {
  const bt::NaoLegs legs = bt::NaoLegs::fromUrdfFile(kNaoUrdf);
  bt::NaoWalkParameters parameters;
  parameters.step_length = 0.5;
  try {
    bt::generateNaoWalk(legs, parameters);
    ADD_FAILURE() << "a 0.5 m step was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("step_length"), std::string::npos) << e.what();
  }
  parameters = bt::NaoWalkParameters();
  parameters.torso_height = 0.34;  // above the straight legs' 0.333 m
  try {
    bt::generateNaoWalk(legs, parameters);
    ADD_FAILURE() << "a torso above the straight legs was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("leg at t = "), std::string::npos) << e.what();
  }
}
