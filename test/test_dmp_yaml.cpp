// DMP files: save → load gives back every double bit for bit (Dmp, DmpState, CartesianDmp of both encodings, and
// CartesianDmpState), a loaded DMP rolls out exactly as the saved one, and bad files are refused with messages that
// name the file and the entry.
#include "bimanual_skills/primitives/dmp_yaml.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace bp = bimanual_skills::primitives;
namespace fs = std::filesystem;

namespace {

constexpr double kDt = 0.002;

fs::path directory() {
  const fs::path dir = fs::temp_directory_path() / "bimanual_skills_dmp_yaml";
  fs::create_directories(dir);
  return dir;
}

std::string file(const std::string& name) {
  return (directory() / name).string();
}

void write(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

/// Bit-for-bit equality (also tells −0 from 0 and compares NaN payloads).
bool sameBits(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

bool sameBits(double a, double b) {
  return std::memcmp(&a, &b, sizeof(double)) == 0;
}

bool sameBits(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return sameBits(a.coeffs(), b.coeffs());
}

void expectSameState(const bp::DmpState& a, const bp::DmpState& b) {
  EXPECT_TRUE(sameBits(a.y, b.y));
  EXPECT_TRUE(sameBits(a.yd, b.yd));
  EXPECT_TRUE(sameBits(a.ydd, b.ydd));
  EXPECT_TRUE(sameBits(a.goal, b.goal));
  EXPECT_TRUE(sameBits(a.x, b.x));
  EXPECT_TRUE(sameBits(a.t, b.t));
}

/// A 4-DoF demonstration with irrational-looking numbers everywhere.
Eigen::MatrixXd demonstration() {
  Eigen::MatrixXd y(801, 4);
  for (int r = 0; r < y.rows(); ++r) {
    const double s = r / 800.0;
    for (int j = 0; j < 4; ++j) y(r, j) = std::sin((j + 1) * 1.1 * s + 0.3 * j) / 3.0 + std::exp(-s) * 0.1;
  }
  return y;
}

std::vector<bp::Pose> poseDemonstration() {
  std::vector<bp::Pose> poses(801);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const double s = static_cast<double>(k) / 800.0;
    poses[k].position = Eigen::Vector3d(0.1 + s / 3.0, std::sin(s), 0.2 * s * s);
    poses[k].orientation = Eigen::Quaterniond(Eigen::AngleAxisd(1.2 * s, Eigen::Vector3d(1.0, s, 0.3).normalized()));
  }
  return poses;
}

/// Expects `load(path)` to throw E with a message containing every one of `parts`.
template <typename E, typename Load>
void expectError(Load load, const std::string& path, const std::vector<std::string>& parts) {
  try {
    load(path);
    ADD_FAILURE() << "no exception for " << path;
  } catch (const E& e) {
    for (const std::string& part : parts) EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

/// A valid one-DoF, two-kernel DMP file with `replace` substituted for `key_line`.
std::string smallDmp(const std::string& key_line = "", const std::string& replace = "") {
  std::string text =
      "type: dmp\n"
      "parameters: {kernels: 2, alpha_z: 25, beta_z: 6.25, alpha_x: 4, goal_scaled_forcing: false, "
      "regularisation: 1e-08}\n"
      "duration: 2\n"
      "start: [0.5]\n"
      "goal: [1.5]\n"
      "weights:\n"
      "  - [1, 2]\n";
  if (!key_line.empty()) {
    const auto at = text.find(key_line);
    EXPECT_NE(at, std::string::npos) << key_line;
    text.replace(at, key_line.size(), replace);
  }
  return text;
}

}  // namespace

TEST(DmpYaml, DmpRoundTripIsBitExact) {
  bp::DmpParameters parameters;
  parameters.goal_scaled_forcing = true;
  parameters.regularisation = 1.0 / 3.0 * 1e-7;
  const bp::Dmp fitted = bp::Dmp::fit(parameters, demonstration(), kDt);
  // Awkward doubles in the weights: extremes, a subnormal, −0, and random ones over many magnitudes.
  Eigen::MatrixXd weights = fitted.weights();
  weights(0, 0) = std::numeric_limits<double>::max();
  weights(0, 1) = std::numeric_limits<double>::denorm_min();
  weights(0, 2) = -0.0;
  weights(0, 3) = std::numeric_limits<double>::min();
  weights(0, 4) = -std::numeric_limits<double>::epsilon();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-300, 300);
  for (int i = 0; i < weights.cols(); ++i) weights(1, i) = std::ldexp(mantissa(rng), exponent(rng));
  const bp::Dmp dmp = fitted.withWeights(weights);
  saveDmp(dmp, file("dmp.yaml"), "test DMP\nsecond comment line");
  const bp::Dmp loaded = bp::loadDmp(file("dmp.yaml"));
  EXPECT_TRUE(sameBits(loaded.weights(), dmp.weights()));
  EXPECT_TRUE(sameBits(loaded.start(), dmp.start()));
  EXPECT_TRUE(sameBits(loaded.goal(), dmp.goal()));
  EXPECT_TRUE(sameBits(loaded.duration(), dmp.duration()));
  EXPECT_EQ(loaded.parameters().kernels, parameters.kernels);
  EXPECT_TRUE(sameBits(loaded.parameters().alpha_z, parameters.alpha_z));
  EXPECT_TRUE(sameBits(loaded.parameters().beta_z, parameters.beta_z));
  EXPECT_TRUE(sameBits(loaded.parameters().alpha_x, parameters.alpha_x));
  EXPECT_TRUE(sameBits(loaded.parameters().regularisation, parameters.regularisation));
  EXPECT_TRUE(loaded.parameters().goal_scaled_forcing);

  // The fitted DMP, saved and loaded, rolls out identically; so does its state, saved mid-movement.
  saveDmp(fitted, file("fitted.yaml"));
  const bp::Dmp reloaded = bp::loadDmp(file("fitted.yaml"));
  bp::DmpState a = fitted.initialState(), b = reloaded.initialState();
  for (int k = 0; k < 500; ++k) {
    ASSERT_EQ(fitted.step(a, kDt), bp::DmpStatus::Success);
    ASSERT_EQ(reloaded.step(b, kDt), bp::DmpStatus::Success);
  }
  expectSameState(a, b);
  saveDmpState(a, file("state.yaml"));
  bp::DmpState c = bp::loadDmpState(file("state.yaml"));
  expectSameState(c, a);
  ASSERT_EQ(fitted.step(a, kDt), bp::DmpStatus::Success);
  ASSERT_EQ(fitted.step(c, kDt), bp::DmpStatus::Success);
  expectSameState(c, a);
}

TEST(DmpYaml, CartesianDmpAndStateRoundTripsAreBitExact) {
  for (const bp::OrientationEncoding encoding :
       {bp::OrientationEncoding::UnitQuaternion, bp::OrientationEncoding::QuaternionVector}) {
    const bp::CartesianDmp dmp = bp::CartesianDmp::fit(bp::DmpParameters(), encoding, poseDemonstration(), kDt);
    saveCartesianDmp(dmp, file("cartesian.yaml"));
    const bp::CartesianDmp loaded = bp::loadCartesianDmp(file("cartesian.yaml"));
    EXPECT_EQ(loaded.encoding(), encoding);
    EXPECT_TRUE(sameBits(loaded.positionWeights(), dmp.positionWeights()));
    EXPECT_TRUE(sameBits(loaded.orientationWeights(), dmp.orientationWeights()));
    EXPECT_TRUE(sameBits(loaded.start().position, dmp.start().position));
    EXPECT_TRUE(sameBits(loaded.start().orientation, dmp.start().orientation));
    EXPECT_TRUE(sameBits(loaded.goal().position, dmp.goal().position));
    EXPECT_TRUE(sameBits(loaded.goal().orientation, dmp.goal().orientation));
    EXPECT_TRUE(sameBits(loaded.duration(), dmp.duration()));

    bp::CartesianDmpState a = dmp.initialState(), b = loaded.initialState();
    for (int k = 0; k < 300; ++k) {
      ASSERT_EQ(dmp.step(a, kDt), bp::DmpStatus::Success);
      ASSERT_EQ(loaded.step(b, kDt), bp::DmpStatus::Success);
    }
    EXPECT_TRUE(sameBits(a.orientation, b.orientation));
    expectSameState(a.position, b.position);
    saveCartesianDmpState(a, file("cartesian_state.yaml"));
    bp::CartesianDmpState c = bp::loadCartesianDmpState(file("cartesian_state.yaml"));
    expectSameState(c.position, a.position);
    expectSameState(c.orientation_vector, a.orientation_vector);
    EXPECT_TRUE(sameBits(c.orientation, a.orientation));
    EXPECT_TRUE(sameBits(c.goal_orientation, a.goal_orientation));
    EXPECT_TRUE(sameBits(c.angular_velocity, a.angular_velocity));
    EXPECT_TRUE(sameBits(c.angular_acceleration, a.angular_acceleration));
    ASSERT_EQ(dmp.step(a, kDt), bp::DmpStatus::Success);
    ASSERT_EQ(dmp.step(c, kDt), bp::DmpStatus::Success);  // continues exactly where it was saved
    EXPECT_TRUE(sameBits(c.orientation, a.orientation));
    expectSameState(c.position, a.position);
  }
}

TEST(DmpYaml, BadFilesAreRefusedWithPreciseMessages) {
  const auto load = [](const std::string& path) { return bp::loadDmp(path); };
  write(file("small.yaml"), smallDmp());
  EXPECT_NO_THROW(bp::loadDmp(file("small.yaml")));

  expectError<std::invalid_argument>(load, file("does_not_exist.yaml"), {"cannot read", "does_not_exist.yaml"});
  EXPECT_THROW(saveDmp(bp::loadDmp(file("small.yaml")), "/nonexistent_directory/dmp.yaml"), std::invalid_argument);

  const auto check = [&](const std::string& name, const std::string& text, const std::vector<std::string>& parts) {
    write(file(name), text);
    expectError<std::invalid_argument>(load, file(name), parts);
  };
  check("syntax.yaml", "type: dmp\nweights: [1, 2\n", {"syntax.yaml", "not valid YAML"});
  check("list.yaml", "- 1\n- 2\n", {"not a YAML map"});
  check("type.yaml", smallDmp("type: dmp", "type: dmp_state"), {"'type' is 'dmp_state', expected 'dmp'"});
  check("no_weights.yaml", smallDmp("weights:\n  - [1, 2]\n", ""), {"no_weights.yaml", "missing key 'weights'"});
  check("no_kernels.yaml", smallDmp("kernels: 2, ", ""), {"'parameters'", "missing key 'kernels'"});
  check("rows.yaml", smallDmp("  - [1, 2]\n", "  - [1, 2]\n  - [3, 4]\n"),
        {"'weights' must be a list of 1 rows (got 2)"});
  check("cols.yaml", smallDmp("[1, 2]", "[1, 2, 3]"), {"'weights' row 1 must be a list of 2 numbers (got 3)"});
  check("text.yaml", smallDmp("[1, 2]", "[1, abc]"), {"'weights' row 1", "entry 2 is not a finite number ('abc')"});
  check("nested.yaml", smallDmp("[1, 2]", "[1, [2]]"), {"entry 2 is not a finite number"});
  check("duration.yaml", smallDmp("duration: 2", "duration: two"), {"'duration' must be a number (got 'two')"});
  check("kernels.yaml", smallDmp("kernels: 2", "kernels: 2.5"), {"'kernels' must be an integer (got '2.5')"});
  check("bool.yaml", smallDmp("goal_scaled_forcing: false", "goal_scaled_forcing: maybe"),
        {"'goal_scaled_forcing' must be true or false"});
  check("goal.yaml", smallDmp("goal: [1.5]", "goal: [1.5, 2]"), {"'goal' must be a list of 1 numbers (got 2)"});
  check("negative.yaml", smallDmp("duration: 2", "duration: -1"), {"negative.yaml", "duration > 0"});
  check("alpha.yaml", smallDmp("alpha_z: 25", "alpha_z: 0"), {"'parameters'", "alpha_z"});
  check("nan.yaml", smallDmp("start: [0.5]", "start: [.nan]"), {"finite"});

  // States and Cartesian files.
  const auto load_state = [](const std::string& path) { return bp::loadDmpState(path); };
  write(file("state_bad.yaml"), "type: dmp_state\ny: [1, 2]\nyd: [0, 0]\nydd: [0]\ngoal: [1, 1]\nx: 1\nt: 0\n");
  expectError<std::invalid_argument>(load_state, file("state_bad.yaml"), {"'ydd' must be a list of 2 numbers (got 1)"});
  write(file("state_no_x.yaml"), "type: dmp_state\ny: [1]\nyd: [0]\nydd: [0]\ngoal: [1]\nt: 0\n");
  expectError<std::invalid_argument>(load_state, file("state_no_x.yaml"), {"missing key 'x'"});

  const bp::CartesianDmp cartesian =
      bp::CartesianDmp::fit(bp::DmpParameters(), bp::OrientationEncoding::UnitQuaternion, poseDemonstration(), kDt);
  saveCartesianDmp(cartesian, file("cartesian_good.yaml"));
  std::ifstream in(file("cartesian_good.yaml"));
  const std::string good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto load_cartesian = [](const std::string& path) { return bp::loadCartesianDmp(path); };
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const auto at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return text.replace(at, from.size(), to);
  };
  write(file("encoding.yaml"), replaced("unit_quaternion", "euler_angles"));
  expectError<std::invalid_argument>(
      load_cartesian, file("encoding.yaml"),
      {"'orientation_encoding' must be unit_quaternion or quaternion_vector", "(got 'euler_angles')"});
  write(file("quaternion.yaml"), replaced("orientation: [", "orientation: [0.5, "));
  expectError<std::invalid_argument>(load_cartesian, file("quaternion.yaml"),
                                     {"'start'", "'orientation' must be a list of 4 numbers (got 5)"});
  // The first orientation is the start's; its list replaced by a non-unit one.
  std::string not_unit = good;
  const auto list = not_unit.find("orientation: [") + std::string("orientation: ").size();
  not_unit.replace(list, not_unit.find(']', list) + 1 - list, "[0.9, 0.9, 0.9, 0.9]");
  write(file("not_unit.yaml"), not_unit);
  expectError<std::invalid_argument>(load_cartesian, file("not_unit.yaml"), {"must be a unit quaternion [x, y, z, w]"});
  write(file("no_orientation_weights.yaml"), replaced("orientation_weights:", "other_weights:"));
  expectError<std::invalid_argument>(load_cartesian, file("no_orientation_weights.yaml"),
                                     {"missing key 'orientation_weights'"});
}
