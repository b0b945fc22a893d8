#!/usr/bin/env bash
# make demo's run: fold_learner on a ROS master of its own (on a free port of this machine, so a running roscore is
# left alone), and its exit status as the script's. Usage: fold_demo.sh CONFIG OUT [_PARAM:=VALUE ...]
# (install/setup.bash sourced); the parameters go to fold_learner, e.g. _reward:=goal.
set -euo pipefail
usage="usage: fold_demo.sh CONFIG OUT [_PARAM:=VALUE ...]   (fold_learner on a ROS master of its own)"
case "${1:-}" in
  -h | --help) echo "$usage"; exit 0 ;;
esac
if [ $# -lt 2 ]; then
  echo "$usage" >&2
  exit 2
fi
config=$1 out=$2
shift 2
port=$((11400 + RANDOM % 400))
while (echo > /dev/tcp/localhost/$port) 2>/dev/null; do port=$((port + 1)); done
export ROS_MASTER_URI=http://localhost:$port
rosmaster --core -p "$port" > /dev/null 2>&1 &
master=$!
trap 'kill $master 2>/dev/null; wait $master 2>/dev/null || true' EXIT
for _ in $(seq 100); do (echo > /dev/tcp/localhost/$port) 2>/dev/null && break; sleep 0.1; done
rosrun bimanual_skills fold_learner _config:="$config" _out:="$out" "$@"
