#!/usr/bin/env bash
# Remakes bags/<behaviour>/: one short zstd-compressed lockstep recording per course behaviour (default world, seed 1;
# noise off for the geometric shapes so their figures are exact, on for avoid). Each stays well under 1 MB.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-44}
record() {
  local behaviour=$1 duration=$2; shift 2
  rm -rf "bags/$behaviour"
  bringup "$behaviour" --duration "$duration" --real-time-factor 0 --lockstep --seed 1 \
    --record "bags/$behaviour" --record-compression zstd "$@"
  du -sh "bags/$behaviour"
}
record forward 8 --no-noise -p goal_distance:=0.3
record spin 4 --no-noise
record circle 9 --no-noise
record rectangle 30 --no-noise
record avoid 30
