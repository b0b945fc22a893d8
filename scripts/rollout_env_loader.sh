#!/bin/bash
# env-loader of the <machine> tags in launch/rollout_workers_hosts.launch: roslaunch runs it on the worker's host
# (over ssh) with the node's command line; it sets up the workspace there and runs the node. The workspace's setup
# file: BIMANUAL_SKILLS_SETUP, else ~/bimanual_skills/install/setup.bash.
setup="${BIMANUAL_SKILLS_SETUP:-$HOME/bimanual_skills/install/setup.bash}"
if [ ! -f "$setup" ]; then
  echo "rollout_env_loader: no $setup on $(hostname) (build the workspace there or set BIMANUAL_SKILLS_SETUP)" >&2
  exit 1
fi
# shellcheck disable=SC1090
source "$setup"
exec "$@"
