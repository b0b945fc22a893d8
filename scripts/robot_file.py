#!/usr/bin/env python3
"""Reads a robot file (config/robots/*.yaml, sim/robot_file.hpp) for launch files.

Usage: robot_file.py urdf FILE   prints the robot's URDF (for robot_description: <param command="..."/>)
       robot_file.py path FILE   prints the URDF's path
Relative paths in the file are relative to its directory. Exits 1 with the reason for a file that cannot be read
or names no URDF."""
import os
import sys

import yaml


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in ("urdf", "path"):
        print(__doc__, file=sys.stderr if len(sys.argv) > 1 and sys.argv[1] not in ("-h", "--help") else sys.stdout)
        return 0 if len(sys.argv) > 1 and sys.argv[1] in ("-h", "--help") else 1
    robot = sys.argv[2]
    try:
        with open(robot, encoding="utf-8") as f:
            data = yaml.safe_load(f)
        urdf = data["urdf"]
    except (OSError, yaml.YAMLError, TypeError, KeyError) as e:
        print(f"robot_file.py: cannot read the URDF entry of robot file '{robot}': {e}", file=sys.stderr)
        return 1
    path = urdf if os.path.isabs(urdf) else os.path.join(os.path.dirname(os.path.abspath(robot)), urdf)
    if sys.argv[1] == "path":
        print(path)
        return 0
    try:
        with open(path, encoding="utf-8") as f:
            sys.stdout.write(f.read())
    except OSError as e:
        print(f"robot_file.py: robot file '{robot}': cannot read its URDF: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
