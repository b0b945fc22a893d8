#!/bin/bash
# The fault run of the rollout workers on a real learning: fold_learner dispatches a learning file's rollouts to
# three rollout workers; after the first rollouts this script kills worker_0 (SIGKILL) and stops worker_1
# (SIGSTOP) for longer than the learner's worker timeout, then lets it go on (it rejoins at a later batch). The
# learning curve (epochs.csv) and every rollout's reward terms must equal those of a learning on threads of the
# same file and seed: REFERENCE, a finished fold_learner directory (e.g. make demo's build/fold_demo), or a new
# threads run when not given.
#   scripts/rollout_fault_run.sh [--config FILE] [--out DIR] [--reference DIR] [--timeout S]
# Needs the workspace's setup.bash sourced. Starts its own ROS master on a free port, on the loopback interface.
set -euo pipefail
usage() { sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; }
config="" out="build/rollout_fault_run" reference="" timeout=20
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --config) config="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --reference) reference="$2"; shift 2 ;;
    --timeout) timeout="$2"; shift 2 ;;
    *) echo "rollout_fault_run: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
command -v roslaunch > /dev/null || { echo "rollout_fault_run: source the workspace's setup.bash first" >&2; exit 2; }
package=$(rospack find bimanual_skills)
[ -n "$config" ] || config="$package/config/fold_demo.yaml"
config=$(readlink -f "$config")
mkdir -p "$out"
out=$(readlink -f "$out")
rm -rf "$out/dispatched"
export ROS_HOSTNAME=localhost
port=$((12311 + $$ % 1000))
export ROS_MASTER_URI=http://localhost:$port

roslaunch -p "$port" bimanual_skills rollout_workers.launch workers:=3 > "$out/workers.log" 2>&1 &
launcher=$!
trap 'kill -INT $launcher 2>/dev/null || true; wait $launcher 2>/dev/null || true' EXIT
pid_of() {
  for _ in $(seq 100); do
    if p=$(rosparam get "/rollout_workers/$1/pid" 2>/dev/null); then echo "$p"; return; fi
    sleep 0.2
  done
  echo "rollout_fault_run: $1 did not start (see $out/workers.log)" >&2; exit 1
}
killed=$(pid_of worker_0) stopped=$(pid_of worker_1)
learner_bin=$(catkin_find --libexec bimanual_skills fold_learner | head -1)
[ -x "$learner_bin" ] || { echo "rollout_fault_run: no fold_learner built" >&2; exit 1; }
start=$(date +%s)
"$learner_bin" _config:="$config" _out:="$out/dispatched" _worker_namespace:=/rollout_workers \
  _worker_timeout:="$timeout" > "$out/learner.log" 2>&1 &
learner=$!
until [ "$({ wc -l < "$out/dispatched/rollouts.csv"; } 2>/dev/null || echo 0)" -ge 4 ]; do
  kill -0 $learner 2>/dev/null || { echo "rollout_fault_run: the learner ended early (see $out/learner.log)" >&2; exit 1; }
  sleep 0.1
done
echo "rollout_fault_run: $(( $(date +%s) - start )) s in: kill worker_0 (pid $killed), stop worker_1 (pid $stopped) for $((timeout + 10)) s"
kill -KILL "$killed"
kill -STOP "$stopped"
sleep $((timeout + 10))
kill -CONT "$stopped"
echo "rollout_fault_run: worker_1 continued"
wait $learner || { echo "rollout_fault_run: the learner failed (see $out/learner.log)" >&2; exit 1; }
echo "rollout_fault_run: dispatched learning done in $(( $(date +%s) - start )) s"
grep -E "lost|joined|\[batch\]" "$out/learner.log" | sed 's/\x1b\[[0-9;]*m//g' > "$out/dispatch_events.log" || true
cat "$out/dispatch_events.log"

if [ -z "$reference" ]; then
  reference="$out/threads"
  rm -rf "$reference"
  "$learner_bin" _config:="$config" _out:="$reference" > "$out/threads.log" 2>&1
fi
key() { tail -n +2 "$1/rollouts.csv" | cut -d, -f1-15 | sort; }
if cmp -s "$out/dispatched/epochs.csv" "$reference/epochs.csv" && cmp -s <(key "$out/dispatched") <(key "$reference"); then
  echo "rollout_fault_run: IDENTICAL: epochs.csv and the $(key "$reference" | wc -l) rollouts' rewards equal $reference's"
else
  echo "rollout_fault_run: DIFFERENT from $reference" >&2
  diff <(key "$out/dispatched") <(key "$reference") | head -5 >&2 || true
  exit 1
fi
