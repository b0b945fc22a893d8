// The scarf task on the simulated WAM (config/scarf_learning.yaml): the demonstration fails the way it was chosen to
// (the scarf not wound round the neck), a loop 4 cm tighter wins on the camera and on the mesh's ground truth, a
// rollout is repeatable bit for bit for a seed, the cost is the sum of its terms (the observer's term removable),
// the control part of every period allocates nothing, and bad policies and bad files get a clear answer.
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/tasks/scarf_task.hpp"
#include "testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

br::ScarfLearningConfig shipped() {
  return br::ScarfLearningConfig::fromYamlFile(BIMANUAL_SKILLS_SOURCE_DIR "/config/scarf_learning.yaml");
}

/// The demonstration's loop with another radius about the neck's axis (same angles, heights and timing).
std::vector<Eigen::Vector3d> withRadius(const std::vector<Eigen::Vector3d>& loop, double radius) {
  std::vector<Eigen::Vector3d> out;
  const Eigen::Vector2d neck(0.5, 0.4);  // config/scenes/mannequin.yaml
  for (const Eigen::Vector3d& p : loop) {
    const Eigen::Vector2d radial = (p.head<2>() - neck).normalized();
    out.emplace_back(neck.x() + radius * radial.x(), neck.y() + radius * radial.y(), p.z());
  }
  return out;
}

bt::ScarfRollout demonstration(bt::ScarfTask& task, std::uint32_t seed,
                               bimanual_skills::realtime::CycleProbe* probe = nullptr) {
  const int d = task.dofs();
  return task.run({Eigen::MatrixXd::Identity(d, d)}, task.demonstrationWeights(), seed, probe);
}

}  // namespace

TEST(ScarfTask, TheDemonstrationFailsAsChosenAndIsRepeatableAndTheControlAllocatesNothing) {
  bt::ScarfTask task(shipped().task);
  EXPECT_EQ(task.dofs(), 7);
  EXPECT_EQ(task.demonstrationWeights().size(), 7 * 25);
  bimanual_skills::realtime::ScopedCounterProbe<bimanual_skills::testing::AllocationCounter> probe;
  const bt::ScarfRollout r = demonstration(task, 1, &probe);
  ASSERT_EQ(r.outcome, bt::FoldOutcome::Ok) << r.reason;
  std::printf(
      "demonstration: cost %.3f (acceleration %.3f, camera %.3f, torque %.3f), d %.1f px (d_ref %.1f), "
      "winding %.2f rad, success %d; %.2f s simulated in %.2f s\n",
      r.cost, r.c_acceleration, r.c_cam, r.c_torque, r.camera.d, task.config().camera.d_ref, r.truth.winding,
      r.truth.success ? 1 : 0, r.simulated_seconds, r.wall_seconds);
  EXPECT_GT(r.cost, 3.0) << "the thesis' success threshold";
  EXPECT_FALSE(r.truth.wrapped);
  EXPECT_FALSE(r.truth.success);
  EXPECT_NEAR(r.cost, r.c_acceleration + r.c_cam + r.c_torque, 1e-12);
  EXPECT_NEAR(r.c_torque, task.config().torque_weight * r.mean_abs_torque, 1e-12);
  EXPECT_NEAR(r.c_acceleration, task.config().acceleration_weight * r.acceleration, 1e-12);
  EXPECT_GT(r.mean_abs_torque, 0.0);
  EXPECT_GT(r.mean_tool_force, 0.5) << "the scarf hangs from the tool";
  std::printf("observer as a force on the tool: mean error %.3f N, largest %.3f N; the scarf's force %.3f N mean\n",
              r.mean_force_error, r.max_force_error, r.mean_tool_force);
  EXPECT_GT(r.mean_force_error, 0.0);
  EXPECT_LE(r.mean_force_error, r.max_force_error);
  EXPECT_EQ(r.control_allocations, 0u);
  EXPECT_EQ(r.joint_path.cols(), r.path_times.size());
  EXPECT_GT(r.path_times.size(), 100);
  // The same seed, the same rollout, to the bit.
  const bt::ScarfRollout again = demonstration(task, 1);
  EXPECT_EQ(again.cost, r.cost);
  EXPECT_EQ(again.cloth_vertices, r.cloth_vertices);
  // Without the observer's term the cost is lower by exactly it.
  bt::ScarfTaskConfig without = task.config();
  without.torque_weight = 0.0;
  bt::ScarfTask plain(without);
  const bt::ScarfRollout p = demonstration(plain, 1);
  EXPECT_EQ(p.c_torque, 0.0);
  EXPECT_NEAR(p.cost, r.cost - r.c_torque, 1e-9);
  // The references a robot is sent (ScarfTask::plan) are the ones the rollout ran: the same accelerations to the bit,
  // the motion's last reference where its measured path ends up, and a truth of the final mesh as the rollout's.
  const bt::ScarfPlan plan = task.plan({Eigen::MatrixXd::Identity(7, 7)}, task.demonstrationWeights());
  ASSERT_EQ(plan.outcome, bt::FoldOutcome::Ok) << plan.reason;
  EXPECT_EQ(plan.acceleration_cost, r.acceleration);
  EXPECT_EQ(plan.position.cols(), plan.move_end - plan.move_start);
  EXPECT_NEAR(plan.end * plan.dt, r.simulated_seconds, 1e-9);
  EXPECT_LT((plan.position.rightCols(1) - r.joint_path.rightCols(1)).cwiseAbs().maxCoeff(), 0.02);
  EXPECT_EQ(task.truthOf(r.cloth_vertices).winding, r.truth.winding);
  EXPECT_THROW(task.truthOf(Eigen::Matrix3Xd::Zero(3, 5)), std::invalid_argument);
}

// The arms are driven by the robot path's controller (control::ArmController, as ctc_controller runs it): with the
// WAM's own velocity limits (2 rad/s) its monitor stops the demonstration where the hand knocks the mannequin's
// shoulder (a jolt of about 3 rad/s on the wrist), as the robot's would; the learning file's 3.5 rad/s, which
// scarf.launch gives ctc_controller too, lets it run.
TEST(ScarfTask, TheRobotPathsVelocityMonitorStopsTheJoltAtTheWAMsLimits) {
  bt::ScarfTaskConfig config = shipped().task;
  EXPECT_EQ(config.velocity_limit, 3.5);
  config.velocity_limit = 0.0;
  bt::ScarfTask task(config);
  const bt::ScarfRollout r = demonstration(task, 1);
  std::printf("the WAM's limits: %s: %s\n", bt::toString(r.outcome), r.reason.c_str());
  EXPECT_EQ(r.outcome, bt::FoldOutcome::ControllerFailed);
  EXPECT_NE(r.reason.find("over its velocity limit 2"), std::string::npos) << r.reason;
  EXPECT_EQ(r.cost, config.failure_cost);
  config.velocity_limit = std::nan("");
  EXPECT_THROW(bt::ScarfTask{config}, std::invalid_argument);
}

TEST(ScarfTask, ALoopFourCentimetresTighterWindsTheScarfOnTheCameraAndInTruth) {
  bt::ScarfTaskConfig config = shipped().task;
  config.demo_waypoints = withRadius(config.demo_waypoints, 0.17);
  bt::ScarfTask task(config);
  const bt::ScarfRollout r = demonstration(task, 1);
  ASSERT_EQ(r.outcome, bt::FoldOutcome::Ok) << r.reason;
  std::printf("0.17 m loop: cost %.3f, c_cam %.3f, d %.1f px, winding %.2f rad, hanging right %d left %d\n", r.cost,
              r.c_cam, r.camera.d, r.truth.winding, r.truth.hanging_right, r.truth.hanging_left);
  EXPECT_LT(r.cost, 3.0);
  EXPECT_TRUE(r.truth.wrapped);
  EXPECT_TRUE(r.truth.success);
  EXPECT_EQ(r.camera.hanging, 0);
}

// A camera that sees the arm (a robot's): after it lets go, while the scarf settles, the tool rises 0.15 m and the
// arm goes to clear_posture, out of the camera's view. The motion before the release is the one without the leave,
// so the scarf is too, to the bit (this simulator's arms touch the scarf only through the gripper). The posture and
// its time are checked.
TEST(ScarfTask, AfterItLetsGoTheArmRisesAndLeavesTheCamerasViewAndTheScarfIsTheSame) {
  bt::ScarfTaskConfig config = shipped().task;
  config.demo_waypoints = withRadius(config.demo_waypoints, 0.17);
  config.settle = 3.5;
  bt::ScarfTask stays(config);
  config.clear_posture = (Eigen::VectorXd(7) << -2.4, 1.9, 0.0, 3.0, 0.0, 0.0, 0.0).finished();
  config.clear_time = 3.0;
  bt::ScarfTask task(config);
  const bt::ScarfPlan plan = task.plan({Eigen::MatrixXd::Identity(7, 7)}, task.demonstrationWeights());
  ASSERT_EQ(plan.outcome, bt::FoldOutcome::Ok) << plan.reason;
  EXPECT_EQ(plan.clear_end - plan.release, 3000);
  EXPECT_EQ(plan.lift_end - plan.release, 750);
  EXPECT_EQ(plan.end - plan.release, 3500) << "the image when the scarf has settled, as without the leave";
  bimanual_skills::kinematics::ChainData at(task.armModel()), up(task.armModel());
  (void)bimanual_skills::kinematics::forwardKinematics(task.armModel(), at, plan.position.rightCols(1));
  (void)bimanual_skills::kinematics::forwardKinematics(task.armModel(), up, plan.lifted);
  const Eigen::Vector3d rise = task.basePose().linear() * (up.tipPose().translation() - at.tipPose().translation());
  EXPECT_LT((rise - Eigen::Vector3d(0.0, 0.0, 0.15)).norm(), 1e-4) << rise.transpose();
  const bt::ScarfRollout r = demonstration(task, 1), s = demonstration(stays, 1);
  ASSERT_EQ(r.outcome, bt::FoldOutcome::Ok) << r.reason;
  ASSERT_EQ(s.outcome, bt::FoldOutcome::Ok) << s.reason;
  std::printf("0.17 m loop, settled 3.5 s: cost %.3f, d %.1f px, winding %.2f rad; the arm left for %s\n", r.cost,
              r.camera.d, r.truth.winding, (std::ostringstream() << config.clear_posture.transpose()).str().c_str());
  EXPECT_NEAR(r.simulated_seconds, plan.end * plan.dt, 1e-9);
  EXPECT_LT((r.joint_path.rightCols(1) - config.clear_posture).cwiseAbs().maxCoeff(), 0.02);
  Eigen::Index lifted = 0;
  (r.path_times.array() - plan.lift_end * plan.dt).abs().minCoeff(&lifted);
  EXPECT_LT((r.joint_path.col(lifted) - plan.lifted).cwiseAbs().maxCoeff(), 0.05);
  EXPECT_LT((s.joint_path.rightCols(1) - plan.position.rightCols(1)).cwiseAbs().maxCoeff(), 0.02) << "it stayed";
  EXPECT_EQ(r.cloth_vertices, s.cloth_vertices);
  EXPECT_EQ(r.cost, s.cost);
  // The shipped learning of a camera that sees the arm is this one (the 0.21 m demonstration's loop).
  const br::ScarfLearningConfig hardware =
      br::ScarfLearningConfig::fromYamlFile(BIMANUAL_SKILLS_SOURCE_DIR "/config/scarf_hardware_learning.yaml");
  EXPECT_EQ(hardware.task.clear_posture, config.clear_posture);
  EXPECT_EQ(hardware.task.clear_time, config.clear_time);
  EXPECT_EQ(hardware.task.settle, config.settle);
  EXPECT_EQ(hardware.task.demo_waypoints, shipped().task.demo_waypoints);
  // The posture and its time go together, within the settling, and the posture is the arm's, within its limits.
  bt::ScarfTaskConfig bad = config;
  bad.clear_time = 0.0;
  EXPECT_THROW(bt::ScarfTask{bad}, std::invalid_argument);
  bad.clear_time = 4.0;
  EXPECT_THROW(bt::ScarfTask{bad}, std::invalid_argument);
  bad.clear_time = 0.003;  // its leave's first waypoint would come before the release
  EXPECT_THROW(bt::ScarfTask{bad}, std::invalid_argument);
  bad.clear_time = bt::ScarfTaskConfig::kMinClearTime;
  EXPECT_NO_THROW(bt::ScarfTask{bad});
  bad = config;
  bad.clear_posture = Eigen::VectorXd::Zero(6);
  EXPECT_THROW(bt::ScarfTask{bad}, std::invalid_argument);
  bad.clear_posture = config.clear_posture;
  bad.clear_posture[1] = 2.5;
  EXPECT_THROW(bt::ScarfTask{bad}, std::invalid_argument);
}

TEST(ScarfTask, BadPoliciesAndFilesGetAClearAnswer) {
  const br::ScarfLearningConfig config = shipped();
  br::ScarfRolloutTask task(config.task);
  const int d = task.task().dofs();
  // A policy with a NaN weight, one of the wrong size, garbage.
  Eigen::VectorXd weights = task.task().demonstrationWeights();
  weights[3] = std::numeric_limits<double>::quiet_NaN();
  const bt::ScarfRollout nan = task.task().run({Eigen::MatrixXd::Identity(d, d)}, weights, 1);
  EXPECT_EQ(nan.outcome, bt::FoldOutcome::InvalidPolicy);
  EXPECT_EQ(nan.cost, config.task.failure_cost);
  EXPECT_NE(nan.reason.find("weights"), std::string::npos) << nan.reason;
  EXPECT_EQ(task.task().plan({Eigen::MatrixXd::Identity(d, d)}, weights).outcome, bt::FoldOutcome::InvalidPolicy);
  // Weights that throw the arm beyond its joint limits: refused before any motion.
  const bt::ScarfPlan wild =
      task.task().plan({Eigen::MatrixXd::Identity(d, d)}, Eigen::VectorXd::Constant(weights.size(), 5e4));
  EXPECT_EQ(wild.outcome, bt::FoldOutcome::OutOfLimits) << wild.reason;
  const br::RolloutResult garbage = task.run(Eigen::VectorXd::Constant(5, 1.0), 1);
  EXPECT_FALSE(garbage.ok);
  EXPECT_EQ(garbage.outcome, "InvalidPolicy");
  EXPECT_EQ(garbage.reward, -config.task.failure_cost);
  EXPECT_EQ(garbage.terms.size(), static_cast<Eigen::Index>(br::ScarfRolloutTask::names().size()));
  // The rollout task's own parameters run the demonstration; a rollout worker's task (the registry's "scarf" of the
  // same file) gives the same result to the bit.
  const br::RolloutResult initial = task.run(task.initialParameters(), 1);
  EXPECT_TRUE(initial.ok) << initial.reason;
  EXPECT_EQ(initial.trajectory.rows(), 3);
  const br::RolloutResult worker =
      br::makeRolloutTask("scarf", BIMANUAL_SKILLS_SOURCE_DIR "/config/scarf_learning.yaml")
          ->run(task.initialParameters(), 1);
  EXPECT_EQ(worker.reward, initial.reward);
  EXPECT_EQ(worker.terms, initial.terms);
  EXPECT_THROW(br::makeRolloutTask("scarf", ""), std::invalid_argument);
  // Files and settings at fault are named.
  const auto refused = [](bt::ScarfTaskConfig c, const std::string& expected) {
    try {
      bt::ScarfTask t(c);
      ADD_FAILURE() << "accepted; expected a refusal naming " << expected;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  bt::ScarfTaskConfig c = config.task;
  c.arm = "third";
  refused(c, "third");
  c = config.task;
  c.kernels = 1;
  refused(c, "kernels");
  c = config.task;
  c.start = "/nonexistent/start.yaml";
  refused(c, "/nonexistent/start.yaml");
  c = config.task;
  c.demo_waypoints.push_back(Eigen::Vector3d(3.0, 0.0, 0.5));  // far out of reach
  refused(c, "waypoint 9");
  c = config.task;
  c.torque_weight = -1.0;
  refused(c, "torque_weight");
}

// The scene placed for the offset-wrist pair (scarf_learner _write_scarf_files): the turn and shift take the WAM's
// left base onto the offset-wrist arm's, the start puts that arm's tool where the placed scene holds the scarf's
// end, pointing as its own start does; the shipped files are that placement, and the demonstration stands to the
// arm as the WAM's does (the same waypoints relative to the base).
TEST(ScarfTask, TheSceneAndStartPlacedForAnotherPairStandToItsArmAsToTheWAMs) {
  const br::ScarfLearningConfig wam = shipped();
  const std::string robot = BIMANUAL_SKILLS_SOURCE_DIR "/config/robots/offset_wrist.yaml";
  const bt::ScarfPlacement placement = bt::scarfPlacementOn(wam.task, robot);
  EXPECT_NEAR(placement.yaw, -M_PI / 2, 1e-12);  // urdf/bimanual_offset_wrist.urdf's left base
  EXPECT_LT((placement.shift - Eigen::Vector3d(0.15, 0.75, 0.15)).norm(), 1e-12);
  const bt::ScarfTask wam_task(wam.task);
  const br::ScarfLearningConfig placed = br::ScarfLearningConfig::fromYamlFile(
      BIMANUAL_SKILLS_SOURCE_DIR "/config/robots/offset_wrist_scarf_learning.yaml");
  const bt::ScarfTask task(placed.task);
  // Every waypoint relative to the holding arm's base as the WAM's.
  ASSERT_EQ(placed.task.demo_waypoints.size(), wam.task.demo_waypoints.size());
  for (std::size_t k = 0; k < wam.task.demo_waypoints.size(); ++k) {
    EXPECT_LT((task.basePose().inverse() * placed.task.demo_waypoints[k] -
               wam_task.basePose().inverse() * wam.task.demo_waypoints[k])
                  .norm(),
              1e-5)
        << "waypoint " << k;
  }
  EXPECT_LT((task.mannequin().neck - placement.apply(wam_task.mannequin().neck)).norm(), 1e-5);
  EXPECT_LT((task.camera().pose.translation() - placement.apply(wam_task.camera().pose.translation())).norm(), 1e-5);
  // The start: the tool at the placed grasp, pointing as the robot file's start does (down).
  const Eigen::VectorXd start = bt::scarfStartOn(wam.task, robot);
  EXPECT_LT((start - task.startPosition()).norm(), 1e-5) << "the shipped start file is this solution";
  namespace bk = bimanual_skills::kinematics;
  bk::ChainData fk(task.armModel()), wam_fk(wam_task.armModel());
  (void)bk::forwardKinematics(task.armModel(), fk, start);
  (void)bk::forwardKinematics(wam_task.armModel(), wam_fk, wam_task.startPosition());
  const Eigen::Isometry3d tool = task.basePose() * fk.tipPose();
  EXPECT_LT((tool.translation() - placement.apply(wam_task.basePose() * wam_fk.tipPose().translation())).norm(), 1e-6);
  EXPECT_LT((tool.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-6) << "pointing down";
  // The WAM placed for itself: no turn, no shift.
  const bt::ScarfPlacement same = bt::scarfPlacementOn(wam.task, BIMANUAL_SKILLS_SOURCE_DIR "/config/robots/wam.yaml");
  EXPECT_NEAR(same.yaw, 0.0, 1e-12);
  EXPECT_LT(same.shift.norm(), 1e-12);
  EXPECT_THROW(
      {
        bt::ScarfTaskConfig right_less = wam.task;
        right_less.arm = "middle";
        (void)bt::scarfPlacementOn(right_less, robot);
      },
      std::invalid_argument);
}
