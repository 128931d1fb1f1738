#!/usr/bin/env bash
# Soak and fault run of the node (issue 14), against its own master on a free port:
#   soak   the default scene at real-time factor 0 for REVS drum revolutions (0.075 s each),
#          a reset every revolution (the kernel struck afresh each time); reports the simulated
#          time reached, the resident memory at the start and the end, and the peak force
#          (/diagnostics; the single strike's is 63.5 N);
#   flood  drum_speed_cmd as fast as Python publishes (~10 kHz) for FLOOD_S seconds, NaN among
#          them (counted as rejected);
#   resets ~reset called in a loop (a reset storm) while the node runs;
#   nan    NaN through dynamic_reconfigure (refused, the server keeps the last good values).
# Usage: scripts/soak.sh [REVS] [FLOOD_S]   (default 100 revolutions, 3 s; the long soak:
# scripts/soak.sh 10000). Prints one line per part; exit 1 if the node died or time stuck.
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
python3 "$ROOT/scripts/soak_faults.py" "$FLOOD_S" >"$LOG/faults.log" 2>&1
FAULTS=$?
kill -0 "$NODE" 2>/dev/null || { echo "soak: the node died under the faults"; FAULTS=1; }
kill -INT "$NODE"; wait "$NODE"; FAULT_RC=$?
cat "$LOG/faults.log"
grep "threshing_sim_node: simulated" "$LOG/fault_node.log" | tail -1 | sed 's/^/faults: /'
echo "faults: node exit after SIGINT $FAULT_RC"
# Soak: factor 0, a reset every revolution, to the end time.
"$NODE_BIN" _scene:="$ROOT/config/default_scene.yaml" \
  _real_time_factor:=0.0 _clock_mode:=sim _reset_period:=0.075 _end_time:="$END" \
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
[ "$RC" -eq 0 ] && [ "$FAULTS" -eq 0 ] && [ "$FAULT_RC" -eq 0 ]
