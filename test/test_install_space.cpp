// The install space stands on its own: a copy of it, with the source tree out of reach (no program names it, and
// the copy is run with nothing of the source or build trees on its paths), runs an experiment program with its plot
// script and the simulator node with its configuration, found beside the programs.
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

namespace fs = std::filesystem;
using bimanual_skills::testing::readTextFile;
using bimanual_skills::testing::runQuietly;

namespace {

/// A copy of the package's install prefix in a temporary directory.
fs::path copyOfInstallSpace() {
  const fs::path copy = fs::temp_directory_path() / ("bimanual_skills_install_copy_" + std::to_string(::getpid()));
  fs::remove_all(copy);
  fs::copy(BIMANUAL_SKILLS_INSTALL_PREFIX, copy, fs::copy_options::recursive | fs::copy_options::copy_symlinks);
  return copy;
}

/// The command run in a clean environment with the copy's libraries and package path only, from /tmp.
std::string inCopy(const fs::path& copy, const std::string& command) {
  return "cd /tmp && env -i PATH=/usr/bin:/bin HOME=/tmp LD_LIBRARY_PATH=" + (copy / "lib").string() +
         " ROS_PACKAGE_PATH=" + (copy / "share").string() +
         " ROS_HOSTNAME=localhost ROS_MASTER_URI=" + "http://localhost:" + std::to_string(11000 + ::getpid() % 500) +
         " " + command;
}

}  // namespace

TEST(InstallSpace, NoInstalledProgramNamesTheSourceTree) {
  const std::string source = BIMANUAL_SKILLS_SOURCE_DIR;
  int programs = 0;
  for (const auto& entry :
       fs::directory_iterator(fs::path(BIMANUAL_SKILLS_INSTALL_PREFIX) / "lib" / "bimanual_skills")) {
    if (!entry.is_regular_file()) continue;
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(bytes.find(source + "/"), std::string::npos) << entry.path() << " names the source tree " << source;
    ++programs;
  }
  EXPECT_GT(programs, 10);
}

TEST(InstallSpace, EveryPlotScriptAProgramRunsIsInstalled) {
  // The scripts the experiment programs name (runPlotScript(..., "plot_*.py")) in their sources.
  int named = 0;
  for (const char* folder : {"bench", "nodes", "src/tools"}) {
    for (const auto& entry : fs::directory_iterator(fs::path(BIMANUAL_SKILLS_SOURCE_DIR) / folder)) {
      const std::string text = readTextFile(entry.path().string());
      for (std::size_t at = text.find("\"plot_"); at != std::string::npos; at = text.find("\"plot_", at + 1)) {
        const std::size_t end = text.find(".py\"", at);
        if (end == std::string::npos) continue;
        const std::string script = text.substr(at + 1, end + 3 - at - 1);
        if (script.find_first_of(" \n") != std::string::npos) continue;
        ++named;
        EXPECT_TRUE(
            fs::exists(fs::path(BIMANUAL_SKILLS_INSTALL_PREFIX) / "share" / "bimanual_skills" / "scripts" / script))
            << entry.path().filename().string() << " runs " << script << ", which is not installed";
      }
    }
  }
  EXPECT_GT(named, 8);
}

TEST(InstallSpace, AnExperimentProgramAndANodeRunFromACopy) {
  const fs::path copy = copyOfInstallSpace();
  const fs::path out = fs::temp_directory_path() / ("bimanual_skills_install_out " + std::to_string(::getpid()));
  fs::remove_all(out);
  // An output directory with a space: the plot script gets it as one argument.
  const std::string program = (copy / "lib" / "bimanual_skills" / "ik_benchmark").string();
  ASSERT_EQ(runQuietly(inCopy(copy, program + " --experiment fig32 --seed 1 --quick --out '" + out.string() + "'")), 0);
  EXPECT_TRUE(fs::exists(out / "summary.json"));
  EXPECT_TRUE(fs::exists(out / "fig32.png")) << "the installed plot script did not run";
  EXPECT_TRUE(fs::exists(out / "tables.md"));
  fs::remove_all(out);

  // The simulator node, against a master of its own: it loads config/sim.yaml and the URDF of the copy.
  const std::string log =
      (fs::temp_directory_path() / ("bimanual_skills_install_node_" + std::to_string(::getpid()))).string();
  const std::string port = std::to_string(11000 + ::getpid() % 500);
  const std::string sim = (copy / "lib" / "bimanual_skills" / "bullet_sim").string();
  const int status =
      runQuietly(inCopy(copy, "sh -c 'rosmaster --core -p " + port + " & master=$!; sleep 2; " + "timeout -s INT 8 " +
                                  sim + " _realtime_factor:=0 > \"" + log + "\" 2>&1; kill $master; wait $master'"));
  (void)status;
  const std::string output = readTextFile(log);
  EXPECT_NE(output.find("bullet_sim: 2 arms"), std::string::npos) << output;
  EXPECT_EQ(output.find("FATAL"), std::string::npos) << output;
  fs::remove(log);
  fs::remove_all(copy);
}
