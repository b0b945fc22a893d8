/// \file
/// The command line of the micro-benchmark programs: Google Benchmark's own flags (--benchmark_filter=REGEX,
/// --benchmark_format=json, --benchmark_repetitions=N, ...), the program's own switches, `--help`/`-h` (the
/// program's description, its switches and Google Benchmark's flags on stdout, exit 0), and anything else: the error
/// and the usage on stderr, exit status 2.
#pragma once

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

namespace bimanual_skills::bench {

/// A switch of the program itself: its flag and help line.
struct BenchmarkSwitch {
  std::string flag;
  std::string help;
};

/// Parses argv (removing what it consumes) and initialises Google Benchmark. Returns, for each of `switches`, whether
/// it was given.
inline std::vector<bool> initialiseBenchmarks(int& argc, char** argv, const std::string& program,
                                              const std::string& description,
                                              const std::vector<BenchmarkSwitch>& switches = {}) {
  const auto usage = [&](std::ostream& out) {
    out << "usage: " << program << " [--benchmark_...=VALUE ...]";
    for (const BenchmarkSwitch& s : switches) out << " [" << s.flag << "]";
    out << "\n\n" << description << "\n\noptions:\n";
    for (const BenchmarkSwitch& s : switches) out << "  " << s.flag << "  " << s.help << "\n";
    out << "  -h, --help  print this help and exit\n\nGoogle Benchmark's options:\n";
  };
  std::vector<bool> given(switches.size(), false);
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      usage(std::cout);
      std::cout.flush();
      benchmark::PrintDefaultHelp();
      std::exit(0);
    }
    bool consumed = false;
    for (std::size_t s = 0; s < switches.size(); ++s) {
      if (arg == switches[s].flag) given[s] = consumed = true;
    }
    if (!consumed) argv[kept++] = argv[i];
  }
  argc = kept;
  benchmark::Initialize(&argc, argv);
  if (argc > 1) {
    std::cerr << program << ": unknown argument '" << argv[1] << "'\n";
    usage(std::cerr);
    std::exit(2);
  }
  return given;
}

}  // namespace bimanual_skills::bench
