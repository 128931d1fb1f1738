#!/usr/bin/env bash
# Launches the threshing demo: rviz where there is a display, headless otherwise (the node
# prints a live one-line status: simulation time, real-time factor, impacts, peak force).
#
# Usage: scripts/run_demo.sh [--duration SIM_SECONDS] [--headless] [demo.launch arg:=value ...]
#   --duration S  stop after S seconds of simulated time (the demo runs at real_time_factor
#                 0.001, so 0.005 takes about 5 s) and print the final summary; default: until
#                 Ctrl-C
#   --headless    no rviz even where there is a display
# Any other argument goes to launch/demo.launch (scene:=..., real_time_factor:=..., ...).
#
# If the package is not on ROS_PACKAGE_PATH yet, it is built first in .build/ws.
set -eo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
duration=0
headless=false
launch_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --duration) duration=$2; shift 2 ;;
    --headless) headless=true; shift ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) launch_args+=("$1"); shift ;;
  esac
done

# A fresh system may have no /etc/hosts (not even "localhost"): use the numeric loopback address
# unless the user chose an address.
if [ -z "${ROS_IP:-}" ] && [ -z "${ROS_HOSTNAME:-}" ]; then export ROS_IP=127.0.0.1; fi
export ROS_MASTER_URI="${ROS_MASTER_URI:-http://127.0.0.1:11311}"

# The package: from a sourced workspace, else built in .build/ws (incremental after the first).
if ! rospack find threshing_sim >/dev/null 2>&1; then
  ws="$root/.build/ws"
  mkdir -p "$ws/src"
  ln -sfn ../../.. "$ws/src/threshing_sim"
  echo "run_demo: building threshing_sim in $ws ..." >&2
  (cd "$ws" && PATH=/usr/bin:$PATH catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 \
     -DCMAKE_BUILD_TYPE=Release >"$ws/build.log" 2>&1) ||
    { echo "run_demo: build failed, see $ws/build.log" >&2; exit 1; }
  # shellcheck disable=SC1091
  source "$ws/devel/setup.bash"
fi

# rviz only where a display answers.
rviz=false
if ! $headless && [ -n "${DISPLAY:-}" ]; then
  if ! command -v xdpyinfo >/dev/null || xdpyinfo >/dev/null 2>&1; then rviz=true; fi
fi
if $rviz; then
  echo "run_demo: display $DISPLAY found, starting rviz" >&2
else
  echo "run_demo: no display, running headless (live status line below; Ctrl-C to stop)" >&2
fi

exec roslaunch --no-summary threshing_sim demo.launch rviz:=$rviz duration:="$duration" \
  "${launch_args[@]}"
