#!/usr/bin/env bash
# Builds the tf2_msgs interface package (tf2_msgs/msg/TFMessage) into .venv when it does not import there:
# tf2_msgs is not on PyPI, but the ament and rosidl packages that generate it are, and the venv is a ROS install
# prefix (lib/, share/, site-packages). Needs CMake and a C/C++ compiler (installed with apt-get when run as root).
# Without them it says so and exits 0: the simulator then runs without /tf and /tf_static.
# Usage: scripts/gen_tf2_msgs.sh [VENV]   (default .venv; idempotent)
set -euo pipefail
cd "$(dirname "$(readlink -f "$0")")/.."
. scripts/elapsed.sh
venv=$(readlink -f "${1:-.venv}")
python=$venv/bin/python
if [ ! -x "$python" ]; then
  echo "[tf2_msgs] no Python at $python: run scripts/setup.sh first" >&2
  exit 2
fi
if "$python" -c 'import tf2_msgs.msg' 2>/dev/null; then
  exit 0
fi
missing=()
command -v cmake >/dev/null || missing+=(cmake)
command -v c++ >/dev/null || missing+=(g++)
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "[tf2_msgs] installing ${missing[*]} with apt-get" >&2
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    echo "[tf2_msgs] not built: needs ${missing[*]} (apt-get install ${missing[*]}); the simulator runs without /tf" >&2
    exit 0
  fi
fi
echo "[tf2_msgs] building tf2_msgs/msg/TFMessage into $venv (pip, then CMake) ..." >&2
began=$SECONDS
"$python" -m pip install --quiet -r scripts/tf2_msgs/build-requirements.txt
build=$(mktemp -d)
trap 'rm -rf "$build"' EXIT
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
export PATH=$venv/bin:$PATH AMENT_PREFIX_PATH=$venv CMAKE_PREFIX_PATH=$venv
cmake -S scripts/tf2_msgs -B "$build" "${generator[@]}" -DCMAKE_INSTALL_PREFIX="$venv" -DBUILD_TESTING=OFF \
  -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE="$python" >"$build/configure.log" 2>&1 \
  || { tail -30 "$build/configure.log" >&2; exit 1; }
cmake --build "$build" --parallel 2 >"$build/build.log" 2>&1 || { tail -30 "$build/build.log" >&2; exit 1; }
cmake --install "$build" >/dev/null
"$python" -c 'from tf2_msgs.msg import TFMessage; TFMessage()'
echo "[tf2_msgs] built in $(elapsed_since "$began"): the simulator publishes /tf and /tf_static" >&2
