#!/usr/bin/env bash
# Runs every gtest and rostest of the package through colcon and prints the counts.
# Exit status: non-zero if any test failed or errored, or if no test ran.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="/usr/bin:/bin:$PATH"

# The modules' floors (docs/ARCHITECTURE.md): no include from a lower floor to a higher one, none sideways.
/usr/bin/python3 scripts/check_floors.py

results=build/bimanual_skills/test_results
rm -rf "$results"
# colcon's setup scripts read unset variables
set +u
# shellcheck disable=SC1091
source install/setup.bash
set -u
colcon test --base-paths . || true

set +e
summary=$(colcon test-result --test-result-base "$results" --verbose)
status=$?
set -e
echo "$summary"
line=$(grep -E '^Summary: ' <<<"$summary" | tail -n 1)
if [[ ! $line =~ Summary:\ ([0-9]+)\ tests?,\ ([0-9]+)\ errors?,\ ([0-9]+)\ failures?,\ ([0-9]+)\ skipped ]]; then
  echo "run_tests: no test results found under $results"
  exit 1
fi
total=${BASH_REMATCH[1]} errors=${BASH_REMATCH[2]} failures=${BASH_REMATCH[3]} skipped=${BASH_REMATCH[4]}
failed=$((errors + failures))
passed=$((total - failed - skipped))
echo
echo "make test: $passed passed, $failed failed, $skipped skipped"
if [ "$total" -eq 0 ]; then
  echo "run_tests: no test ran"
  exit 1
fi
[ "$status" -eq 0 ] && [ "$failed" -eq 0 ]
