// The bottle task on the simulated WAM (thesis Sec. 6.2): the straight line knocks both bottles over and does not
// cross between them; an S through them knocks none and crosses; the tool keeps its height; the same rollout twice
// is the same to the bit; bad policies and bad files are refused by name, never a crash.
#include "bimanual_skills/tasks/policy_search_tasks.hpp"
#include "bimanual_skills/tasks/wam_bottles.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

namespace bt = bimanual_skills::tasks;

namespace {

std::string configFile(const std::string& name) {
  return std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/" + name;
}

bt::WamBottleConfig config() {
  return bt::WamBottleConfig::fromYamlFile(configFile("bottles_wam.yaml"));
}

/// The weights of an S in the line's units: y = amplitude sin(2π s) along the minimum-jerk s (left of the first
/// bottle for a positive amplitude, right of the second).
Eigen::VectorXd sPath(double amplitude) {
  Eigen::MatrixXd path(101, 2);
  for (int i = 0; i < 101; ++i) {
    const double s = bt::minimumJerk(i / 100.0);
    path(i, 0) = s;
    path(i, 1) = amplitude * std::sin(2.0 * M_PI * s);
  }
  return bt::DmpRollout::fit(path, 0.01, 10).parameters();
}

void print(const char* what, const bt::WamBottleRollout& r) {
  std::printf(
      "%s: %s, reward %.3f, %d down, L %.3f m, sides %+.3f %+.3f m, ik %.2g m, height %.3f m, tracking %.3f "
      "rad, %.2f s\n",
      what, bt::toString(r.outcome), r.reward, r.down, r.length, r.sides[0], r.sides[1], r.max_ik_error,
      r.max_height_error, r.max_tracking_error, r.wall_seconds);
}

}  // namespace

TEST(WamBottles, TheStraightLineKnocksBothOverAnSThroughThemNone) {
  bt::WamBottleTask task(config());
  EXPECT_NEAR(task.lineLength(), 0.6, 1e-12);
  EXPECT_NEAR(task.bottleOnLine(0).x(), 0.3, 1e-9);
  EXPECT_NEAR(task.bottleOnLine(1).x(), 0.7, 1e-9);
  const bt::WamBottleRollout line = task.run(task.initialParameters(), 1);
  print("straight line", line);
  ASSERT_EQ(line.outcome, bt::FoldOutcome::Ok) << line.reason;
  EXPECT_EQ(line.down, 2);
  EXPECT_FALSE(line.crossed);
  EXPECT_FALSE(line.satisfactory);
  EXPECT_NEAR(line.reward, -4.0 - 0.15 * line.length - 4.0, 1e-12);
  EXPECT_GT(line.length, 0.55);
  EXPECT_LT(line.max_ik_error, 1e-3);
  // The tool reaches the goal.
  EXPECT_LT((line.tool_path.rightCols(1) - task.fromLine(Eigen::Vector2d(1.0, 0.0))).norm(), 0.02);

  const bt::WamBottleRollout s = task.run(sPath(0.22), 1);
  print("S path", s);
  ASSERT_EQ(s.outcome, bt::FoldOutcome::Ok) << s.reason;
  EXPECT_EQ(s.down, 0);
  EXPECT_TRUE(s.crossed);
  EXPECT_GT(s.sides[0], 0.05);
  EXPECT_LT(s.sides[1], -0.05);
  EXPECT_TRUE(s.satisfactory);
  EXPECT_NEAR(s.reward, -0.15 * s.length, 1e-12);
  EXPECT_LT(s.max_height_error, 0.01);
  for (int b = 0; b < 2; ++b) EXPECT_GT(s.bottles[static_cast<std::size_t>(b)].linear()(2, 2), 0.999);

  // The same S the other way round passes each bottle on its other side: crossed too.
  const bt::WamBottleRollout mirrored = task.run(sPath(-0.22), 1);
  print("mirrored S", mirrored);
  EXPECT_TRUE(mirrored.satisfactory);
  // Both bottles on the left: no bottle down, not crossed: (6.18) takes 4, (6.17) does not.
  Eigen::VectorXd around = bt::DmpRollout::fit(
                               [] {
                                 Eigen::MatrixXd p(101, 2);
                                 for (int i = 0; i < 101; ++i) {
                                   const double u = bt::minimumJerk(i / 100.0);
                                   p(i, 0) = u;
                                   p(i, 1) = 0.25 * std::sin(M_PI * u);
                                 }
                                 return p;
                               }(),
                               0.01, 10)
                               .parameters();
  const bt::WamBottleRollout arc = task.run(around, 1);
  print("arc", arc);
  EXPECT_EQ(arc.down, 0);
  EXPECT_FALSE(arc.crossed);
  EXPECT_NEAR(arc.reward, -0.15 * arc.length - 4.0, 1e-12);
  bt::WamBottleConfig c617 = config();
  c617.crossing_term = false;
  bt::WamBottleTask task617(c617);
  EXPECT_NEAR(task617.run(around, 1).reward, -0.15 * arc.length, 1e-12);
}

TEST(WamBottles, TheSameRolloutTwiceIsTheSameToTheBit) {
  bt::WamBottleTask task(config());
  const Eigen::VectorXd theta = sPath(0.15);
  const bt::WamBottleRollout first = task.run(theta, 7);
  (void)task.run(task.initialParameters(), 3);  // knocks both over in between
  const bt::WamBottleRollout again = task.run(theta, 7);
  EXPECT_EQ(first.reward, again.reward);
  EXPECT_EQ(first.down, again.down);
  ASSERT_EQ(first.tool_path.cols(), again.tool_path.cols());
  EXPECT_EQ((first.tool_path - again.tool_path).cwiseAbs().maxCoeff(), 0.0);
}

TEST(WamBottles, BadPoliciesAndFilesAreRefusedByName) {
  bt::WamBottleTask task(config());
  const bt::WamBottleRollout short_policy = task.run(Eigen::VectorXd::Zero(5), 1);
  EXPECT_EQ(short_policy.outcome, bt::FoldOutcome::InvalidPolicy);
  EXPECT_EQ(short_policy.reward, task.config().failure_reward);
  Eigen::VectorXd nan = task.initialParameters();
  nan[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(task.run(nan, 1).outcome, bt::FoldOutcome::InvalidPolicy);
  // Absurd weights take the tool out of reach: a failed rollout, not a crash.
  const bt::WamBottleRollout absurd = task.run(Eigen::VectorXd::Constant(20, 1e4), 1);
  print("absurd", absurd);
  EXPECT_NE(absurd.outcome, bt::FoldOutcome::Ok);
  EXPECT_EQ(absurd.reward, task.config().failure_reward);
  EXPECT_FALSE(absurd.reason.empty());

  // The file the workers get reads back as the same configuration.
  const std::string copy = testing::TempDir() + "/bottles_copy.yaml";
  std::ofstream(copy) << config().toYaml();
  const bt::WamBottleConfig back = bt::WamBottleConfig::fromYamlFile(copy);
  EXPECT_EQ(back.sim_config, config().sim_config);
  EXPECT_EQ(back.start, config().start);
  EXPECT_EQ(back.duration, config().duration);
  EXPECT_NEAR(back.tilt, config().tilt, 1e-15);
  EXPECT_EQ(back.crossing_term, config().crossing_term);

  bt::WamBottleConfig c = config();
  c.goal.z() += 0.1;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = config();
  c.duration = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = config();
  c.arm = "middle";
  EXPECT_THROW(bt::WamBottleTask{c}, std::invalid_argument);
  // A scene with one bottle.
  const std::string scene = testing::TempDir() + "/one_bottle_sim.yaml";
  std::ofstream(scene) << "robot: " << configFile("robots/wam.yaml")
                       << "\ntable: {xyz: [0.55, 0.0, 0.0], size: [0.7, 1.2, 0.3]}\nobstacles:\n"
                          "  - {name: b, shape: cylinder, size: [0.035, 0.25], xyz: [0.55, -0.4, 0.275], mass: 0.4}\n";
  c = config();
  c.sim_config = scene;
  try {
    bt::WamBottleTask one(c);
    ADD_FAILURE() << "a scene with one bottle was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("two free obstacles"), std::string::npos) << e.what();
  }
  const std::string file = testing::TempDir() + "/bad_bottles.yaml";
  std::ofstream(file) << "sim_config: " << configFile("bottles_sim.yaml") << "\nduraton: 2\n";
  try {
    (void)bt::WamBottleConfig::fromYamlFile(file);
    ADD_FAILURE() << "a misspelt key was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("duraton"), std::string::npos) << e.what();
  }
}
