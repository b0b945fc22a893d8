// The configuration files of the simulator: config/plant.yaml and config/sim.yaml load; bad files are rejected with
// messages that name the file and the entry.
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/sim/plant_model.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "bimanual_skills/sim/sim_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace bs = bimanual_skills;
namespace fs = std::filesystem;
using bs::sim::PlantModel;
using bs::sim::SimConfig;

namespace {

const std::string kConfig = BIMANUAL_SKILLS_SOURCE_DIR "/config";

/// Writes `text` to a temporary file and returns its path.
std::string write(const std::string& name, const std::string& text) {
  const fs::path path = fs::temp_directory_path() / ("bimanual_skills_sim_" + name);
  std::ofstream(path) << text;
  return path.string();
}

template <typename Load>
std::string errorOf(Load load) {
  try {
    load();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}

const char* kGoodArm = R"(
    rotor_inertia: [0.1, 0.2]
    friction:
      - {joint: 1, static: 1.0, coulomb: 0.8, viscous: 0.5}
      - {joint: 2, static: 0.5, coulomb: 0.4, ripple: 0.1, ripple_frequency: 3, ripple_phase: [0, 1]}
)";

}  // namespace

TEST(SimConfigFiles, ThePlantFileDescribesBothWams) {
  const PlantModel plant = PlantModel::fromYamlFile(kConfig + "/plant.yaml");
  ASSERT_EQ(plant.arms.size(), 2u);
  for (const char* name : {"left", "right"}) {
    const bs::sim::ArmPlantParameters& arm = plant.arm(name);
    EXPECT_NO_THROW(arm.validate(7, name));
    ASSERT_EQ(arm.drives.size(), 5u);
    EXPECT_TRUE(arm.drives[1].isDifferential());
    EXPECT_EQ(arm.drives[1].first, 1);
    EXPECT_EQ(arm.drives[1].second, 2);
    EXPECT_TRUE(arm.drives[3].isDifferential());
    for (const bs::sim::Drive& d : arm.drives) {
      EXPECT_GT(d.friction.static_friction, d.friction.coulomb) << "stick-slip: static above Coulomb";
    }
    EXPECT_EQ(arm.rotor_inertia.size(), 7);
    EXPECT_TRUE(arm.saturate_torque);
  }
  EXPECT_NE(plant.arm("left").drives[0].friction.coulomb, plant.arm("right").drives[0].friction.coulomb);
  EXPECT_NE(errorOf([&] { plant.arm("middle"); }).find("middle"), std::string::npos);
}

TEST(SimConfigFiles, TheSimulationFileResolvesItsPaths) {
  const SimConfig config = SimConfig::fromYamlFile(kConfig + "/sim.yaml");
  EXPECT_TRUE(fs::exists(config.urdf_path)) << config.urdf_path;
  EXPECT_TRUE(fs::exists(config.plant_path)) << config.plant_path;
  EXPECT_DOUBLE_EQ(config.step, 0.001);
  ASSERT_EQ(config.arms.size(), 2u);
  EXPECT_EQ(config.arms[1].tip_link, "right_wam_tool");
  EXPECT_TRUE(config.has_table);
  EXPECT_NEAR(config.table.topCentre().z(), 0.15, 1e-12);
  ASSERT_TRUE(config.has_cloth);
  EXPECT_EQ(config.cloth.nodes_x, 20);
  EXPECT_EQ(config.cloth.nodes_y, 24);
  EXPECT_DOUBLE_EQ(config.cloth.length, 0.5);
  EXPECT_DOUBLE_EQ(config.cloth.width, 0.6);
  EXPECT_DOUBLE_EQ(config.cloth.mass, 0.22);
  EXPECT_NO_THROW(config.validate());
}

TEST(SimConfigFiles, BadPlantFilesNameTheFileAndTheEntry) {
  const auto plant = [&](const std::string& name, const std::string& arm) {
    const std::string path = write(name, "arms:\n  left:" + arm);
    return std::pair{path, errorOf([&] { PlantModel::fromYamlFile(path).arm("left").validate(2, "left"); })};
  };
  EXPECT_EQ(plant("good.yaml", kGoodArm).second, "no exception");
  struct Case {
    const char* file;
    std::string arm;
    const char* expected;
  };
  const std::string good = kGoodArm;
  const Case cases[] = {
      {"typo.yaml", good + "    viscosity: 3\n", "unknown entry 'viscosity'"},
      {"static.yaml", "\n    friction:\n      - {joint: 1, static: 0.5, coulomb: 0.8}\n      - {joint: 2}\n",
       "'static'"},
      {"number.yaml", "\n    friction:\n      - {joint: 1, coulomb: abc}\n      - {joint: 2}\n", "'coulomb'"},
      {"twice.yaml", "\n    friction:\n      - {joint: 1}\n      - {joint: 1}\n", "more than one"},
      {"missing.yaml", "\n    friction:\n      - {joint: 1}\n", "joint 2 has no friction entry"},
      {"range.yaml", "\n    friction:\n      - {joint: 1, hysteresis: 1.5}\n      - {joint: 2}\n", "'hysteresis'"},
      {"ratio.yaml", "\n    friction:\n      - {differential: [1, 2], ratio: -1}\n", "'ratio'"},
      {"size.yaml", "\n    rotor_inertia: [0.1, 0.2, 0.3]\n", "'rotor_inertia'"},
      {"drive.yaml", "\n    friction:\n      - {static: 1.0}\n", "needs 'joint'"},
  };
  for (const Case& c : cases) {
    const auto [path, message] = plant(c.file, c.arm);
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.file << ": " << message;
    // Sizes and completeness need the arm's joint count: checked when the simulation is built, not by the loader.
    if (std::string(c.expected).find("joint 2 has no") == std::string::npos &&
        std::string(c.expected) != "'rotor_inertia'") {
      EXPECT_NE(message.find(path), std::string::npos) << c.file << " names the file: " << message;
    }
  }
  EXPECT_NE(errorOf([] { PlantModel::fromYamlFile("/nonexistent/plant.yaml"); }).find("/nonexistent/plant.yaml"),
            std::string::npos);
  const std::string syntax = write("syntax.yaml", "arms: [left: {");
  EXPECT_NE(errorOf([&] { PlantModel::fromYamlFile(syntax); }).find(syntax), std::string::npos);
}

TEST(SimConfigFiles, BadSimulationFilesNameTheFileAndTheEntry) {
  const std::string plant = write("plant_for_sim.yaml", std::string("arms:\n  left:") + kGoodArm);
  const std::string urdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/bimanual_wam.urdf";
  const std::string head = "urdf: " + urdf + "\nplant: " + plant + "\n";
  const std::string arms = "arms:\n  - {name: left, base_link: left_wam_base, tip_link: left_wam_tool}\n";
  const auto sim = [&](const std::string& name, const std::string& text) {
    const std::string path = write(name, text);
    return std::pair{path, errorOf([&] { SimConfig::fromYamlFile(path); })};
  };
  EXPECT_EQ(sim("sim_good.yaml", head + arms).second, "no exception");
  struct Case {
    const char* file;
    std::string text;
    const char* expected;
  };
  const Case cases[] = {
      {"sim_key.yaml", head + arms + "rate: 1000\n", "unknown entry 'rate'"},
      {"sim_arms.yaml", head, "'arms'"},
      {"sim_plant_arm.yaml", head + "arms:\n  - {name: right, base_link: a, tip_link: b}\n", "no arm 'right'"},
      {"sim_step.yaml", head + arms + "step: -0.001\n", "'step'"},
      {"sim_table.yaml", head + arms + "table: {size: [1, 0, 1]}\n", "table 'size'"},
      {"sim_cloth_rate.yaml", head + arms + "table: {}\ncloth: {step: 0.0025}\n", "whole multiple"},
      {"sim_cloth_nodes.yaml", head + arms + "table: {}\ncloth: {nodes: [20.5, 24]}\n", "'nodes'"},
      {"sim_cloth_key.yaml", head + arms + "table: {}\ncloth: {stiffness: 1}\n", "unknown entry 'stiffness'"},
      {"sim_seed.yaml", head + arms + "seed: -3\n", "'seed'"},
  };
  for (const Case& c : cases) {
    const auto [path, message] = sim(c.file, c.text);
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.file << ": " << message;
    EXPECT_NE(message.find(path), std::string::npos) << c.file << " names the file: " << message;
  }
}

// ---- robot files (config/robots/*.yaml) ----

TEST(RobotFile, TheWamFileGivesWhatTheSimulationAndTheControllersUsed) {
  const bs::sim::RobotFile wam = bs::sim::RobotFile::fromYamlFile(kConfig + "/robots/wam.yaml");
  EXPECT_EQ(wam.name, "wam");
  ASSERT_EQ(wam.arms.size(), 2u);
  EXPECT_EQ(wam.arms[0].name, "left");
  EXPECT_EQ(wam.arms[1].tip_link, "right_wam_tool");
  EXPECT_TRUE(fs::exists(wam.urdf_path));
  EXPECT_TRUE(fs::exists(wam.arms[1].friction_file));
  EXPECT_EQ(wam.kp.size(), 7);
  EXPECT_EQ(wam.kp[0], 150.0);
  EXPECT_EQ(wam.braking_damping[6], 0.5);
  EXPECT_EQ(wam.rated_payload, 4.0);
  EXPECT_EQ(wam.arms[0].start[3], 2.0);
  ASSERT_NE(wam.arm("right"), nullptr);
  EXPECT_EQ(wam.arm("middle"), nullptr);
  // config/sim.yaml names it: the same arms, URDF and plant as a file that names them itself (test/sim_500hz.yaml).
  const SimConfig via_robot = SimConfig::fromYamlFile(kConfig + "/sim.yaml");
  const SimConfig explicit_arms = SimConfig::fromYamlFile(BIMANUAL_SKILLS_SOURCE_DIR "/test/sim_500hz.yaml");
  EXPECT_EQ(fs::canonical(via_robot.urdf_path), fs::canonical(explicit_arms.urdf_path));
  EXPECT_EQ(fs::canonical(via_robot.plant_path), fs::canonical(explicit_arms.plant_path));
  ASSERT_EQ(via_robot.arms.size(), explicit_arms.arms.size());
  for (std::size_t a = 0; a < via_robot.arms.size(); ++a) {
    EXPECT_EQ(via_robot.arms[a].base_link, explicit_arms.arms[a].base_link);
    EXPECT_EQ(via_robot.arms[a].tip_link, explicit_arms.arms[a].tip_link);
  }
  EXPECT_EQ(fs::canonical(via_robot.robot_path), fs::canonical(kConfig + "/robots/wam.yaml"));
  // A robot given to a file that names its arms replaces them.
  EXPECT_EQ(SimConfig::fromYamlFile(BIMANUAL_SKILLS_SOURCE_DIR "/test/sim_500hz.yaml", kConfig + "/robots/wam.yaml")
                .robot_path,
            kConfig + "/robots/wam.yaml");
}

TEST(RobotFile, BadRobotFilesAreRefusedNamingTheEntry) {
  const std::string urdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/bimanual_wam.urdf";
  const std::string plant = kConfig + "/plant.yaml";
  const auto robot = [&](const std::string& arms, const std::string& extra) {
    return "name: test\nurdf: " + urdf + "\nplant: " + plant + "\nrated_payload: 4\narms:\n" + arms +
           "kp: [1, 1, 1, 1, 1, 1, 1]\nkv: [1, 1, 1, 1, 1, 1, 1]\nbraking_damping: [1, 1, 1, 1, 1, 1, 1]\n" + extra;
  };
  const std::string left =
      "  - {name: left, base_link: left_wam_base, tip_link: left_wam_tool, start: [0, 0.6, 0, 2, 0, 0.5, 0]}\n";
  const auto load = [](const std::string& path) { return bs::sim::RobotFile::fromYamlFile(path); };
  EXPECT_EQ(errorOf([&] { load(write("robot_ok.yaml", robot(left, ""))); }), "no exception");
  EXPECT_NE(errorOf([&] { load(write("robot_extra.yaml", robot(left, "kd: [1]\n"))); }).find("kd"), std::string::npos);
  EXPECT_NE(errorOf([&] { load(write("robot_twice.yaml", robot(left + left, ""))); }).find("taken by another arm"),
            std::string::npos);
  const std::string far =
      "  - {name: left, base_link: left_wam_base, tip_link: left_wam_tool, start: [0, 0.6, 0, 9, 0, 0.5, 0]}\n";
  EXPECT_NE(errorOf([&] { load(write("robot_far.yaml", robot(far, ""))); }).find("outside the URDF's joint limits"),
            std::string::npos);
  const std::string short_start =
      "  - {name: left, base_link: left_wam_base, tip_link: left_wam_tool, start: [0, 0.6, 0]}\n";
  EXPECT_NE(errorOf([&] { load(write("robot_short.yaml", robot(short_start, ""))); }).find("start"), std::string::npos);
  const std::string no_link =
      "  - {name: left, base_link: left_wam_base, tip_link: nowhere, start: [0, 0.6, 0, 2, 0, 0.5, 0]}\n";
  EXPECT_NE(errorOf([&] { load(write("robot_link.yaml", robot(no_link, ""))); }).find("nowhere"), std::string::npos);
  // A simulation file naming a robot and arms of its own is ambiguous.
  const std::string both = write("sim_both.yaml", "robot: " + kConfig + "/robots/wam.yaml\nurdf: " + urdf + "\n");
  EXPECT_NE(errorOf([&] { SimConfig::fromYamlFile(both); }).find("the robot file gives them"), std::string::npos);
}

// ---- what a robot file leaves out comes from the model ----

/// The second robot's left arm, as its robot file has it (gravity in its base frame).
bs::kinematics::ChainModel offsetWristArm() {
  const bs::sim::RobotFile robot = bs::sim::RobotFile::fromYamlFile(kConfig + "/robots/offset_wrist.yaml");
  // Its base stands upright: gravity is the chain's default.
  return bs::kinematics::ChainModel::fromUrdfFile(robot.urdf_path, "left_base_link", "left_tool");
}

TEST(RobotFileDerivation, GainsAreTheBandwidthOnTheInertiaEachJointSees) {
  const bs::kinematics::ChainModel arm = offsetWristArm();
  const Eigen::VectorXd q = (Eigen::VectorXd(7) << 0.1, 0.5, -0.2, -2.0, 0.3, 2.0, 0.4).finished();
  const Eigen::VectorXd hz = (Eigen::VectorXd(7) << 1, 2, 3, 4, 5, 6, 7).finished();
  Eigen::VectorXd kp, kv;
  bs::sim::gainsFromBandwidth(arm, q, hz, 0.7, kp, kv);
  // Independent reference: M_ii as the torque of joint i for a unit acceleration of joint i alone (inverse dynamics
  // at rest, gravity taken out), not the composite-rigid-body mass matrix the derivation uses.
  bs::dynamics::DynamicsData data(arm);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(7);
  Eigen::VectorXd rest(7), pushed(7);
  ASSERT_EQ(bs::dynamics::inverseDynamics(arm, data, q, zero, zero, rest), bs::dynamics::DynamicsStatus::Success);
  for (int i = 0; i < 7; ++i) {
    const Eigen::VectorXd unit = Eigen::VectorXd::Unit(7, i);
    ASSERT_EQ(bs::dynamics::inverseDynamics(arm, data, q, zero, unit, pushed), bs::dynamics::DynamicsStatus::Success);
    const double inertia = pushed[i] - rest[i], omega = 2.0 * M_PI * hz[i];
    EXPECT_NEAR(kp[i], inertia * omega * omega, 1e-9 * kp[i]) << "joint " << i + 1;
    EXPECT_NEAR(kv[i], 2.0 * 0.7 * inertia * omega, 1e-9 * kv[i]) << "joint " << i + 1;
  }
  EXPECT_THROW(bs::sim::gainsFromBandwidth(arm, q, -hz, 1.0, kp, kv), std::invalid_argument);
}

TEST(RobotFileDerivation, BrakingAndPayloadComeFromTheUrdfLimits) {
  const bs::kinematics::ChainModel arm = offsetWristArm();
  // The URDF's limits (scripts/generate_test_arms.py): 87 N m at 2.175 rad/s, 12 N m at 2.61 rad/s.
  const Eigen::VectorXd braking = bs::sim::brakingFromLimits(arm);
  EXPECT_NEAR(braking[0], 87.0 / (2.0 * 2.175), 1e-12);
  EXPECT_NEAR(braking[6], 12.0 / (2.0 * 2.61), 1e-12);
  // The payload: with that mass at the tool, the most loaded joint needs exactly half its effort limit against
  // gravity and no joint more (inverse dynamics at rest with the payload, a reference apart from the derivation).
  const Eigen::VectorXd q = (Eigen::VectorXd(7) << 0.0, 0.6, 0.0, -1.5, 0.0, 1.8, 0.0).finished();
  const double payload = bs::sim::payloadFromEfforts(arm, q);
  EXPECT_GT(payload, 0.5);
  bs::dynamics::DynamicsData data(arm);
  bs::dynamics::Payload load;
  load.mass = payload;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(7);
  Eigen::VectorXd held(7);
  ASSERT_EQ(bs::dynamics::inverseDynamics(arm, data, q, zero, zero, held, load), bs::dynamics::DynamicsStatus::Success);
  const double worst = (held.cwiseAbs().array() / (0.5 * arm.effortLimits().array())).maxCoeff();
  EXPECT_NEAR(worst, 1.0, 1e-9);
  // An arm whose URDF gives no limits: nothing to derive, said per joint.
  const bs::kinematics::ChainModel unlimited = bs::kinematics::ChainModel::fromUrdfFile(
      BIMANUAL_SKILLS_SOURCE_DIR "/test/chain_no_limits.urdf", "base_link", "tool");
  EXPECT_NE(errorOf([&] { bs::sim::brakingFromLimits(unlimited); }).find("no effort or velocity limit"),
            std::string::npos);
}

TEST(RobotFileDerivation, TheStartPostureIsTheSolutionNearestTheMiddleOfTheRanges) {
  const bs::kinematics::ChainModel arm = offsetWristArm();
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translation() = Eigen::Vector3d(0.45, 0.1, 0.3);
  tool.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::VectorXd q = bs::sim::postureFromToolPose(arm, tool);
  EXPECT_EQ(bs::sim::postureFromToolPose(arm, tool), q);  // the same answer every time
  EXPECT_TRUE(arm.withinLimits(q));
  bs::kinematics::ChainData data(arm);
  (void)bs::kinematics::forwardKinematics(arm, data, q);
  EXPECT_LT((data.tipPose().translation() - tool.translation()).norm(), 1e-4);
  EXPECT_LT((data.tipPose().linear() - tool.linear()).norm(), 1e-3);
  // Brute force: no solution from 40 independently seeded searches lies nearer the middle of the ranges.
  const Eigen::ArrayXd middle = 0.5 * (arm.lowerLimits() + arm.upperLimits()).array();
  const Eigen::ArrayXd range = (arm.upperLimits() - arm.lowerLimits()).array();
  const auto distance = [&](const Eigen::VectorXd& x) { return ((x.array() - middle) / range).square().sum(); };
  for (std::uint32_t seed = 100; seed < 140; ++seed) {
    bs::kinematics::GlobalIkParameters parameters;
    parameters.seed = seed;
    parameters.timeout = 1.0;
    bs::kinematics::GlobalIkSolver solver(arm, parameters);
    std::mt19937 rng(seed);
    Eigen::VectorXd other(7);
    if (solver.solve(tool, bs::kinematics::randomWithinLimits(arm, rng), other).status !=
        bs::kinematics::IkStatus::Converged) {
      continue;
    }
    EXPECT_LE(distance(q), distance(other) + 0.05) << "seed " << seed << ": " << other.transpose();
  }
  Eigen::Isometry3d far = tool;
  far.translation() = Eigen::Vector3d(3.0, 0.0, 0.0);
  EXPECT_NE(errorOf([&] { bs::sim::postureFromToolPose(arm, far); }).find("no posture"), std::string::npos);
}

TEST(RobotFileDerivation, TheSecondRobotFileDerivesWhatItLeavesOutAndBadOnesSayWhatToGive) {
  const bs::sim::RobotFile robot = bs::sim::RobotFile::fromYamlFile(kConfig + "/robots/offset_wrist.yaml");
  EXPECT_EQ(robot.derived.size(), 5u);  // two starts, the gains, the braking, the payload
  EXPECT_GT(robot.rated_payload, 1.0);
  EXPECT_EQ(robot.kp.size(), 7);
  EXPECT_EQ(robot.braking_damping.size(), 7);
  for (const bs::sim::RobotArm& arm : robot.arms) EXPECT_EQ(arm.ik_seed, arm.start);
  // The WAM's file gives everything: nothing derived.
  EXPECT_TRUE(bs::sim::RobotFile::fromYamlFile(kConfig + "/robots/wam.yaml").derived.empty());

  const std::string head = "name: test\nurdf: " + std::string(BIMANUAL_SKILLS_SOURCE_DIR) +
                           "/urdf/bimanual_offset_wrist.urdf\nplant: " + kConfig +
                           "/robots/offset_wrist/plant.yaml\narms:\n  - {name: left, base_link: left_base_link, "
                           "tip_link: left_tool, ";
  const std::string reachable = "start_tool: {xyz: [0.55, 0.25, 0.45], rpy: [3.14159, 0, 0]}}\n";
  const auto refused = [&](const std::string& file, const std::string& text) {
    return errorOf([&] { bs::sim::RobotFile::fromYamlFile(write(file, text)); });
  };
  EXPECT_EQ(refused("derive_ok.yaml", head + reachable + "bandwidth: 3\n"), "no exception");
  EXPECT_NE(refused("derive_no_start.yaml", head + "friction: ''}\nbandwidth: 3\n").find("'start_tool'"),
            std::string::npos);
  EXPECT_NE(refused("derive_both_starts.yaml", head + "start: [0, 0, 0, -2, 0, 2, 0], " + reachable + "bandwidth: 3\n")
                .find("not both"),
            std::string::npos);
  EXPECT_NE(refused("derive_far.yaml", head + "start_tool: {xyz: [3, 0, 0.45]}}\nbandwidth: 3\n")
                .find("no 'start' and none derived from the model"),
            std::string::npos);
  EXPECT_NE(refused("derive_no_gains.yaml", head + reachable).find("'bandwidth'"), std::string::npos);
  EXPECT_NE(refused("derive_gains_twice.yaml",
                    head + reachable + "bandwidth: 3\nkp: [1, 1, 1, 1, 1, 1, 1]\nkv: [1, 1, 1, 1, 1, 1, 1]\n")
                .find("not both"),
            std::string::npos);
  EXPECT_NE(refused("derive_bad_bandwidth.yaml", head + reachable + "bandwidth: -1\n").find("give 'kp' and 'kv'"),
            std::string::npos);
}

// ---- obstacles: a list or a file of them ----

TEST(SimConfigFiles, ObstaclesComeFromAListOrAFileAndBadOnesAreNamed) {
  const SimConfig scarf = SimConfig::fromYamlFile(kConfig + "/scarf_sim.yaml");
  ASSERT_EQ(scarf.obstacles.size(), 6u);
  const bs::sim::Obstacle& head = scarf.obstacles[4];
  EXPECT_EQ(head.name, "head");
  EXPECT_EQ(head.shape, bs::sim::Obstacle::Shape::Sphere);
  EXPECT_EQ(head.size, Eigen::Vector3d(0.09, 0.0, 0.0));
  EXPECT_EQ(head.pose.translation(), Eigen::Vector3d(0.5, 0.4, 0.525));
  EXPECT_FALSE(scarf.obstacles[5].collides);  // the nose mark
  EXPECT_FALSE(scarf.has_table);
  EXPECT_TRUE(SimConfig::fromYamlFile(kConfig + "/sim.yaml").obstacles.empty());

  const std::string head_yaml = "robot: " + kConfig + "/robots/wam.yaml\n";
  const auto refused = [&](const std::string& file, const std::string& obstacles) {
    return errorOf([&] { SimConfig::fromYamlFile(write(file, head_yaml + "obstacles:\n" + obstacles)); });
  };
  EXPECT_EQ(refused("obstacles_ok.yaml", "  - {name: b, shape: box, xyz: [1, 0, 0], size: [0.1, 0.2, 0.3]}\n"),
            "no exception");
  EXPECT_NE(
      refused("obstacles_shape.yaml", "  - {name: b, shape: cone, size: [0.1]}\n").find("box, sphere or cylinder"),
      std::string::npos);
  EXPECT_NE(refused("obstacles_size.yaml", "  - {name: b, shape: cylinder, size: [0.1]}\n").find("needs 2 value(s)"),
            std::string::npos);
  EXPECT_NE(refused("obstacles_zero.yaml", "  - {name: b, shape: sphere, size: [0]}\n").find("'size'"),
            std::string::npos);
  EXPECT_NE(refused("obstacles_colour.yaml", "  - {name: b, shape: sphere, size: [0.1], colour: [2, 0, 0]}\n")
                .find("'colour'"),
            std::string::npos);
  EXPECT_NE(refused("obstacles_twice.yaml",
                    "  - {name: b, shape: sphere, size: [0.1]}\n  - {name: b, shape: sphere, size: [0.2]}\n")
                .find("taken by another obstacle"),
            std::string::npos);
  EXPECT_NE(refused("obstacles_key.yaml", "  - {name: b, shape: sphere, size: [0.1], radius: 1}\n").find("radius"),
            std::string::npos);
  EXPECT_NE(errorOf([&] {
              SimConfig::fromYamlFile(write("obstacles_file.yaml", head_yaml + "obstacles: no_such_scene.yaml\n"));
            }).find("no_such_scene.yaml"),
            std::string::npos);
}
