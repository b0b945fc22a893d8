// Human-guided learning of the bottle task (thesis Sec. 6.2, Figs. 6.9, 6.13): the scripted person draws within its
// ranges and is the same for the same seed, the hand's S leaves the first bottle on its left, the robot's reference
// starts and ends on the line's ends within its speed limit and follows the hand between take and release; a short
// guided learning on the simulated WAM gives an average starting and ending where the line does and a DMP that keeps
// its sides of the bottles; bad configs are refused by name.
#include "bimanual_skills/sim/robot_file.hpp"
#include "bimanual_skills/tasks/human_guidance.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace bt = bimanual_skills::tasks;

namespace {

bt::WamBottleConfig config() {
  return bt::WamBottleConfig::fromYamlFile(std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/bottles_wam.yaml");
}

}  // namespace

TEST(ScriptedPerson, DrawsWithinItsRangesTheSameForTheSameSeed) {
  const bt::PersonConfig c;
  for (std::uint32_t seed = 1; seed < 30; ++seed) {
    const bt::ScriptedPerson p(c, 0.6, seed), q(c, 0.6, seed);
    EXPECT_EQ(p.take(), q.take());
    EXPECT_EQ(p.cameraPoints().back().point, q.cameraPoints().back().point);
    EXPECT_GE(p.take(), c.take_min);
    EXPECT_LE(p.take(), c.take_max);
    EXPECT_GE(p.release(), c.release_min);
    EXPECT_LE(p.release(), c.release_max);
    EXPECT_GE(p.amplitude(), c.amplitude_min);
    EXPECT_LE(p.amplitude(), c.amplitude_max);
    EXPECT_GE(p.guidedSeconds(), c.guided_min);
    EXPECT_LE(p.guidedSeconds(), c.guided_max);
    // 10 Hz points from the take to the release.
    ASSERT_EQ(p.cameraPoints().size(), static_cast<std::size_t>(std::floor(p.guidedSeconds() * 10.0)) + 1);
    EXPECT_DOUBLE_EQ(p.cameraPoints()[3].time, 0.3);
    EXPECT_TRUE(p.intended(0.0).isApprox(Eigen::Vector2d(p.take(), 0.0)));
    EXPECT_NEAR(p.intended(p.guidedSeconds()).x(), p.release(), 1e-12);
    EXPECT_NEAR(p.intended(p.guidedSeconds()).y(), 0.0, 1e-12);
  }
  EXPECT_NE(bt::ScriptedPerson(c, 0.6, 1).take(), bt::ScriptedPerson(c, 0.6, 2).take());
}

TEST(ScriptedPerson, TheHandsSLeavesTheFirstBottleOnItsLeft) {
  const bt::ScriptedPerson p(bt::PersonConfig{}, 0.6, 7);
  // Where the intended hand passes x = 0.3 and x = 0.7 (the bottles): right of the line, then left.
  double y1 = 0.0, y2 = 0.0;
  for (double t = 0.0; t < p.guidedSeconds(); t += 1e-3) {
    const Eigen::Vector2d h = p.intended(t), next = p.intended(t + 1e-3);
    if (h.x() <= 0.3 && next.x() > 0.3) y1 = h.y();
    if (h.x() <= 0.7 && next.x() > 0.7) y2 = h.y();
  }
  EXPECT_LT(y1, -0.5 * p.amplitude());
  EXPECT_GT(y2, 0.5 * p.amplitude());
  // The camera's points scatter about the intended hand by its noise and the tremor (5 mm + 3 mm of 0.6 m).
  double worst = 0.0;
  for (const bt::HandPoint& h : p.cameraPoints()) worst = std::max(worst, (h.point - p.intended(h.time)).norm());
  EXPECT_GT(worst, 0.002 / 0.6);
  EXPECT_LT(worst, 0.04 / 0.6);
}

TEST(GuidanceFollower, FollowsTheRaisedHandGoesBackToTheLineAndArrivesWithoutAllocating) {
  bt::GuidanceConfig g;
  bt::GuidanceFollower f(g);
  const double dt = 1e-3;
  // Never raised: along the line, y = 0, arriving at rest on the goal within 3 s of its target (to 1e-6).
  int k = 0;
  {
    bimanual_skills::testing::NoAllocGuard guard;
    while (f.step(dt, false, Eigen::Vector2d::Zero()) != bt::GuidanceFollower::Phase::Arrived && k < 10000) ++k;
  }
  EXPECT_GT(k * dt, 1.0 / g.line_speed);
  EXPECT_LT(k * dt, 1.0 / g.line_speed + 3.0);
  EXPECT_EQ(f.position(), Eigen::Vector2d(1.0, 0.0));
  EXPECT_EQ(f.velocity(), Eigen::Vector2d::Zero());
  // Raised: the reference converges on the hand (critically damped: within 1 % after 7 lags), NaN points ignored.
  f.reset();
  for (int k = 0; k < 400; ++k) f.step(dt, false, Eigen::Vector2d::Zero());
  EXPECT_EQ(f.phase(), bt::GuidanceFollower::Phase::Line);
  const Eigen::Vector2d hand(0.2, -0.1);
  for (int k = 0; k < 7 * 150; ++k) f.step(dt, true, k % 10 == 0 ? Eigen::Vector2d(NAN, 0.0) : hand);
  EXPECT_EQ(f.phase(), bt::GuidanceFollower::Phase::Guided);
  EXPECT_LT((f.position() - hand).norm(), 0.01 * hand.norm());
  // Lowered: back to the line at the reference's x; a hand raised again is not followed.
  f.step(dt, false, hand);
  EXPECT_EQ(f.phase(), bt::GuidanceFollower::Phase::Back);
  EXPECT_NEAR(f.target().x(), hand.x(), 5e-3);
  EXPECT_EQ(f.target().y(), 0.0);
  for (int k = 0; k < 2000; ++k) f.step(dt, true, Eigen::Vector2d(0.5, 0.3));
  EXPECT_EQ(f.target().y(), 0.0);
  EXPECT_LT(std::abs(f.position().y()), 1e-3);
  // The speed cap holds for a far hand.
  f.reset();
  double fastest = 0.0;
  for (int k = 0; k < 2000; ++k) {
    f.step(dt, true, Eigen::Vector2d(1.0, 1.0));
    fastest = std::max(fastest, f.velocity().norm());
  }
  EXPECT_LE(fastest, g.max_speed + 1e-12);
  EXPECT_GT(fastest, 0.99 * g.max_speed);
  g.lag = 0.0;
  EXPECT_THROW(bt::GuidanceFollower{g}, std::invalid_argument);
}

TEST(GuidedReference, RunsFromStartToGoalFollowingTheHandBetweenTakeAndRelease) {
  const bt::ScriptedPerson p(bt::PersonConfig{}, 0.6, 11);
  const bt::GuidanceConfig g;
  const bt::GuidedReference r = bt::guidedReference(p, g, 1e-3);
  ASSERT_GT(r.path.cols(), 1000);
  EXPECT_EQ(r.path.col(0), Eigen::Vector2d::Zero());
  EXPECT_EQ(r.path.col(r.path.cols() - 1), Eigen::Vector2d(1.0, 0.0));
  EXPECT_NEAR(r.take * 1e-3, p.take() / g.line_speed, 2e-3);
  EXPECT_NEAR((r.release - r.take) * 1e-3, p.guidedSeconds(), 2e-3);
  double fastest = 0.0, lowest = 0.0, highest = 0.0;
  for (Eigen::Index i = 1; i < r.path.cols(); ++i) {
    fastest = std::max(fastest, (r.path.col(i) - r.path.col(i - 1)).norm() / 1e-3);
    if (i > r.take && i < r.release) {
      lowest = std::min(lowest, r.path(1, i));
      highest = std::max(highest, r.path(1, i));
    }
  }
  EXPECT_LE(fastest, g.max_speed + 1e-9);
  EXPECT_LT(lowest, -0.7 * p.amplitude());  // the follower reaches most of the hand's S
  EXPECT_GT(highest, 0.7 * p.amplitude());
  // Off the guidance the reference stays on the line before the take.
  EXPECT_LT(r.path.row(1).head(r.take).cwiseAbs().maxCoeff(), 1e-12);
  const bt::GuidedReference again = bt::guidedReference(p, g, 1e-3);
  EXPECT_EQ(again.path, r.path);
}

TEST(GuidedReference, BadConfigsAreRefusedByName) {
  const bt::ScriptedPerson p(bt::PersonConfig{}, 0.6, 3);
  bt::GuidanceConfig g;
  EXPECT_THROW(bt::guidedReference(p, g, 0.0), std::invalid_argument);
  g.max_seconds = 1.0;
  try {
    bt::guidedReference(p, g, 1e-3);
    ADD_FAILURE() << "a reference that cannot reach the goal in 1 s was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("did not reach the goal"), std::string::npos) << e.what();
  }
  g = {};
  g.lag = -1.0;
  EXPECT_THROW(g.validate(), std::invalid_argument);
  bt::PersonConfig c;
  c.release_min = 0.1;
  EXPECT_THROW(bt::ScriptedPerson(c, 0.6, 1), std::invalid_argument);
  c = {};
  c.pace_unevenness = 1.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  EXPECT_THROW(bt::ScriptedPerson(bt::PersonConfig{}, 0.0, 1), std::invalid_argument);
  bt::GuidedLearningConfig l;
  l.runs = 1;
  EXPECT_THROW(l.validate(), std::invalid_argument);
}

TEST(GuidedLearning, AShortSetOnTheArmAveragesIntoADmpThatKeepsItsSides) {
  bt::WamBottleTask task(config());
  bt::GuidedLearningConfig c;
  c.runs = 4;
  c.alignment.samples = 60;
  const bt::GuidedLearning l = bt::learnFromGuidance(task, c, 100);
  ASSERT_EQ(l.runs.size(), 4u);
  ASSERT_GE(l.ok_runs, 2);
  EXPECT_NEAR(l.weights.sum(), 1.0, 1e-12);
  EXPECT_EQ(l.average.rows(), 3 * 60 - 2);
  EXPECT_LT(l.average.row(0).norm(), 0.02);
  EXPECT_LT((l.average.row(l.average.rows() - 1) - Eigen::RowVector2d(1.0, 0.0)).norm(), 0.02);
  for (Eigen::Index i = 1; i < l.average_times.size(); ++i) ASSERT_GT(l.average_times[i], l.average_times[i - 1]);
  ASSERT_EQ(l.theta.size(), 20);
  ASSERT_EQ(l.policy.outcome, bt::FoldOutcome::Ok) << l.policy.reason;
  // The guided runs and the learned policy pass the first bottle on the line's right, the second on its left.
  for (const bt::GuidedRun& r : l.runs) {
    if (r.rollout.outcome != bt::FoldOutcome::Ok) continue;
    EXPECT_LT(r.rollout.sides[0], 0.0) << "seed " << r.seed;
    EXPECT_GT(r.rollout.sides[1], 0.0) << "seed " << r.seed;
  }
  EXPECT_LT(l.policy.sides[0], 0.0);
  EXPECT_GT(l.policy.sides[1], 0.0);
  EXPECT_TRUE(l.policy.crossed);
  // The alignment brought each guided part's curves closer together.
  EXPECT_LE(l.alignment[1].cost_after, l.alignment[1].cost_before);
}

TEST(GuidedLearning, TheGuidedRobotFileStartsTheArmAtTheTasksStartPosture) {
  // guided.launch's robot file (config/robots/wam_guided.yaml) starts the right arm where WamBottleTask does.
  bt::WamBottleTask task(config());
  const bimanual_skills::sim::RobotFile robot = bimanual_skills::sim::RobotFile::fromYamlFile(
      std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/robots/wam_guided.yaml");
  const bimanual_skills::sim::RobotArm* arm = robot.arm("right");
  ASSERT_NE(arm, nullptr);
  const Eigen::VectorXd q = task.starts()[static_cast<std::size_t>(task.arm())];
  ASSERT_EQ(arm->start.size(), q.size());
  EXPECT_LT((arm->start - q).cwiseAbs().maxCoeff(), 1e-5) << "task's start: " << q.transpose();
}
