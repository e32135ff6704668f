#!/bin/sh
# `make colcon-check`: build linkage_monitor the ROS 2 way — colcon, in a throw-away workspace
# with the package linked in, against the ROS 2 wheels in the venv ($VENV, default .venv) (no ROS distribution) —
# then, from that workspace's install tree only, import the built messages and run the node for
# a few seconds: a JointState and a pressure in, the outputs must come back (tools/colcon_smoke.py).
set -eu
REPO=$(cd "$(dirname "$0")/.." && pwd)
VENV=${VENV:-.venv}; case $VENV in /*) ;; *) VENV=$REPO/$VENV ;; esac
WS=$(mktemp -d "${TMPDIR:-/tmp}/linkage_monitor_colcon.XXXXXX")
trap 'rm -rf "$WS"' EXIT
mkdir "$WS/src"
ln -s "$REPO" "$WS/src/linkage_monitor"
export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH"
cd "$WS"
echo ">> colcon build in $WS"
colcon build --paths src/linkage_monitor --event-handlers console_direct- \
  --cmake-args -G Ninja -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" \
  || { cat "$WS"/log/latest_build/linkage_monitor/stdout_stderr.log; exit 1; }
# the install tree's environment (PYTHONPATH, AMENT_PREFIX_PATH, LD_LIBRARY_PATH); the
# repository's editable install is taken off the path so nothing can come from it
set +u; . "$WS/install/setup.sh"; set -u
echo ">> smoke test from $WS/install"
"$VENV/bin/python" -P "$REPO/tools/colcon_smoke.py" "$WS/install"
