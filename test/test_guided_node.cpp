// rostest (test/guided.test): guided.launch with the scripted person over 3 runs. Checks bottles_guidance's phases
// in order in each run, that the right tool followed the raised hand between the bottles (runs.csv), every record's
// columns, and the policy learned from the runs (guided_policy.csv with the DMP's 20 weights, summary.json). In the
// third run, while the hand guides, the arm's controller is switched to hold (as a controller that leaves follow
// mode by itself would be): that run ends as Failed and is not learned from.
#include "bimanual_skills/GuidancePhase.h"
#include "bimanual_skills/SetControlMode.h"
#include "ros_wait.hpp"

#include <ros/ros.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

namespace {

std::string text(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::vector<std::string>> rows(const std::string& path) {
  std::vector<std::vector<std::string>> out;
  std::istringstream in(text(path));
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> fields;
    std::istringstream f(line);
    std::string field;
    while (std::getline(f, field, ',')) fields.push_back(field);
    out.push_back(fields);
  }
  return out;
}

}  // namespace

TEST(GuidedNode, TheScriptedPersonGuidesTheArmBetweenTheBottlesAndAPolicyIsLearned) {
  ros::NodeHandle node;
  std::vector<std::string> phases;  // "run K: phase"
  std::vector<std::string> outcomes;
  const auto sub = node.subscribe<bimanual_skills::GuidancePhase>(
      "/bottles_guidance/phase", 20, [&](const bimanual_skills::GuidancePhaseConstPtr& m) {
        const std::string p = "run " + std::to_string(m->run) + ": " + m->phase;
        if (phases.empty() || phases.back() != p) phases.push_back(p);
        if (!m->outcome.empty()) outcomes.push_back(m->outcome);
        EXPECT_EQ(m->runs, 3u);
      });
  std::string out;
  ASSERT_TRUE(bimanual_skills::test::spinUntil([&] { return ros::param::get("/bottles_guidance/out", out); }, 30.0));
  ASSERT_TRUE(bimanual_skills::test::spinUntil(
      [&] { return std::find(phases.begin(), phases.end(), "run 2: guided") != phases.end(); }, 200.0))
      << "run 2 never guided; phases seen: " << phases.size();
  bimanual_skills::SetControlMode hold;
  hold.request.mode = "hold";
  ASSERT_TRUE(ros::service::call("/right/set_mode", hold));
  ASSERT_TRUE(hold.response.success) << hold.response.message;
  ASSERT_TRUE(bimanual_skills::test::spinUntil([&] { return std::filesystem::exists(out + "/summary.json"); }, 120.0))
      << "no summary in " << out << "; phases seen: " << phases.size();
  for (const int run : {0, 1}) {
    const std::string prefix = "run " + std::to_string(run) + ": ";
    std::vector<std::string> seen;
    for (const std::string& p : phases) {
      if (p.rfind(prefix, 0) == 0) seen.push_back(p.substr(prefix.size()));
    }
    const std::vector<std::string> expected = {"approach", "line", "guided", "back", "arrived"};
    EXPECT_EQ(seen, expected) << "run " << run;
  }
  bimanual_skills::test::spinUntil([&] { return !phases.empty() && phases.back() == "run 3: done"; }, 5.0);
  EXPECT_EQ(phases.back(), "run 3: done");
  EXPECT_EQ(outcomes, (std::vector<std::string>{"Ok", "Ok", "Failed"}))
      << "each run's outcome, in the next run's first phase";
  auto runs = rows(out + "/runs.csv");
  ASSERT_EQ(runs.size(), 3u);
  ASSERT_EQ(runs[2].size(), 12u);
  EXPECT_EQ(runs[2][1], "Failed") << "the run whose controller left follow mode";
  EXPECT_EQ(runs[2][3], "-1") << "a failed run has no release";
  runs.pop_back();
  for (const auto& r : runs) {
    ASSERT_EQ(r.size(), 12u);
    EXPECT_EQ(r[1], "Ok") << "run " << r[0];
    const double take = std::atof(r[2].c_str()), release = std::atof(r[3].c_str()), end = std::atof(r[4].c_str());
    EXPECT_GT(take, 0.0);
    EXPECT_GT(release, take + 1.5) << "the hand guided for less than 1.5 s";
    EXPECT_GT(end, release);
    // The first bottle passed on the line's right, the second on its left: the S the person draws.
    EXPECT_LT(std::atof(r[6].c_str()), -0.03) << "run " << r[0];
    EXPECT_GT(std::atof(r[7].c_str()), 0.03) << "run " << r[0];
    EXPECT_EQ(r[8], "1");
    const auto record = rows(out + "/run_" + r[0] + ".csv");
    ASSERT_GT(record.size(), 300u);
    for (const auto& row : record) ASSERT_EQ(row.size(), 11u);
  }
  const auto weights = rows(out + "/guided_policy.csv");
  EXPECT_EQ(weights.size(), 20u);
  const std::string summary = text(out + "/summary.json");
  for (const char* key : {"\"guided_runs\": 2", "\"policy_reward\"", "\"policy_crossed\""}) {
    EXPECT_NE(summary.find(key), std::string::npos) << key << " in " << summary;
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_guided");
  ros::NodeHandle keep;
  return RUN_ALL_TESTS();
}
