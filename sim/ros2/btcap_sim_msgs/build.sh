#!/usr/bin/env bash
# Build the btcap_sim_msgs interface package with the rosidl generator wheels and install
# it into the prefix of the venv whose python is $1 (`make ros-sim` passes .venv-ros's),
# beside the ros-jazzy-* wheels, where rclpy finds it. Needs cmake and a C/C++ compiler.
set -euo pipefail
py=$1
prefix=$("$py" -c 'import sys; print(sys.prefix)')
src=$(cd "$(dirname "$0")" && pwd)
build=$(mktemp -d)
trap 'rm -rf "$build"' EXIT
export AMENT_PREFIX_PATH="$prefix" CMAKE_PREFIX_PATH="$prefix" PATH="$prefix/bin:$PATH"
run() { "$@" >>"$build/log" 2>&1 || { cat "$build/log" >&2; exit 1; }; }
run cmake -S "$src" -B "$build" -DCMAKE_INSTALL_PREFIX="$prefix" -DBUILD_TESTING=OFF \
    -DPython3_EXECUTABLE="$prefix/bin/python" -DCMAKE_BUILD_TYPE=Release
run cmake --build "$build" -j 2
run cmake --install "$build"
echo "btcap_sim_msgs installed into $prefix"
