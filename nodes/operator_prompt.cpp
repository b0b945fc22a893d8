// operator_prompt: the scene reset of a real robot. Serves ~reset (std_srvs/Trigger), the service bullet_sim's ~reset
// answers in simulation: it asks the person at the robot to lay the cloth flat and waits for Enter on this node's
// terminal, then answers success; "n" + Enter, a closed terminal or no answer within ~timeout answer failure (the
// rollout then fails with that reason and the learning goes on).
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "node_cli.hpp"

#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <poll.h>
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <mutex>
#include <string>

namespace bs = bimanual_skills;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills operator_prompt [_prompt:=TEXT] [_timeout:=S]\n"
    "\n"
    "The scene reset of a real robot for fold_learner _backend:=ros (give it _reset_service:=operator_prompt/reset):\n"
    "serves ~reset (std_srvs/Trigger). Each call prints the prompt on this terminal and waits for the operator:\n"
    "Enter answers success; \"n\" + Enter, a closed standard input, or no answer within the timeout answer failure\n"
    "with the reason. Run it in a terminal of its own (roslaunch: launch-prefix=\"xterm -e\").\n"
    "\n"
    "Parameters (private):\n"
    "  ~prompt   the text shown (default: lay the cloth flat on the table, grippers open, arms clear)\n"
    "  ~timeout  [s] longest wait for the operator (default 600)\n";

class OperatorPrompt {
 public:
  OperatorPrompt() : private_node_("~"), parameters_(private_node_, "operator_prompt") {
    prompt_ = parameters_.text("prompt",
                               "Lay the cloth flat on the table at its marks, open the grippers and clear the arms' "
                               "way; then press Enter (n + Enter: refuse)");
    timeout_ = parameters_.number("timeout", 600.0, 1.0, 86400.0);
    parameters_.warnUnknown();
    service_ = private_node_.advertiseService("reset", &OperatorPrompt::onReset, this);
    ROS_INFO("operator_prompt: serving %s", service_.getService().c_str());
  }

 private:
  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    const std::lock_guard<std::mutex> lock(mutex_);  // one prompt at a time
    std::printf("\n>>> %s\n", prompt_.c_str());
    std::fflush(stdout);
    pollfd input{STDIN_FILENO, POLLIN, 0};
    const int ready = poll(&input, 1, static_cast<int>(timeout_ * 1000.0));
    std::string line;
    if (ready == 0) {
      response.message = "no answer from the operator within " + std::to_string(static_cast<int>(timeout_)) + " s";
    } else if (ready < 0 || !std::getline(std::cin, line)) {
      response.message = "no operator: standard input is closed";
    } else if (!line.empty() && (line[0] == 'n' || line[0] == 'N')) {
      response.message = "the operator refused the reset";
    } else {
      response.success = true;
      response.message = "the operator laid the cloth flat";
    }
    ROS_INFO("operator_prompt: %s", response.message.c_str());
    return true;
  }

  ros::NodeHandle private_node_;
  bs::ros_layer::ParameterReader parameters_;
  std::string prompt_;
  double timeout_ = 600.0;
  ros::ServiceServer service_;
  std::mutex mutex_;
};

}  // namespace

int main(int argc, char** argv) {
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "operator_prompt");
  try {
    OperatorPrompt node;
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("operator_prompt: %s", e.what());
    return 1;
  }
  return 0;
}
