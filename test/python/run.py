"""Runs the Python tests (pytest, arguments as pytest's) with the numerics pinned, as every C++ program runs: they
compare rollouts with the C++ programs' and across processes (Ray's workers start pinned). make test runs it, with
BIMANUAL_SKILLS_REQUIRE_VENV=1 when build/venv is there (Ray and Gymnasium must then import)."""
import os
import sys

import bimanual_skills

bimanual_skills.pin_numerics()  # re-executes this program once, before pytest captures its output

import pytest  # noqa: E402

if os.environ.get("BIMANUAL_SKILLS_REQUIRE_VENV") == "1":
    # make test with build/venv: the Ray and Gymnasium tests must run, not skip.
    for module in ("ray", "gymnasium"):
        try:
            __import__(module)
        except ImportError as e:
            sys.exit("run.py: %s is not importable from %s (make venv): %s" % (module, sys.executable, e))

sys.exit(pytest.main(sys.argv[1:]))
