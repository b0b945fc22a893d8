// The committed robot descriptions must be exactly what the generator scripts produce from their sources.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace {

const std::string kSource = BIMANUAL_SKILLS_SOURCE_DIR;

std::string readFile(const std::string& path) {
  std::ifstream file(path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

/// Runs a generator with /usr/bin/python3 (the ROS interpreter) and returns what it wrote.
std::string generate(const std::string& script, const std::string& arguments) {
  char dir_template[] = "/tmp/bimanual_skills_urdf_XXXXXX";
  const char* dir = mkdtemp(dir_template);
  EXPECT_NE(dir, nullptr);
  const std::string out = std::string(dir) + "/generated.urdf";
  const std::string command = "/usr/bin/python3 " + kSource + "/scripts/" + script + " " + arguments + " --out " + out;
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  std::string text = readFile(out);
  std::remove(out.c_str());
  rmdir(dir);
  return text;
}

}  // namespace

TEST(UrdfGeneration, CommittedWamEqualsGenerated) {
  const std::string generated = generate("generate_wam_urdf.py", "");
  ASSERT_FALSE(generated.empty());
  EXPECT_EQ(readFile(kSource + "/urdf/wam.urdf"), generated)
      << "urdf/wam.urdf is stale: run scripts/generate_wam_urdf.py --out urdf/wam.urdf";
}

TEST(UrdfGeneration, CommittedBimanualEqualsGenerated) {
  const std::string generated = generate("generate_bimanual_urdf.py", "");
  ASSERT_FALSE(generated.empty());
  EXPECT_EQ(readFile(kSource + "/urdf/bimanual_wam.urdf"), generated)
      << "urdf/bimanual_wam.urdf is stale: run scripts/generate_bimanual_urdf.py --out urdf/bimanual_wam.urdf";
}

TEST(UrdfGeneration, CommittedSecondRobotEqualsGenerated) {
  const std::string generated =
      generate("generate_bimanual_urdf.py", "--arm " + kSource + "/urdf/test_arms/offset_wrist_arm.urdf --config " +
                                                kSource + "/config/robots/offset_wrist/placement.yaml");
  ASSERT_FALSE(generated.empty());
  EXPECT_EQ(readFile(kSource + "/urdf/bimanual_offset_wrist.urdf"), generated)
      << "urdf/bimanual_offset_wrist.urdf is stale: run the command in config/robots/offset_wrist.yaml";
}

TEST(UrdfGeneration, CommittedTestArmsEqualGenerated) {
  for (const std::string arm : {"offset_wrist_arm", "spherical_wrist_arm"}) {
    const std::string generated = generate("generate_test_arms.py", "--arm " + arm);
    ASSERT_FALSE(generated.empty());
    EXPECT_EQ(readFile(kSource + "/urdf/test_arms/" + arm + ".urdf"), generated)
        << "urdf/test_arms/" << arm << ".urdf is stale: run scripts/generate_test_arms.py --arm " << arm
        << " --out urdf/test_arms/" << arm << ".urdf";
  }
}

TEST(UrdfGeneration, BadConfigurationIsAClearErrorNotACrash) {
  char path[] = "/tmp/bimanual_skills_config_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  const std::string bad = "arms:\n  - prefix: left_\n    xyz: [0, nan_here, 0]\n    rpy: [0, 0, 0]\n";
  ASSERT_EQ(write(fd, bad.data(), bad.size()), static_cast<ssize_t>(bad.size()));
  close(fd);
  const std::string command =
      "/usr/bin/python3 " + kSource + "/scripts/generate_bimanual_urdf.py --config " + path + " > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  std::remove(path);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
}
