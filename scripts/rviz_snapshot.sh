#!/usr/bin/env bash
# Saves a PNG of rviz's view of a running ROS graph, headless: rviz under Xvfb with software GL, screenshot with
# ImageMagick's import. The graph (e.g. roslaunch bimanual_skills sim.launch) must already be running.
#
#   scripts/rviz_snapshot.sh [--config FILE.rviz] [--wait SECONDS] [--size WxH] OUT.png
#
# --config  rviz configuration (default: the package's config/sim.rviz)
# --wait    seconds between rviz's start and the screenshot (default 8)
# --size    screen size (default 1200x800)
set -euo pipefail

usage() { sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
config=""
wait_s=8
size=1200x800
out=""
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --config) config="$2"; shift 2 ;;
    --wait) wait_s="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    -*) echo "rviz_snapshot: unknown option $1" >&2; usage >&2; exit 2 ;;
    *) out="$1"; shift ;;
  esac
done
[ -n "$out" ] || { echo "rviz_snapshot: OUT.png is required" >&2; usage >&2; exit 2; }
if [ -z "$config" ]; then
  config="$(rospack find bimanual_skills 2>/dev/null)/config/sim.rviz"
  [ -f "$config" ] || config="$here/../config/sim.rviz"
fi
[ -f "$config" ] || { echo "rviz_snapshot: no rviz configuration $config" >&2; exit 2; }
rostopic list > /dev/null 2>&1 || { echo "rviz_snapshot: no ROS master (start the graph first)" >&2; exit 1; }

# A free X display number.
display=99
while [ -e "/tmp/.X${display}-lock" ]; do display=$((display + 1)); done
Xvfb ":$display" -screen 0 "${size}x24" -nolisten tcp > /dev/null 2>&1 &
xvfb=$!
rviz_pid=""
cleanup() {
  [ -n "$rviz_pid" ] && kill "$rviz_pid" 2> /dev/null || true
  kill "$xvfb" 2> /dev/null || true
}
trap cleanup EXIT
sleep 1

# rviz sometimes dies at its first start under software GL: one retry.
for attempt in 1 2; do
  DISPLAY=":$display" LIBGL_ALWAYS_SOFTWARE=1 rviz -d "$config" > /tmp/rviz_snapshot.log 2>&1 &
  rviz_pid=$!
  sleep "$wait_s"
  if kill -0 "$rviz_pid" 2> /dev/null; then
    DISPLAY=":$display" import -window root "$out"
    echo "rviz_snapshot: wrote $out ($size, display :$display, $config)"
    exit 0
  fi
  echo "rviz_snapshot: rviz exited (attempt $attempt; log /tmp/rviz_snapshot.log)" >&2
  rviz_pid=""
done
exit 1
