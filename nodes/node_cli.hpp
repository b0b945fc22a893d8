/// \file
/// The command line of the ROS nodes: `--help` or `-h` prints the node's usage on stdout and exits 0 (no master
/// needed); ROS remappings (`name:=value`, `__ns:=...`, `_param:=...`) pass through to ros::init; anything else is an
/// error: the usage on stderr and exit status 2.
#pragma once

#include <cstdlib>
#include <iostream>
#include <string>

namespace bimanual_skills::nodes {

/// Call first in main(), before ros::init. `usage`: synopsis, what the node does, its parameters, topics and
/// services.
inline void handleCommandLine(int argc, char** argv, const std::string& usage) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::cout << usage;
      std::exit(0);
    }
    if (arg.find(":=") == std::string::npos) {
      std::cerr << argv[0] << ": unknown argument '" << arg << "' (a node takes ROS remappings name:=value)\n" << usage;
      std::exit(2);
    }
  }
}

}  // namespace bimanual_skills::nodes
