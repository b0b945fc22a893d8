// The gtests' main: the numerics pinned first (src/cli/pinned_numerics.hpp), so that a test of a seeded result sees
// what the programs compute, on any x86-64 machine.
#include "cli/pinned_numerics.hpp"

#include <gtest/gtest.h>

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
