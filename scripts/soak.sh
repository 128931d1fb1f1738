#!/usr/bin/env bash
# Soak and fault run of the node (issue 14), against its own master on a free port:
#   flood  drum_speed_cmd at 10 kHz for FLOOD_S seconds from a C++ publisher (drum_cmd_flood),
#          half of them NaN, inf or 1e4 rad/s; the node's count of rejected commands must
#          equal the invalid ones sent (none lost);
#   resets ~reset called in a loop (a reset storm) while the node runs;
#   nan    NaN through dynamic_reconfigure (refused, the server keeps the last good values);
#   soak   the default scene at real-time factor 0 for REVS drum revolutions, the kernel
#          re-seeded at the same drum phase every revolution (~loop_revolutions 1), so that
#          every strike is the single strike; reports the simulated time reached, the resident
#          memory 2 s in and at most, and the peak force (the single strike's is 63.5 N).
# Usage: scripts/soak.sh [REVS] [FLOOD_S]   (default 100 revolutions, 3 s; the long soak:
# scripts/soak.sh 10000). Prints one line per part; exit 1 if the node died, time stuck, a
# command was lost or the peak force differs from the single strike's by more than 1 %.
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
REVS=${1:-100}
FLOOD_S=${2:-3}
WS="$ROOT/.build/ws"
export PATH="/usr/bin:$PATH"
set +u; source "$WS/devel/setup.bash"; set -u
PORT=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI="http://127.0.0.1:$PORT" ROS_IP=127.0.0.1
LOG=$(mktemp -d /tmp/soak.XXXX)
roscore -p "$PORT" >"$LOG/roscore.log" 2>&1 &
CORE=$!
trap 'kill $NODE $CORE 2>/dev/null; wait 2>/dev/null' EXIT
NODE=0
for _ in $(seq 50); do rosparam list >/dev/null 2>&1 && break; sleep 0.2; done
END=$(python3 -c "print($REVS * 0.075)")
NODE_BIN="$WS/devel/lib/threshing_sim/threshing_sim_node"
# Faults, against a node that runs until stopped (real time, wall clock).
"$NODE_BIN" _scene:="$ROOT/config/default_scene.yaml" _status_period:=0 >"$LOG/fault_node.log" 2>&1 &
NODE=$!
sleep 2
"$WS/devel/lib/threshing_sim/drum_cmd_flood" 10000 "$FLOOD_S" >"$LOG/flood.log" 2>&1
FAULTS=$?
sleep 1.5  # the node's counters catch up
python3 "$ROOT/scripts/soak_faults.py" >"$LOG/faults.log" 2>&1 || FAULTS=1
kill -0 "$NODE" 2>/dev/null || { echo "soak: the node died under the faults"; FAULTS=1; }
kill -INT "$NODE"; wait "$NODE"; FAULT_RC=$?
cat "$LOG/flood.log" "$LOG/faults.log"
FAULT_SUMMARY=$(grep "threshing_sim_node: simulated" "$LOG/fault_node.log" | tail -1)
echo "faults: $FAULT_SUMMARY"
echo "faults: node exit after SIGINT $FAULT_RC"
INVALID=$(sed -n 's/.*, \([0-9]*\) invalid.*/\1/p' "$LOG/flood.log")
REJECTED=$(echo "$FAULT_SUMMARY" | sed -n 's/.*, \([0-9]*\) rejected commands.*/\1/p')
if [ -z "$INVALID" ] || [ "$INVALID" != "$REJECTED" ]; then
  echo "faults: the node counted ${REJECTED:-?} rejected commands of ${INVALID:-?} invalid sent"
  FAULTS=1
else
  echo "faults: the node counted all $REJECTED invalid commands as rejected (none lost)"
fi
# Soak: factor 0, the kernel re-seeded every revolution at the same drum phase, to the end time.
"$NODE_BIN" _scene:="$ROOT/config/default_scene.yaml" \
  _real_time_factor:=0.0 _clock_mode:=sim _loop_revolutions:=1 _end_time:="$END" \
  _status_period:=0 >"$LOG/node.log" 2>&1 &
NODE=$!
sleep 2
rss() { awk '/VmRSS/ {print $2}' "/proc/$NODE/status" 2>/dev/null || echo 0; }
RSS0=$(rss)
RSS_MAX=$RSS0
while kill -0 "$NODE" 2>/dev/null; do
  r=$(rss); [ "${r:-0}" -gt "$RSS_MAX" ] && RSS_MAX=$r
  sleep 1
done
wait "$NODE"; RC=$?
SUMMARY=$(grep "threshing_sim_node: simulated" "$LOG/node.log" | tail -1)
echo "soak: $REVS revolutions (end time $END s): node exit $RC; rss 2 s in ${RSS0} kB, max ${RSS_MAX} kB"
echo "soak: $SUMMARY"
echo "soak: logs in $LOG"
SIM=$(echo "$SUMMARY" | sed -n 's/.*simulated \([0-9.]*\) s.*/\1/p')
python3 -c "import sys; sys.exit(0 if float('${SIM:-0}') >= $END - 1e-6 else 1)" || { echo "soak: time stuck"; exit 1; }
# The peak force against the single strike's (simulate on the same scene).
"$WS/devel/lib/threshing_sim/simulate" "$ROOT/config/default_scene.yaml" --quiet \
  --summary "$LOG/single.json" >/dev/null 2>&1
PEAK=$(echo "$SUMMARY" | sed -n 's/.*peak normal force \([0-9.]*\) N.*/\1/p')
python3 - "$LOG/single.json" "${PEAK:-0}" <<'PY' || FAULTS=1
import json, sys
single = json.load(open(sys.argv[1]))["peak_normal_force_N"]
peak = float(sys.argv[2])
print(f"soak: peak normal force {peak} N, single strike {single:.4f} N ({peak / single - 1:+.2%})")
sys.exit(0 if abs(peak / single - 1) <= 0.01 else 1)
PY
[ "$RC" -eq 0 ] && [ "$FAULTS" -eq 0 ] && [ "$FAULT_RC" -eq 0 ]
