#!/usr/bin/env bash
# make demo's run: fold_learner on a ROS master of its own (on a free port of this machine, so a running roscore is
# left alone), and its exit status as the script's. Usage: fold_demo.sh CONFIG OUT (install/setup.bash sourced).
set -euo pipefail
config=$1 out=$2
port=$((11400 + RANDOM % 400))
while (echo > /dev/tcp/localhost/$port) 2>/dev/null; do port=$((port + 1)); done
export ROS_MASTER_URI=http://localhost:$port
rosmaster --core -p "$port" > /dev/null 2>&1 &
master=$!
trap 'kill $master 2>/dev/null; wait $master 2>/dev/null || true' EXIT
for _ in $(seq 100); do (echo > /dev/tcp/localhost/$port) 2>/dev/null && break; sleep 0.1; done
rosrun bimanual_skills fold_learner _config:="$config" _out:="$out"
