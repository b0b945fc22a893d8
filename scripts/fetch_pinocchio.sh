#!/usr/bin/env bash
# Fetches Pinocchio's C++ headers for control_bench's BM_PinocchioCrba: the libpinocchio wheel from PyPI (Pinocchio
# is not a Debian package; the wheel holds its headers and libraries), unpacked under build/peers/pinocchio. The next
# build (make build) compiles it into control_bench. Only the headers are used (and Debian's Boost and Eigen).
#
#   scripts/fetch_pinocchio.sh [VERSION]     # default 4.1.0
set -euo pipefail
case "${1:-}" in
  -h | --help)
    sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
esac
version="${1:-4.1.0}"
root="$(cd "$(dirname "$0")/.." && pwd)"
dest="$root/build/peers/pinocchio"
if [[ -f "$dest/cmeel.prefix/include/pinocchio/algorithm/crba.hpp" ]]; then
  echo "fetch_pinocchio: already in $dest"
  exit 0
fi
download="$(mktemp -d)"
trap 'rm -rf "$download"' EXIT
/usr/bin/python3 -m pip download --quiet --no-deps --dest "$download" "libpinocchio==$version"
mkdir -p "$dest"
/usr/bin/python3 -m zipfile -e "$download"/libpinocchio-*.whl "$dest"
echo "fetch_pinocchio: Pinocchio $version in $dest; rebuild (make build) for control_bench's BM_PinocchioCrba"
