#!/usr/bin/env bash
# Remakes bags/<behaviour>/: one short zstd-compressed lockstep recording per course behaviour (default world, seed 1;
# noise off for the geometric shapes so their figures are exact, on for avoid), and bags/swarm: five robots running
# avoid. Each stays under 2 MB.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-44}
record() {  # record FOLDER BEHAVIOUR DURATION [BRINGUP OPTION ...]
  local folder=$1 behaviour=$2 duration=$3; shift 3
  rm -rf "bags/$folder"
  bringup "$behaviour" --duration "$duration" --real-time-factor 0 --lockstep --seed 1 \
    --record "bags/$folder" --record-compression zstd "$@"
  du -sh "bags/$folder"
}
record forward forward 8 --no-noise -p goal_distance:=0.3
record spin spin 4 --no-noise
record circle circle 9 --no-noise
record rectangle rectangle 30 --no-noise
record avoid avoid 30
record swarm avoid 20 --robots 5
