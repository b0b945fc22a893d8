/// \file
/// The `learning:` section of a learning file (module-private to rollout): the keys every learner shares, read the
/// same way for each (the fold's FoldLearningConfig, the generic DMP learner's DmpLearningConfig, whose members of
/// these names they are), beside the keys a learner adds.
#pragma once

#include "io/yaml_io.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

/// The search schedule and settings that every learner's section has.
inline const std::vector<std::string> kSharedLearningKeys = {
    "algorithms", "runs",          "updates",          "rollouts",          "reuse",
    "epsilon",    "eta",           "initial_stddev",   "covariance_memory", "seed",
    "jobs",       "robot_retries", "robot_fault_limit"};

/// Reads `learning` into `c` (a config with the members algorithms, runs, updates, rollouts, reuse, epsilon, eta,
/// initial_stddev, covariance_memory, seed, jobs, robot_retries, robot_fault_limit): entries absent keep c's values.
/// Fails (std::invalid_argument naming `at` and the entry) on a key neither shared nor in `own_keys`, `algorithms`
/// that is not a list, a number where an integer belongs and a seed outside [0, 2^32). The learner reads its own keys
/// after this; ranges are its validate()'s.
template <typename Config>
void readSharedLearning(const YAML::Node& learning, const std::string& at, Config& c,
                        const std::vector<std::string>& own_keys) {
  std::vector<std::string> keys = kSharedLearningKeys;
  keys.insert(keys.end(), own_keys.begin(), own_keys.end());
  io::checkKeys(learning, at, keys);
  if (const YAML::Node algorithms = learning["algorithms"]) {
    if (!algorithms.IsSequence()) io::fail(at + ": 'algorithms' must be a list of names");
    c.algorithms.clear();
    for (const YAML::Node& a : algorithms) {
      if (!a.IsScalar()) io::fail(at + ": each of 'algorithms' must be a name");
      c.algorithms.push_back(a.as<std::string>());
    }
  }
  for (const auto& [key, member] :
       {std::pair{"runs", &c.runs}, std::pair{"updates", &c.updates}, std::pair{"rollouts", &c.rollouts},
        std::pair{"reuse", &c.reuse}, std::pair{"jobs", &c.jobs}, std::pair{"robot_retries", &c.robot_retries},
        std::pair{"robot_fault_limit", &c.robot_fault_limit}}) {
    if (learning[key]) *member = io::readInt(learning, key, at);
  }
  c.epsilon = io::readDouble(learning, "epsilon", at, c.epsilon);
  c.eta = io::readDouble(learning, "eta", at, c.eta);
  c.initial_stddev = io::readDouble(learning, "initial_stddev", at, c.initial_stddev);
  c.covariance_memory = io::readDouble(learning, "covariance_memory", at, c.covariance_memory);
  if (learning["seed"]) {
    const double seed = io::readDouble(learning, "seed", at);
    if (!(seed >= 0.0) || seed > 4294967295.0 || seed != static_cast<double>(static_cast<std::uint32_t>(seed))) {
      io::fail(at + ": 'seed' must be an integer in [0, 2^32)");
    }
    c.seed = static_cast<std::uint32_t>(seed);
  }
}

}  // namespace bimanual_skills::rollout
