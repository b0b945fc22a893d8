#!/usr/bin/env python3
"""Checks that modules stand on floors (docs/ARCHITECTURE.md, "Floors"): a file includes only headers of its own
module or of modules on lower floors, never above and never sideways on its own floor.

Usage: check_floors.py [REPO]   (default: the repository this script is in). Prints each offending include as
FILE:LINE: MODULE (floor F) includes HEADER of MODULE (floor G), and exits 1 if there is any, else 0."""
import os
import re
import sys

# Module -> floor. Ground first; programs (nodes, bench, tools) on top.
FLOORS = {
    "kinematics": 0, "learning": 0, "signal": 0, "realtime": 0, "parallel": 0, "io": 0, "testing": 0,
    "dynamics": 1,
    "control": 2, "primitives": 2, "sim": 2, "vision": 2, "workspace": 2,
    "tasks": 3,
    "rollout": 4,
    "ros_layer": 5, "cli": 5,
    "nodes": 6, "bench": 6, "tools": 6, "test": 6,
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def module_of_file(rel):
    """Module of a file of the repository, or None for files outside the modules."""
    parts = rel.split("/")
    if parts[0] in ("include",) and len(parts) > 2 and parts[1] == "bimanual_skills":
        return parts[2] if parts[2] in FLOORS else None
    if parts[0] == "src" and len(parts) > 2:
        return parts[1] if parts[1] in FLOORS else None
    if parts[0] in ("nodes", "bench", "test"):
        return parts[0]
    return None


def module_of_header(header, including_path, repo):
    """Module of an included header as the compiler finds it: beside the including file, then in the package's
    include directories (include/, src/, nodes/, bench/); None for generated and foreign headers."""
    beside = os.path.join(os.path.dirname(including_path), header)
    candidates = [beside] + [os.path.join(repo, d, header) for d in ("include", "src", "nodes", "bench", "test")]
    for candidate in candidates:
        if os.path.isfile(candidate):
            return module_of_file(os.path.relpath(os.path.realpath(candidate), repo))
    return None


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if len(sys.argv) > 1 and sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0
    problems = 0
    for top in ("include", "src", "nodes", "bench", "test"):
        for root, _, files in os.walk(os.path.join(repo, top)):
            for name in sorted(files):
                if not name.endswith((".hpp", ".cpp", ".h")):
                    continue
                path = os.path.join(root, name)
                rel = os.path.relpath(path, repo)
                module = module_of_file(rel)
                if module is None:
                    continue
                with open(path, encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        match = INCLUDE.match(line)
                        if not match:
                            continue
                        other = module_of_header(match.group(1), path, repo)
                        if other is None or other == module:
                            continue
                        floor, other_floor = FLOORS[module], FLOORS[other]
                        if module == "test" and other != "test":
                            continue  # tests stand above everything they test
                        if other_floor >= floor:
                            problems += 1
                            print(f"{rel}:{number}: {module} (floor {floor}) includes {match.group(1)} "
                                  f"of {other} (floor {other_floor})")
    if problems:
        print(f"check_floors: {problems} include(s) against the floors (docs/ARCHITECTURE.md, Floors)")
        return 1
    print("check_floors: every include stands on a lower floor or its own module")
    return 0


if __name__ == "__main__":
    sys.exit(main())
