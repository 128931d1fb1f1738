#!/usr/bin/env bash
# The main job: installs what is missing, builds (scripts/setup.sh), runs the default scene
# headless with `simulate` and prints its summary, then runs the live ROS demo: rviz where a
# display answers (until Ctrl-C), otherwise headless for 10 ms of simulated time in slow motion
# (real_time_factor 0.001, about 10 s) with a live one-line status and a final summary.
# Usage: scripts/demo.sh [scene.yaml]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SCENE=$(realpath "${1:-$ROOT/config/default_scene.yaml}")
bash "$ROOT/scripts/setup.sh"

# shellcheck source=scripts/ros_env.sh
source "$ROOT/scripts/ros_env.sh"

echo "== simulate $SCENE"
"$ROOT/.build/ws/devel/lib/threshing_sim/simulate" "$SCENE"

echo "== live demo (threshing_sim_node)"
if [ -n "${DISPLAY:-}" ]; then
  exec bash "$ROOT/scripts/run_demo.sh" scene:="$SCENE"
fi
exec bash "$ROOT/scripts/run_demo.sh" --headless --duration 0.01 scene:="$SCENE"
