#!/usr/bin/env bash
# Sets up the venv if needed, then runs the simulator with a behaviour (default: avoid, one simulated minute,
# recorded to bags/). Any arguments are passed to `bringup`; see `scripts/run.sh --help`.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-42}
if [ $# -eq 0 ]; then
  set -- avoid --duration 60 --record
fi
exec bringup "$@"
