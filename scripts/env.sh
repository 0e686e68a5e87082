# Sourced by the other scripts: keeps DDS discovery on this machine and uses the project's venv.
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export PATH="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/.venv/bin:$PATH"
