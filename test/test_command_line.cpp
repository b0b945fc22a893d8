// Every program of the project answers --help and -h with its usage on stdout and exit status 0, and an unknown
// argument with the error and the usage on stderr and exit status 2. The programs' paths come from CMake
// (PROGRAMS: a comma-separated list).
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

std::vector<std::string> programs() {
  std::vector<std::string> out;
  std::stringstream list(PROGRAMS);
  for (std::string path; std::getline(list, path, ',');) {
    if (!path.empty()) out.push_back(path);
  }
  return out;
}

struct Outcome {
  int status = -1;
  std::string out, err;
};

Outcome run(const std::string& program, const std::string& arguments) {
  const std::string out = "/tmp/bimanual_skills_cli_out.txt", err = "/tmp/bimanual_skills_cli_err.txt";
  const int raw = std::system((program + " " + arguments + " > " + out + " 2> " + err + " < /dev/null").c_str());
  Outcome outcome;
  outcome.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  outcome.out = bimanual_skills::testing::readTextFile(out);
  outcome.err = bimanual_skills::testing::readTextFile(err);
  return outcome;
}

}  // namespace

TEST(CommandLine, EveryProgramPrintsItsUsageOnHelpAndRejectsUnknownArguments) {
  ASSERT_GE(programs().size(), 8u);
  for (const std::string& program : programs()) {
    for (const std::string flag : {"--help", "-h"}) {
      const Outcome help = run(program, flag);
      EXPECT_EQ(help.status, 0) << program << " " << flag << "\n" << help.err;
      EXPECT_NE(help.out.find("usage:"), std::string::npos) << program << " " << flag << " printed:\n" << help.out;
    }
    const Outcome bad = run(program, "--no-such-option");
    EXPECT_EQ(bad.status, 2) << program << "\n" << bad.out << bad.err;
    EXPECT_NE(bad.err.find("usage:"), std::string::npos) << program << " wrote on stderr:\n" << bad.err;
    EXPECT_NE(bad.err.find("--no-such-option"), std::string::npos) << program;
    EXPECT_EQ(bad.out.find("usage:"), std::string::npos) << program << ": the usage of an error goes to stderr";
  }
}
