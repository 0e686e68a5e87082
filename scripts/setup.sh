#!/usr/bin/env bash
# Creates .venv with ROS 2 Jazzy from PyPI and installs epuck_ros into it (editable).
# Idempotent: it reinstalls only when requirements.txt or setup.py changed.
set -euo pipefail
# The real checkout, even when called through a symlinked scripts/ (test_readme runs commands in a scratch copy):
# an editable install from elsewhere would point the executables at that copy.
cd "$(dirname "$(readlink -f "$0")")/.."
python=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv with $($python --version)" >&2
  "$python" -m venv .venv
fi
stamp=.venv/.epuck_ros_installed
want=$(cat requirements.txt setup.py setup.cfg package.xml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "[setup] installing ROS 2 Jazzy (rclpy, common_interfaces) and epuck_ros into .venv" >&2
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -r requirements.txt
  .venv/bin/python -m pip install --quiet --no-deps -e .
  echo "$want" > "$stamp"
fi
# tf2_msgs/TFMessage for /tf is not on PyPI: built from PyPI's ament and rosidl packages (a no-op once it imports).
scripts/gen_tf2_msgs.sh .venv || echo "[setup] tf2_msgs could not be built (see above): the simulator runs without /tf" >&2
