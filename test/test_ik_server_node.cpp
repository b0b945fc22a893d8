// rostest of ik_server: correct answers (checked by FK), every kind of bad input answered with its code, and 1000
// requests from 4 concurrent clients all answered correctly, with the throughput reported. The clients are
// persistent: a non-persistent roscpp call fails now and then although the server answered (ros/ros_comm#1976).
#include "bimanual_skills/SolveFk.h"
#include "bimanual_skills/SolveIk.h"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/pose_error.hpp"
#include "cli/pinned_numerics.hpp"

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_eigen/tf2_eigen.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace bk = bimanual_skills::kinematics;
using bimanual_skills::SolveFk;
using bimanual_skills::SolveIk;

namespace {

struct Arm {
  std::string name;
  bk::ChainModel model;
};

Arm arm(const std::string& name) {
  std::string description;
  if (!ros::param::get("/robot_description", description)) throw std::runtime_error("no robot_description");
  return {name, bk::ChainModel::fromUrdfString(description, name + "_wam_base", name + "_wam_tool")};
}

geometry_msgs::PoseStamped poseMsg(const Eigen::Isometry3d& T, const std::string& frame) {
  geometry_msgs::PoseStamped msg;
  msg.header.frame_id = frame;
  msg.pose = tf2::toMsg(T);
  return msg;
}

/// Max pose-error component between FK of the response and the target (both in the arm's base frame).
double solutionError(const bk::ChainModel& model, const SolveIk::Response& response, const Eigen::Isometry3d& target) {
  if (response.solution.position.size() != static_cast<std::size_t>(model.nq())) return INFINITY;
  bk::ChainData data(model);
  const Eigen::Map<const Eigen::VectorXd> q(response.solution.position.data(), model.nq());
  if (bk::forwardKinematics(model, data, q) != bk::KinematicsStatus::Success) return INFINITY;
  Eigen::VectorXd e(6);
  bk::poseError(data.tipPose(), target, bk::TaskMode::Pose, e);
  return e.cwiseAbs().maxCoeff();
}

SolveIk::Request validRequest(const bk::ChainModel& model, std::mt19937& rng, Eigen::Isometry3d& target) {
  bk::ChainData data(model);
  EXPECT_EQ(bk::forwardKinematics(model, data, randomWithinLimits(model, rng)), bk::KinematicsStatus::Success);
  target = data.tipPose();
  SolveIk::Request request;
  request.target = poseMsg(target, model.baseLink());
  request.timeout = 1.0;
  return request;
}

SolveIk::Response call(ros::ServiceClient& client, SolveIk::Request request) {
  SolveIk srv;
  srv.request = std::move(request);
  EXPECT_TRUE(client.call(srv)) << "service call failed";
  return srv.response;
}

}  // namespace

TEST(IkServer, SolvesTargetsInTheBaseAndInTheWorldFrame) {
  ASSERT_TRUE(ros::service::waitForService("/left/solve_ik", ros::Duration(30.0)));
  ros::NodeHandle node;
  auto client = node.serviceClient<SolveIk>("/left/solve_ik", true);
  const Arm left = arm("left");
  std::mt19937 rng(11);
  Eigen::Isometry3d target;
  SolveIk::Request request = validRequest(left.model, rng, target);
  SolveIk::Response response = call(client, request);
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  EXPECT_LE(solutionError(left.model, response, target), 1e-5);
  EXPECT_TRUE(
      left.model.withinLimits(Eigen::Map<const Eigen::VectorXd>(response.solution.position.data(), left.model.nq())));
  EXPECT_EQ(response.solution.name.front(), "left_wam_joint1");
  // The same pose in the world frame: the left base stands at y = +0.4 (config/robots/wam/placement.yaml), via tf.
  request.target = poseMsg(Eigen::Translation3d(0.0, 0.4, 0.0) * target, "world");
  request.method = "ED";
  response = call(client, request);
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  EXPECT_LE(solutionError(left.model, response, target), 1e-5);
}

TEST(IkServer, BadInputGetsACodeNotACrash) {
  ASSERT_TRUE(ros::service::waitForService("/right/solve_ik", ros::Duration(30.0)));
  ros::NodeHandle node;
  auto client = node.serviceClient<SolveIk>("/right/solve_ik", true);
  const Arm right = arm("right");
  std::mt19937 rng(12);
  Eigen::Isometry3d target;
  const SolveIk::Request valid = validRequest(right.model, rng, target);
  const auto expectCode = [&](SolveIk::Request request, int code, const char* what) {
    const SolveIk::Response response = call(client, std::move(request));
    EXPECT_EQ(response.error_code, code) << what << ": " << response.message;
    EXPECT_FALSE(response.message.empty()) << what;
  };
  SolveIk::Request r = valid;
  r.target.pose.position.x = std::nan("");
  expectCode(r, SolveIk::Response::INVALID_INPUT, "NaN position");
  r = valid;
  r.target.pose.orientation.w = INFINITY;
  expectCode(r, SolveIk::Response::INVALID_INPUT, "Inf quaternion");
  r = valid;
  r.target.pose.orientation = geometry_msgs::Quaternion();
  expectCode(r, SolveIk::Response::INVALID_INPUT, "zero quaternion");
  r = valid;
  r.target.pose.orientation.x = 0.5;
  r.target.pose.orientation.y = 0.5;
  r.target.pose.orientation.z = 0.5;
  r.target.pose.orientation.w = 1.0;
  expectCode(r, SolveIk::Response::INVALID_INPUT, "unnormalised quaternion");
  r = valid;
  r.target.header.frame_id = "no_such_frame";
  expectCode(r, SolveIk::Response::FRAME_TRANSFORM_FAILURE, "unknown frame");
  r = valid;
  r.tip_link = "no_such_link";
  expectCode(r, SolveIk::Response::INVALID_LINK_NAME, "unknown tip link");
  r = valid;
  r.tip_link = "left_wam_tool";  // exists, but not below right_wam_base
  expectCode(r, SolveIk::Response::INVALID_LINK_NAME, "tip on the other arm");
  r = valid;
  r.method = "XYZ";
  expectCode(r, SolveIk::Response::INVALID_INPUT, "unknown method");
  r = valid;
  r.seed.position = {0.0, 0.1, 0.2};
  expectCode(r, SolveIk::Response::INVALID_ROBOT_STATE, "seed of the wrong size");
  r = valid;
  r.seed.name = {"left_wam_joint1", "elbow"};
  r.seed.position = {0.0, 0.1};
  expectCode(r, SolveIk::Response::INVALID_ROBOT_STATE, "seed naming none of the arm's joints");
  r = valid;
  r.seed.position = {0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0};
  expectCode(r, SolveIk::Response::INVALID_ROBOT_STATE, "seed outside the limits");
  r = valid;
  r.seed.position = {0.0, 0.0, std::nan(""), 1.0, 0.0, 0.0, 0.0};
  expectCode(r, SolveIk::Response::INVALID_INPUT, "NaN seed");
  r = valid;
  r.timeout = -1.0;
  expectCode(r, SolveIk::Response::INVALID_INPUT, "negative timeout");
  r = valid;
  r.timeout = std::nan("");
  expectCode(r, SolveIk::Response::INVALID_INPUT, "NaN timeout");
  // Unreachable: answered at once with the best residual.
  r = valid;
  r.target.pose.position.x = 3.0;
  SolveIk::Response response = call(client, r);
  EXPECT_EQ(response.error_code, SolveIk::Response::NO_IK_SOLUTION) << response.message;
  EXPECT_GT(response.residual, 1.0);
  EXPECT_EQ(response.solution.position.size(), 7U);
  // Within reach but not attainable in the time given: TIMED_OUT, with the best attempt.
  r = valid;
  r.target.pose.position.x = 0.0;
  r.target.pose.position.y = 0.0;
  r.target.pose.position.z = 0.2;  // inside the base
  r.timeout = 0.01;
  response = call(client, r);
  EXPECT_EQ(response.error_code, SolveIk::Response::TIMED_OUT) << response.message;
  EXPECT_GT(response.residual, 0.0);
  // Zero timeout means the default; a huge one is capped and the answer says so.
  r = valid;
  r.timeout = 0.0;
  response = call(client, r);
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  r.timeout = 1e9;
  response = call(client, r);
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  EXPECT_NE(response.message.find("capped"), std::string::npos) << response.message;
  // The server is still healthy.
  response = call(client, valid);
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS);
  EXPECT_LE(solutionError(right.model, response, target), 1e-5);
}

TEST(IkServer, ClosestAndAllModes) {
  ASSERT_TRUE(ros::service::waitForService("/left/solve_ik", ros::Duration(30.0)));
  ros::NodeHandle node;
  auto client = node.serviceClient<SolveIk>("/left/solve_ik", true);
  const Arm left = arm("left");
  std::mt19937 rng(13);
  Eigen::Isometry3d target;
  SolveIk::Request request = validRequest(left.model, rng, target);
  request.method = "ED";
  request.timeout = 0.05;
  request.seed.position = {0.5, -0.5, 0.5, 1.0, -0.5, 0.5, -0.5};
  const Eigen::Map<const Eigen::VectorXd> seed(request.seed.position.data(), 7);
  const SolveIk::Response first = call(client, request);
  request.mode = "closest";
  const SolveIk::Response closest = call(client, request);
  request.mode = "all";
  const SolveIk::Response all = call(client, request);
  for (const SolveIk::Response* r : {&first, &closest, &all}) {
    ASSERT_EQ(r->error_code, SolveIk::Response::SUCCESS) << r->message;
    EXPECT_LE(solutionError(left.model, *r, target), 1e-5);
  }
  const auto distance = [&](const SolveIk::Response& r) {
    return (Eigen::Map<const Eigen::VectorXd>(r.solution.position.data(), 7) - seed).norm();
  };
  EXPECT_LE(distance(closest), distance(first) + 1e-12);
  EXPECT_GE(all.solutions.size(), 2U) << all.message;
  for (const auto& solution : all.solutions) {
    SolveIk::Response one;
    one.solution = solution;
    EXPECT_LE(solutionError(left.model, one, target), 1e-5);
  }
  request.mode = "fastest";
  EXPECT_EQ(call(client, request).error_code, SolveIk::Response::INVALID_INPUT);
}

TEST(IkServer, ForwardKinematicsService) {
  ASSERT_TRUE(ros::service::waitForService("/left/solve_fk", ros::Duration(30.0)));
  ros::NodeHandle node;
  auto client = node.serviceClient<SolveFk>("/left/solve_fk", true);
  SolveFk srv;
  srv.request.joint_state.position = {0.0, 0.0, 0.0, M_PI / 2, 0.0, 0.0, 0.0};
  srv.request.frame_id = "world";
  ASSERT_TRUE(client.call(srv));
  EXPECT_EQ(srv.response.error_code, SolveFk::Response::SUCCESS) << srv.response.message;
  // q4 = π/2: (0.405, 0, 0.595) from the shoulder, 0.346 m above the left base at y = 0.4.
  EXPECT_NEAR(srv.response.pose.pose.position.x, 0.405, 1e-9);
  EXPECT_NEAR(srv.response.pose.pose.position.y, 0.4, 1e-9);
  EXPECT_NEAR(srv.response.pose.pose.position.z, 0.941, 1e-9);
  srv.request.joint_state.position = {0.0, 0.0};
  ASSERT_TRUE(client.call(srv));
  EXPECT_EQ(srv.response.error_code, SolveFk::Response::INVALID_ROBOT_STATE);
  srv.request.joint_state.position = {0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0};
  srv.request.tip_link = "nowhere";
  ASSERT_TRUE(client.call(srv));
  EXPECT_EQ(srv.response.error_code, SolveFk::Response::INVALID_LINK_NAME);
}

TEST(IkServer, ThousandRequestsFromFourConcurrentClients) {
  ASSERT_TRUE(ros::service::waitForService("/left/solve_ik", ros::Duration(30.0)));
  ASSERT_TRUE(ros::service::waitForService("/right/solve_ik", ros::Duration(30.0)));
  constexpr int kClients = 4;
  constexpr int kPerClient = 250;
  const Arm left = arm("left");
  const Arm right = arm("right");
  std::atomic<int> answered{0}, correct{0};
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      const Arm& a = c % 2 == 0 ? left : right;
      ros::NodeHandle node;
      auto client = node.serviceClient<SolveIk>("/" + a.name + "/solve_ik", true);
      std::mt19937 rng(100 + c);
      for (int k = 0; k < kPerClient; ++k) {
        Eigen::Isometry3d target;
        SolveIk srv;
        srv.request = validRequest(a.model, rng, target);
        if (!client.call(srv)) continue;
        ++answered;
        if (srv.response.error_code == SolveIk::Response::SUCCESS &&
            solutionError(a.model, srv.response, target) <= 1e-5 &&
            a.model.withinLimits(Eigen::Map<const Eigen::VectorXd>(srv.response.solution.position.data(), 7))) {
          ++correct;
        }
      }
    });
  }
  for (auto& thread : clients) thread.join();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double throughput = kClients * kPerClient / seconds;
  std::printf("ik_server: %d requests from %d clients in %.2f s: %.0f requests/s, %d answered, %d correct\n",
              kClients * kPerClient, kClients, seconds, throughput, answered.load(), correct.load());
  RecordProperty("requests_per_second", std::to_string(throughput));
  EXPECT_EQ(answered.load(), kClients * kPerClient);
  EXPECT_EQ(correct.load(), kClients * kPerClient);
}

// A whole /joint_states message of the two-arm robot seeds either arm: the other arm's joints are skipped by name.
// solve_fk stays strict: a joint outside the chain is an error.
TEST(IkServer, FourteenJointSeedIsTakenByName) {
  ASSERT_TRUE(ros::service::waitForService("/left/solve_ik", ros::Duration(30.0)));
  const Arm left = arm("left");
  std::mt19937 rng(3);
  Eigen::Isometry3d target;
  SolveIk::Request request = validRequest(left.model, rng, target);
  request.mode = "closest";
  const Eigen::VectorXd q_left = bk::randomWithinLimits(left.model, rng);
  for (const std::string side : {"right", "left"}) {
    for (int i = 1; i <= 7; ++i) {
      request.seed.name.push_back(side + "_wam_joint" + std::to_string(i));
      request.seed.position.push_back(side == "left" ? q_left[i - 1] : 0.1 * i);
    }
  }
  ros::NodeHandle node;
  auto client = node.serviceClient<SolveIk>("/left/solve_ik", true);
  const SolveIk::Response response = call(client, request);
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  EXPECT_LE(solutionError(left.model, response, target), 1e-5);

  auto fk = node.serviceClient<SolveFk>("/left/solve_fk", true);
  SolveFk srv;
  srv.request.joint_state = request.seed;
  ASSERT_TRUE(fk.call(srv));
  EXPECT_EQ(srv.response.error_code, SolveFk::Response::INVALID_ROBOT_STATE) << srv.response.message;
}

// Each arm has its own callback queue and thread: a long request on the left arm (mode closest searches until its
// 2 s budget or max_attempts) does not delay the right arm's.
TEST(IkServer, ArmsAnswerInParallel) {
  ASSERT_TRUE(ros::service::waitForService("/left/solve_ik", ros::Duration(30.0)));
  ASSERT_TRUE(ros::service::waitForService("/right/solve_ik", ros::Duration(30.0)));
  const Arm left = arm("left"), right = arm("right");
  std::mt19937 rng(4);
  Eigen::Isometry3d long_target, short_target;
  SolveIk::Request long_request = validRequest(left.model, rng, long_target);
  long_request.mode = "closest";  // searches for the whole time budget
  long_request.timeout = 2.0;
  const SolveIk::Request short_request = validRequest(right.model, rng, short_target);
  std::atomic<double> long_end{0.0};
  const auto t0 = std::chrono::steady_clock::now();
  const auto since = [t0] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  std::thread long_call([&] {
    ros::NodeHandle node;
    auto client = node.serviceClient<SolveIk>("/left/solve_ik", true);
    const SolveIk::Response response = call(client, long_request);
    long_end = since();
    EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ros::NodeHandle node;
  auto client = node.serviceClient<SolveIk>("/right/solve_ik", true);
  const double short_start = since();
  const SolveIk::Response response = call(client, short_request);
  const double short_end = since();
  long_call.join();
  std::printf(
      "ik_server: the right arm answered in %.3f s while the left arm's long request ran (it ended at %.3f s)\n",
      short_end - short_start, long_end.load());
  EXPECT_EQ(response.error_code, SolveIk::Response::SUCCESS) << response.message;
  EXPECT_LT(short_end - short_start, 0.5);
  EXPECT_LT(short_end, long_end.load()) << "the short request waited for the long one";
  EXPECT_GT(long_end.load(), 0.5) << "the left request was not long (it ends at 2 s or max_attempts)";
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_ik_server");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
