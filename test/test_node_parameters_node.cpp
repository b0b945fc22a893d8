// rostest (test/node_parameters.test): the nodes refuse mistyped and out-of-range private parameters at start with
// the parameter's name and the reason (exit status non-zero, nothing half-started), and warn about keys they do not
// know. Each node runs as a child process against the test's master.
#include "cli/pinned_numerics.hpp"

#include <gtest/gtest.h>
#include <ros/ros.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct NodeRun {
  int status = -1;
  std::string output;
};

/// Runs `command` (at most `seconds`), its output captured.
NodeRun run(const std::string& command, int seconds) {
  const std::string log = "/tmp/node_parameters_" + std::to_string(::getpid()) + ".log";
  NodeRun r;
  const int status =
      std::system(("timeout -s INT " + std::to_string(seconds) + " " + command + " > " + log + " 2>&1").c_str());
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log);
  std::stringstream text;
  text << in.rdbuf();
  r.output = text.str();
  std::remove(log.c_str());
  return r;
}

void expectRefused(const NodeRun& r, const std::string& reason) {
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.status, 124) << "the node did not stop on a bad parameter:\n" << r.output;
  EXPECT_NE(r.output.find(reason), std::string::npos) << "expected '" << reason << "' in:\n" << r.output;
}

TEST(NodeParameters, OutOfRangeAndMistypedValuesStopTheNodeWithTheReason) {
  // Lists cannot be given on a command line: set on the master first.
  ros::param::set("/sim_d/hosted_controllers", std::vector<std::string>{"middle"});
  ros::param::set("/left/ctc_a/kp", std::vector<double>{1.0, 2.0});
  const std::string sim = BULLET_SIM, ik = IK_SERVER;
  const std::string ctc = std::string(CTC_CONTROLLER) + " __ns:=left _robot:=" + ROBOT_FILE;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {sim + " __name:=sim_a _realtime_factor:=-1", "parameter /sim_a/realtime_factor = -1 is out of range [0, 1000]"},
      {sim + " __name:=sim_b _lockstep:=maybe", "parameter /sim_b/lockstep must be true or false"},
      {sim + " __name:=sim_c _max_payload:=1e9", "parameter /sim_c/max_payload = 1000000000 is out of range [0, 1000]"},
      {sim + " __name:=sim_d", "unknown arm 'middle'"},
      {sim + " __name:=sim_f _loop_priority:=50 _realtime_factor:=0", "~loop_priority needs a paced loop"},
      {ctc + " __name:=ctc_a", "parameter /left/ctc_a/kp has 2 entries; it needs 7"},
      {ctc + " __name:=ctc_d _kv:=fast", "parameter /left/ctc_d/kv must be a number or a list of 7 numbers"},
      {ctc + " __name:=ctc_b _observer/fir_cutoff:=900.0",
       "parameter /left/ctc_b/observer/fir_cutoff = 900 is out of range"},
      {ctc + " __name:=ctc_c _initial_mode:=dance", "is not one of: gravity_compensation, hold"},
      {ik + " __name:=ik_a _max_timeout:=-3.0", "parameter /ik_a/max_timeout = -3 is out of range"},
      {ik + " __name:=ik_b _method:=XYZ", "parameter /ik_b/method = 'XYZ'"},
  };
  for (const auto& [command, reason] : cases) expectRefused(run(command, 30), reason);
}

TEST(NodeParameters, UnknownKeysAreWarnedAbout) {
  // A typo of realtime_factor: the node runs (stopped by SIGINT after a few seconds) and names the key.
  const NodeRun r = run(std::string(BULLET_SIM) + " __name:=sim_e _realtime_factr:=2.0", 8);
  EXPECT_NE(r.output.find("unknown parameter /sim_e/realtime_factr"), std::string::npos) << r.output;
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_node_parameters");
  return RUN_ALL_TESTS();
}
