#!/usr/bin/env bash
# Sets up the venv if needed, then runs the whole test suite (extra arguments go to pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
. scripts/env.sh
exec python -m pytest "$@"
