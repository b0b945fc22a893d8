/// \file
/// Command line and plotting shared by the experiment programs (ik_benchmark, ps_benchmark):
///   PROGRAM --experiment NAME --seed S --out DIR [--runs R] [--quick]
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

namespace bimanual_skills::bench {

struct ExperimentOptions {
  std::string experiment;
  std::string out;
  std::uint32_t seed = 1;
  int runs = 0;  ///< 0: not given (the experiment's default).
  bool quick = false;
};

/// Parses the command line; on any error prints it with the usage line and exits with status 2. `--runs` is
/// accepted only when `with_runs`.
inline ExperimentOptions parseExperimentOptions(int argc, char** argv, const std::string& program,
                                                const std::vector<std::string>& experiments, bool with_runs) {
  std::string names;
  for (const std::string& e : experiments) names += (names.empty() ? "" : "|") + e;
  const auto usage = [&](const std::string& error) {
    std::cerr << program << ": " << error << "\nusage: " << program << " --experiment " << names
              << (with_runs ? " --runs R" : "") << " --seed S --out DIR [--quick]\n";
    std::exit(2);
  };
  const auto count = [&](const std::string& flag, const std::string& text, unsigned long maximum) {
    char* end = nullptr;
    const unsigned long value = std::strtoul(text.c_str(), &end, 10);
    if (text.empty() || text[0] == '-' || *end != '\0' || value > maximum) {
      usage(flag + " must be an integer in [0, " + std::to_string(maximum) + "]");
    }
    return value;
  };
  ExperimentOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--experiment") {
      options.experiment = value();
    } else if (arg == "--out") {
      options.out = value();
    } else if (arg == "--seed") {
      options.seed = static_cast<std::uint32_t>(count(arg, value(), 0xffffffffUL));
    } else if (arg == "--runs" && with_runs) {
      options.runs = static_cast<int>(count(arg, value(), 10000));
      if (options.runs == 0) usage("--runs must be >= 1");
    } else if (arg == "--quick") {
      options.quick = true;
    } else {
      usage("unknown argument '" + arg + "'");
    }
  }
  if (std::find(experiments.begin(), experiments.end(), options.experiment) == experiments.end()) {
    usage("--experiment must be one of " + names);
  }
  if (options.out.empty()) usage("--out DIR is required");
  return options;
}

/// Runs `/usr/bin/python3 SCRIPT DIR` (the program's plots and tables); false, with a message, if it fails.
inline bool runPlotScript(const std::string& program, const std::string& script, const std::string& out) {
  const std::string command = "/usr/bin/python3 " + script + " " + out;
  if (std::system(command.c_str()) != 0) {
    std::fprintf(stderr, "%s: plotting failed (%s); CSV and summary.json are written\n", program.c_str(),
                 command.c_str());
    return false;
  }
  std::printf("%s: wrote %s/summary.json, CSV, PNG and tables.md\n", program.c_str(), out.c_str());
  return true;
}

}  // namespace bimanual_skills::bench
