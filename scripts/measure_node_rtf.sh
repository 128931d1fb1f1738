#!/usr/bin/env bash
# Measured real-time factor of threshing_sim_node on a scene (default: the default scene), at
# real_time_factor 1 and 0, over the first 10 ms (the tooth-kernel contact) and over 1 s, in
# wall clock mode. Prints the node's own final summary line for each run.
# Usage: scripts/measure_node_rtf.sh [scene.yaml]   (after scripts/setup.sh)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SCENE=$(realpath "${1:-$ROOT/config/default_scene.yaml}")
export PATH="/usr/bin:$PATH" ROS_IP=127.0.0.1 ROS_MASTER_URI=http://127.0.0.1:11411
set +u
# shellcheck disable=SC1091
source "$ROOT/.build/ws/devel/setup.bash"
set -u
for rtf in 1 0; do
  for duration in 0.01 1.0; do
    line=$(roslaunch -p 11411 --no-summary threshing_sim simulator.launch scene:="$SCENE" \
             clock_mode:=wall real_time_factor:=$rtf duration:=$duration status_period:=0 2>&1 |
           grep "threshing_sim_node: simulated" || echo "(no summary)")
    echo "real_time_factor $rtf, duration $duration s: ${line#threshing_sim_node: }"
  done
done
