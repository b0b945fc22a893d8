#!/usr/bin/env bash
# Makes the virtual environment of bimanual_skills' Python side (Ray, Gymnasium: python/requirements.txt, pinned),
# on Debian's /usr/bin/python3 with its site packages visible (rospy, numpy, pytest, and the bindings once
# install/setup.bash is sourced). Idempotent: nothing is installed when the pinned versions are there.
#   scripts/make_venv.sh DIR
set -euo pipefail
cd "$(dirname "$0")/.."
venv=${1:?usage: make_venv.sh DIR}
requirements=python/requirements.txt
if [ -x "$venv/bin/python" ] && "$venv/bin/python" - "$requirements" <<'PY'
import sys
from importlib.metadata import version, PackageNotFoundError
ok = True
for line in open(sys.argv[1]):
    line = line.split("#")[0].strip()
    if not line:
        continue
    name, _, pinned = line.partition("==")
    try:
        ok = ok and version(name) == pinned
    except PackageNotFoundError:
        ok = False
sys.exit(0 if ok else 1)
PY
then
  echo "make_venv: $venv has python/requirements.txt's versions"
  exit 0
fi
echo "make_venv: making $venv with python/requirements.txt (Ray, Gymnasium; from PyPI)"
/usr/bin/python3 -m venv --system-site-packages "$venv"
"$venv/bin/pip" install --disable-pip-version-check -q -r "$requirements"
echo "make_venv: $venv ready"
