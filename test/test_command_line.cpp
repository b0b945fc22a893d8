// Every program of the project answers --help and -h with its usage on stdout and exit status 0, and an unknown
// argument with the error and the usage on stderr and exit status 2. The programs' paths come from CMake
// (PROGRAMS: a comma-separated list). CommandLine's options that take one of a set of values accept only those.
#include "cli/command_line.hpp"
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

/// Parses `arguments` (after the program's name) with one choice option --mode a|b|c; the value it took.
std::string parseMode(std::vector<std::string> arguments) {
  bimanual_skills::cli::CommandLine line("prog", "--mode a|b|c", "A test program.");
  std::string mode = "a";
  line.choice("--mode", {"a", "b", "c"}, "the mode (default a)", &mode);
  arguments.insert(arguments.begin(), "prog");
  std::vector<char*> argv;
  for (std::string& a : arguments) argv.push_back(a.data());
  line.parse(static_cast<int>(argv.size()), argv.data());
  return mode;
}

TEST(CommandLine, AChoiceTakesOneOfItsValuesAndRejectsOthers) {
  EXPECT_EQ(parseMode({}), "a");
  EXPECT_EQ(parseMode({"--mode", "c"}), "c");
  EXPECT_EXIT(parseMode({"--mode", "d"}), ::testing::ExitedWithCode(2), "--mode: 'd' is not one of a\\|b\\|c");
  EXPECT_EXIT(parseMode({"--mode", "A"}), ::testing::ExitedWithCode(2), "is not one of");
  EXPECT_EXIT(parseMode({"--mode"}), ::testing::ExitedWithCode(2), "--mode needs a value a\\|b\\|c");
  EXPECT_EXIT(parseMode({"--help"}), ::testing::ExitedWithCode(0), "");
}

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
