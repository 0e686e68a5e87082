#!/usr/bin/env bash
# Sets up the venv if needed, then runs the test suite (extra arguments go to pytest) and prints the package's
# coverage (line and branch).
#   scripts/test.sh          every test but the slow tier (pytest marker `slow`: minutes of CPU each)
#   scripts/test.sh --slow   only the slow tier (.ci/run runs it after the rest)
#   scripts/test.sh --all    both at once
# The tests use your ROS_DOMAIN_ID if you set one (and no other test run holds it), else a free one; pytest's
# header says which.
set -euo pipefail
cd "$(dirname "$0")/.."
tier=(-m 'not slow')
case "${1:-}" in
  --slow) tier=(-m slow); shift ;;
  --all) tier=(); shift ;;
esac
scripts/setup.sh
. scripts/env.sh
# Three test processes (pytest-xdist), each on a ROS domain of its own (docs/tests.md: how long it takes; most tests
# wait on other processes and DDS part of the time, so three keep two cores busier than two do; four were a minute
# faster, but their load made discovery races between other processes (a recorder and a controller) show).
# --dist loadfile keeps each test file in one process: the README's commands build on each other (test_readme.py);
# the files are handed out longest first (test/conftest.py), not reordered by xdist.
exec python -m pytest -n 3 --dist loadfile --no-loadscope-reorder "${tier[@]}" \
  --cov=epuck_ros --cov-branch --cov-report=term:skip-covered "$@"
