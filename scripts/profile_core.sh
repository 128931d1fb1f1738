#!/usr/bin/env bash
# Instruction counts (valgrind callgrind, Ir) of the stepping loop of `simulate` on the default
# scene and the kernel stream, both integrators. Ir are stable on a noisy shared machine where
# wall times are not. Prints one table row per case: the Ir of advanceTo (stepping only, scene
# loading excluded), steps, and Ir per step; with --keep DIR the callgrind files stay in DIR for
# callgrind_annotate. With --streams, the stream scene of the benchmark (config/bench/stream.yaml)
# with 1, 100 and 1000 kernels, live and idle (scripts/bench.py --stream-kernels N [--idle]),
# both integrators, in shortened runs, instead: the cost per kernel and per step.
# Usage: scripts/profile_core.sh [--simulate PATH] [--keep DIR] [--streams]
# (after scripts/setup.sh; needs valgrind: apt-get install -y valgrind)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SIMULATE="$ROOT/.build/ws/devel/lib/threshing_sim/simulate"
KEEP=""
STREAMS=0
while [ $# -gt 0 ]; do
  case "$1" in
    --simulate) SIMULATE=$2; shift 2 ;;
    --keep) KEEP=$2; shift 2 ;;
    --streams) STREAMS=1; shift ;;
    *) echo "usage: $0 [--simulate PATH] [--keep DIR] [--streams]" >&2; exit 2 ;;
  esac
done
OUT=${KEEP:-$(mktemp -d)}
mkdir -p "$OUT"
# name | scene | options (the stream runs are shortened; its first kernel is met at 1 ms)
CASES=(
  "default_event_driven|config/default_scene.yaml|--integrator event_driven --tolerance 1e-6"
  "default_time_stepping|config/default_scene.yaml|--integrator time_stepping --dt 1e-6"
  "stream_event_driven_1.5ms|config/scenes/stream.yaml|--integrator event_driven --duration 0.0015"
  "stream_time_stepping_4ms|config/scenes/stream.yaml|--integrator time_stepping --dt 1e-6 --duration 0.004"
)
if [ "$STREAMS" = 1 ]; then
  # name | scene | options: kernel files generated into $OUT; time stepping 200 steps of 1 us
  # (idle) or past the first strikes (live, 1.1 ms) and 500 steps of 10 us; event-driven 1 ms
  # (idle) or 0.2 ms (live: its small steps make longer runs take minutes under valgrind).
  CASES=()
  for n in 1 100 1000; do
    for kind in live idle; do
      f="$OUT/kernels_${n}_$kind.yaml"
      /usr/bin/python3 "$ROOT/scripts/bench.py" --stream-kernels "$n" \
        $([ "$kind" = idle ] && echo --idle) >"$f"
      ts_dur=$([ "$kind" = idle ] && echo 0.0002 || echo 0.0011)
      CASES+=("stream_${n}_${kind}_ts_1us|config/bench/stream.yaml|--set-file $f --integrator time_stepping --dt 1e-6 --duration $ts_dur")
      CASES+=("stream_${n}_${kind}_ts_10us|config/bench/stream.yaml|--set-file $f --integrator time_stepping --dt 1e-5 --duration 0.005")
      ed_dur=$([ "$kind" = idle ] && echo 0.001 || echo 0.0002)
      CASES+=("stream_${n}_${kind}_ed|config/bench/stream.yaml|--set-file $f --integrator event_driven --duration $ed_dur")
    done
  done
fi
echo "| case | stepping Ir (advanceTo) | steps | Ir per step |"
echo "|---|---|---|---|"
for c in "${CASES[@]}"; do
  IFS='|' read -r name scene opts <<<"$c"
  # shellcheck disable=SC2086
  valgrind --tool=callgrind --toggle-collect='threshing_sim::advancePast*' \
    --callgrind-out-file="$OUT/$name.cg" "$SIMULATE" "$ROOT/$scene" \
    $opts --quiet --summary "$OUT/$name.json" >"$OUT/$name.log" 2>&1
  ir=$(callgrind_annotate --inclusive=yes "$OUT/$name.cg" 2>/dev/null |
       awk '/PROGRAM TOTALS/ {gsub(",", "", $1); print $1}')
  steps=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['steps'])" \
          "$OUT/$name.json")
  echo "| $name | $ir | $steps | $((ir / steps)) |"
done
[ -n "$KEEP" ] || rm -rf "$OUT"
