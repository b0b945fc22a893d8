// The C++ side of test/python/test_bindings.py: one rollout of a registry task's initial policy, as a C++ program
// runs it (numerics pinned), printed bit for bit (hexadecimal floats) for the Python module's to be compared with.
//   python_reference NAME CONFIG SEED
#include "bimanual_skills/rollout/task_registry.hpp"
#include "cli/pinned_numerics.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  if (argc != 4) {
    std::fprintf(stderr, "usage: python_reference NAME CONFIG SEED\n");
    return 2;
  }
  try {
    const auto task = bimanual_skills::rollout::makeRolloutTask(argv[1], argv[2]);
    const auto result =
        task->run(task->initialParameters(), static_cast<std::uint32_t>(std::strtoul(argv[3], nullptr, 10)));
    std::printf("outcome %s\nreward %a\n", result.outcome.c_str(), result.reward);
    for (Eigen::Index i = 0; i < result.terms.size(); ++i) std::printf("term %a\n", result.terms[i]);
    std::printf("numerics %s\n", bimanual_skills::cli::numericsState().c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "python_reference: %s\n", e.what());
    return 1;
  }
  return 0;
}
