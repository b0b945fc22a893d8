#!/usr/bin/env python3
"""Checks that modules stand on floors (docs/ARCHITECTURE.md, "Floors"), with the floors taken from the CMake targets
themselves: a file of module M may include headers of M and of the modules whose libraries M's library links,
directly or through others (target_link_libraries in CMakeLists.txt, PUBLIC or PRIVATE). So a module never includes
one above it or beside it, and the build and this check cannot disagree. Programs and tests (nodes/, bench/, test/,
src/tools/) stand on top and may include anything.

Usage: check_floors.py [REPO]   (default: the repository this script is in). Prints each offending include as
FILE:LINE: MODULE includes HEADER of MODULE (not linked by bimanual_skills_...), the floors it computed, and exits 1
if there is any, else 0."""
import os
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
# A library target of the package and its link list (multi-line): target_link_libraries(NAME ... )
LINKS = re.compile(r"target_link_libraries\(\s*(bimanual_skills_\w+)([^)]*)\)", re.S)
MODULE_FUNCTION = re.compile(r"bimanual_skills_module\((\w+)\)")
ADD_LIBRARY = re.compile(r"add_library\((bimanual_skills_\w+)\s")
TOP = ("nodes", "bench", "test", "tools")
# Folders whose target is not bimanual_skills_<folder>: ros_layer/ (and its sub-folders), testing/ (test support),
# cli/ (header-only, programs only: no target, so no module may include it).
TARGET_OF = {
    "ros_layer": "bimanual_skills_ros",
    "ros_layer/workers": "bimanual_skills_ros_workers",
    "ros_layer/robot": "bimanual_skills_ros_robot",
    "testing": "bimanual_skills_testing",
}


def read_targets(repo):
    """Library targets of the package -> the package libraries each links (directly)."""
    with open(os.path.join(repo, "CMakeLists.txt"), encoding="utf-8") as f:
        text = re.sub(r"#[^\n]*", "", f.read())
    targets = {f"bimanual_skills_{m}": set() for m in MODULE_FUNCTION.findall(text)}
    for name in ADD_LIBRARY.findall(text):
        targets.setdefault(name, set())
    for name, body in LINKS.findall(text):
        if name in targets:
            targets[name] |= {w for w in body.split() if w in targets or w.startswith("bimanual_skills_")}
    # The test support library wraps the allocation counter; both are one module (testing).
    targets.setdefault("bimanual_skills_testing", set()).add("bimanual_skills_allocation_counter")
    return targets


def closure(targets, name):
    seen, todo = set(), [name]
    while todo:
        for dep in targets.get(todo.pop(), ()):
            if dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return seen


def floors(targets):
    """Floor of each target: 0 without package libraries below it, else one above the highest it links."""
    memo = {}

    def floor(name, stack=()):
        if name in memo:
            return memo[name]
        if name in stack:
            raise SystemExit(f"check_floors: a cycle of libraries through {name}")
        deps = [d for d in targets.get(name, ()) if d in targets and d != "bimanual_skills_allocation_counter"]
        memo[name] = 1 + max((floor(d, stack + (name,)) for d in deps), default=-1)
        return memo[name]

    return {name: floor(name) for name in targets}


def module_of_file(rel):
    """(module, target) of a file of the repository; module "top" for programs and tests; None outside modules."""
    parts = rel.split("/")
    if parts[0] in ("nodes", "bench", "test") or parts[:2] == ["src", "tools"]:
        return ("top", None)
    if parts[0] == "include" and len(parts) > 3 and parts[1] == "bimanual_skills":
        folder = parts[2:-1]
    elif parts[0] == "src" and len(parts) > 2:
        folder = parts[1:-1]
    else:
        return None
    key = "/".join(folder[:2])
    if key in TARGET_OF:
        return (key, TARGET_OF[key])
    return (folder[0], TARGET_OF.get(folder[0], f"bimanual_skills_{folder[0]}"))


def module_of_header(header, including_path, repo):
    """(module, target) of an included header as the compiler finds it: beside the including file, then in the
    package's include directories; None for generated and foreign headers."""
    beside = os.path.join(os.path.dirname(including_path), header)
    candidates = [beside] + [os.path.join(repo, d, header) for d in ("include", "src", "nodes", "bench", "test")]
    for candidate in candidates:
        if os.path.isfile(candidate):
            return module_of_file(os.path.relpath(os.path.realpath(candidate), repo))
    return None


def main():
    if len(sys.argv) > 1 and sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    targets = read_targets(repo)
    problems = 0
    for top in ("include", "src", "nodes", "bench", "test"):
        for root, _, files in os.walk(os.path.join(repo, top)):
            for name in sorted(files):
                if not name.endswith((".hpp", ".cpp", ".h")):
                    continue
                path = os.path.join(root, name)
                rel = os.path.relpath(path, repo)
                mine = module_of_file(rel)
                if mine is None or mine[0] == "top":
                    continue
                with open(path, encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        match = INCLUDE.match(line)
                        if not match:
                            continue
                        other = module_of_header(match.group(1), path, repo)
                        if other is None or other == mine:
                            continue
                        if other[0] == "top" or other[1] not in closure(targets, mine[1]) | {mine[1]}:
                            problems += 1
                            print(f"{rel}:{number}: {mine[0]} includes {match.group(1)} of {other[0]} "
                                  f"(not linked by {mine[1]})")
    levels = floors(targets)
    print("check_floors: floors from CMakeLists.txt: " +
          "; ".join(f"{f}: " + " ".join(sorted(n.replace("bimanual_skills_", "") for n in levels if levels[n] == f))
                    for f in sorted(set(levels.values()))))
    if problems:
        print(f"check_floors: {problems} include(s) of a module that the including module's library does not link")
        return 1
    print("check_floors: every include is of the own module or of a module its library links")
    return 0


if __name__ == "__main__":
    sys.exit(main())
