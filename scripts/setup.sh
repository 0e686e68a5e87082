#!/usr/bin/env bash
# Creates .venv with ROS 2 Jazzy from PyPI and installs epuck_ros into it (editable).
# Idempotent: it reinstalls only when requirements.txt or setup.py changed. A first run takes minutes, most of them
# pip fetching and unpacking the ROS wheels: it says what it is doing, one line per phase and the time each took.
set -euo pipefail
# The real checkout, even when called through a symlinked scripts/ (test_readme runs commands in a scratch copy):
# an editable install from elsewhere would point the executables at that copy.
cd "$(dirname "$(readlink -f "$0")")/.."
. scripts/elapsed.sh
python=${PYTHON:-python3}
started=$SECONDS
phase() {  # phase NUMBER WHAT COMMAND...: says what it does, runs it, says how long it took
  local number=$1 what=$2 began=$SECONDS
  shift 2
  echo "[setup] $number $what ..." >&2
  "$@"
  echo "[setup] $number done in $(elapsed_since "$began")" >&2
}
if [ ! -x .venv/bin/python ]; then
  phase 1/4 "creating .venv with $($python --version 2>&1)" "$python" -m venv .venv
fi
stamp=.venv/.epuck_ros_installed
want=$(cat requirements.txt setup.py setup.cfg package.xml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  phase 2/4 "upgrading pip" .venv/bin/python -m pip install --quiet --upgrade pip
  phase 3/4 "installing ROS 2 Jazzy (rclpy, common_interfaces) and the other requirements (requirements.txt; the \
longest phase, minutes on a fresh machine)" .venv/bin/python -m pip install --quiet -r requirements.txt
  phase 4/4 "installing epuck_ros (editable)" .venv/bin/python -m pip install --quiet --no-deps -e .
  echo "$want" > "$stamp"
  echo "[setup] .venv ready in $(elapsed_since "$started")" >&2
fi
# tf2_msgs/TFMessage for /tf is not on PyPI: built from PyPI's ament and rosidl packages (a no-op once it imports).
scripts/gen_tf2_msgs.sh .venv || echo "[setup] tf2_msgs could not be built (see above): the simulator runs without /tf" >&2
