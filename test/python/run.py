"""Runs the Python tests (pytest, arguments as pytest's) with the numerics pinned, as every C++ program runs: they
compare rollouts with the C++ programs' and across processes (Ray's workers start pinned). make test runs it."""
import sys

import bimanual_skills

bimanual_skills.pin_numerics()  # re-executes this program once, before pytest captures its output

import pytest  # noqa: E402

sys.exit(pytest.main(sys.argv[1:]))
