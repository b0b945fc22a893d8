/// \file
/// Command line and plotting shared by the experiment programs (ik_benchmark, ps_benchmark, ...):
///   PROGRAM --experiment NAME --seed S --out DIR [--runs R] [--jobs N] [--quick] [program options]
#pragma once

#include "cli/command_line.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/summary_json.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace bimanual_skills::bench {

struct ExperimentOptions {
  std::string experiment;
  std::string out;
  std::uint32_t seed = 1;
  int runs = 0;  ///< 0: not given (the experiment's default).
  int jobs = 1;  ///< Independent runs in parallel (programs that take --jobs; default: the cores).
  bool quick = false;
};

/// What an experiment program accepts besides the common options.
struct ExperimentProgram {
  std::string name;
  std::string description;               ///< What the program reproduces (printed by --help).
  std::vector<std::string> experiments;  ///< Accepted --experiment names.
  bool with_runs = false;                ///< Accepts --runs R.
  bool with_jobs = false;                ///< Accepts --jobs N.
  /// Declares the program's own options on the command line (bound to the program's variables).
  std::function<void(cli::CommandLine&)> extra;
};

/// Parses the command line: --help/-h prints the usage and exits 0; an error prints it with the usage on stderr and
/// exits 2.
inline ExperimentOptions parseExperimentOptions(int argc, char** argv, const ExperimentProgram& program) {
  const std::string names = cli::joined(program.experiments, "|");
  ExperimentOptions options;
  long seed = options.seed, runs = 0;
  long jobs = std::max(1u, std::thread::hardware_concurrency());
  cli::CommandLine line(program.name,
                        "--experiment " + names + " --seed S --out DIR" + (program.with_runs ? " [--runs R]" : "") +
                            (program.with_jobs ? " [--jobs N]" : "") + " [--quick] [options]",
                        program.description);
  line.choice("--experiment", program.experiments, "the experiment to run", &options.experiment);
  line.option("--seed", "S", "seed of every random generator (default 1)", &seed, 0, 0xffffffffL);
  line.option("--out", "DIR", "output directory: summary.json, CSV, PNG and tables.md", &options.out);
  if (program.with_runs)
    line.option("--runs", "R", "independent runs per algorithm (default: the thesis')", &runs, 1, 10000);
  if (program.with_jobs) {
    line.option("--jobs", "N", "independent runs in parallel (default: the cores; results do not depend on it)", &jobs,
                1, 256);
  }
  line.flag("--quick", "a smoke run of a few seconds (fewer samples, runs and updates)", &options.quick);
  if (program.extra) program.extra(line);
  line.parse(argc, argv);
  if (options.experiment.empty()) line.fail("--experiment " + names + " is required");
  if (options.out.empty()) line.fail("--out DIR is required");
  // Absolute, so that the nodes an experiment launches (which run in ~/.ros) write where the program reads.
  options.out = std::filesystem::absolute(options.out).lexically_normal().string();
  options.seed = static_cast<std::uint32_t>(seed);
  options.runs = static_cast<int>(runs);
  options.jobs = static_cast<int>(jobs);
  return options;
}

using io::JsonRow;

/// Writes DIR/summary.json of an experiment program (io::writeSummaryJson). \throws std::runtime_error.
inline void writeSummaryJson(const ExperimentOptions& options, const std::string& program,
                             const std::vector<JsonRow>& rows) {
  io::writeSummaryJson(options.out + "/summary.json",
                       {program, options.experiment, options.seed, options.quick, cli::numericsState()}, rows);
}

/// Runs the package's plot script `scripts/SCRIPT` as `/usr/bin/python3 SCRIPT DIR` (an argument vector, no shell:
/// any DIR works), for the program's plots and tables; false, with a message, if it cannot run or fails.
inline bool runPlotScript(const std::string& program, const std::string& script, const std::string& out) {
  std::string path;
  try {
    path = cli::packageFile("scripts/" + script);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: plotting skipped: %s; CSV and summary.json are written\n", program.c_str(), e.what());
    return false;
  }
  std::fflush(stdout);
  const pid_t child = ::fork();
  if (child == 0) {
    const char* argv[] = {"/usr/bin/python3", path.c_str(), out.c_str(), nullptr};
    ::execv(argv[0], const_cast<char* const*>(argv));
    std::_Exit(127);
  }
  int status = -1;
  if (child < 0 || ::waitpid(child, &status, 0) != child || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "%s: plotting failed (/usr/bin/python3 %s '%s'); CSV and summary.json are written\n",
                 program.c_str(), path.c_str(), out.c_str());
    return false;
  }
  std::printf("%s: wrote %s/summary.json, CSV, PNG and tables.md\n", program.c_str(), out.c_str());
  return true;
}

}  // namespace bimanual_skills::bench
