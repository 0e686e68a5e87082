#!/usr/bin/env bash
# Sets up the venv if needed, then runs `bringup` with the arguments given (see `scripts/run.sh --help`).
# Without arguments: `avoid` for 60 simulated seconds, recorded to bags/. `scripts/run.sh --view` runs avoid until
# Ctrl-C and prints the address of the live view to open in a browser.
# The ROS domain is yours: set ROS_DOMAIN_ID to keep runs apart (bringup prints the one it uses; default 0, so a
# `record` or `view` in another shell sees the run).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
if [ $# -eq 0 ]; then
  set -- avoid --duration 60 --record
fi
exec bringup "$@"
