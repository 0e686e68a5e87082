#!/usr/bin/env bash
# Runs every benchmark; each prints its measured figures and ratios against a baseline measured in the same run.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-43}
echo "[bench] ROS_DOMAIN_ID=$ROS_DOMAIN_ID" >&2
for bench in benchmarks/bench_*.py; do
  echo "== $bench"
  python "$bench"
done
