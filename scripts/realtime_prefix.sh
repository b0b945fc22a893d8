#!/usr/bin/env bash
# Runs a command wholly at SCHED_FIFO, as a robot's driver and controllers run: every thread, ROS's receive and
# publish threads too. Where the policy is not permitted (no CAP_SYS_NICE, no real-time budget) it says so and runs
# the command unchanged. A roslaunch launch-prefix (sim.launch's process_priority).
#
#   scripts/realtime_prefix.sh PRIORITY COMMAND [ARGS...]
#
# PRIORITY  1-99, SCHED_FIFO's priority; 0 runs the command unchanged
set -euo pipefail

usage() { sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; }
case "${1:-}" in
  -h|--help) usage; exit 0 ;;
esac
[ $# -ge 2 ] || { echo "realtime_prefix: PRIORITY and COMMAND are required" >&2; usage >&2; exit 2; }
priority="$1"
shift
[[ "$priority" =~ ^[0-9]+$ ]] && [ "$priority" -le 99 ] ||
  { echo "realtime_prefix: PRIORITY must be 0-99, not '$priority'" >&2; exit 2; }
[ "$priority" -gt 0 ] || exec "$@"
if chrt -f "$priority" true 2>/dev/null; then
  exec chrt -f "$priority" "$@"
fi
echo "realtime_prefix: SCHED_FIFO $priority not permitted here; $1 runs at the normal policy (its states and" \
  "commands may come late under load)" >&2
exec "$@"
