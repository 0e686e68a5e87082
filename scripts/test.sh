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
# Four test processes (pytest-xdist), each on a ROS domain of its own (docs/tests.md: how long it takes; most tests
# wait on other processes and DDS part of the time, so four keep two cores busier than three do: 6 min 29 s against
# about 8 min quiet. Four were tried before and made a race of the product show, a recorder a controller had not
# matched yet at the resume; bringup now waits until the recorder has heard from the controllers).
# --dist loadfile keeps each test file in one process: the README's commands build on each other (test_readme.py);
# the files are handed out longest first (test/conftest.py), not reordered by xdist.
exec python -m pytest -n 4 --dist loadfile --no-loadscope-reorder "${tier[@]}" \
  --cov=epuck_ros --cov-branch --cov-report=term:skip-covered "$@"
