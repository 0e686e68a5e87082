#!/usr/bin/env bash
# Sets up the venv if needed, then runs the whole test suite (extra arguments go to pytest).
# The tests use your ROS_DOMAIN_ID if you set one (and no other test run holds it), else a free one; pytest's
# header says which.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
# Two test processes (pytest-xdist), each on a ROS domain of its own (README, Tests: how long it takes).
# --dist loadfile keeps each test file in one process: the README's commands build on each other (test_readme.py).
exec python -m pytest -n 2 --dist loadfile "$@"
