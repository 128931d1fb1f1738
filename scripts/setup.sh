#!/usr/bin/env bash
# Installs what is missing from Debian's own packages and builds the package (Release) in a
# git-ignored catkin workspace, .build/ws, whose src/ links to this repository.
# Idempotent: a second run only rebuilds what changed. Works as root on a bare Debian 12.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

PACKAGES=(
  g++ make cmake catkin catkin-lint ros-core-dev ros-message-generation libroscpp-dev
  libeigen3-dev libyaml-cpp-dev libtf2-ros-dev libtf2-eigen-dev libgeometry-msgs-dev
  libvisualization-msgs-dev libstd-srvs-dev librosbag-dev python3-rosbag librostest-dev
  python3-rostest googletest libgtest-dev libbenchmark-dev
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libdiagnostic-updater-dev python3-diagnostic-msgs rviz libgl1-mesa-dri
  xvfb xauth imagemagick python3-numpy python3-matplotlib python3-yaml
  python3-std-srvs python3-geometry-msgs python3-visualization-msgs python3-tf2-msgs
  python3-distributed
  python3-rospy python3-rostopic python3-rosgraph python3-roslib python3-std-msgs
  python3-rosgraph-msgs
)

# Install only when something is missing (dpkg-query is fast; apt needs root and network).
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# roslaunch names its local machine "localhost", which must resolve; a minimal system
# (debootstrap minbase, some containers) has no /etc/hosts at all.
if ! getent hosts localhost >/dev/null 2>&1; then
  echo "setup: adding the loopback entries to /etc/hosts (roslaunch needs 'localhost')"
  printf '127.0.0.1\tlocalhost\n::1\tlocalhost ip6-localhost ip6-loopback\n' >> /etc/hosts
fi

# Build in .build/ws with Debian's python (a pyenv shim on PATH lacks catkin_pkg).
WS="$ROOT/.build/ws"
mkdir -p "$WS/src"
ln -sfn "$ROOT" "$WS/src/threshing_sim"
cd "$WS"
export PATH="/usr/bin:$PATH"
JOBS=$(nproc 2>/dev/null || echo 2)
catkin_make -DCMAKE_BUILD_TYPE=Release -DPYTHON_EXECUTABLE=/usr/bin/python3 -j"$JOBS" \
  > "$WS/build.log" 2>&1 || { tail -60 "$WS/build.log"; echo "setup: build failed (log: $WS/build.log)"; exit 1; }
echo "setup: built in $WS (log: $WS/build.log)"
