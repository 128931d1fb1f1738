#!/usr/bin/env bash
# Instruction counts (valgrind callgrind, Ir) of the event-driven stepping loop on the default
# single strike (config/default_scene.yaml) at tolerances 1e-6 and 1e-7: the whole 10 ms run,
# and the tooth-kernel contact alone (the difference between runs that end just before the
# first touch, at 288 us, and just after the contact ends, at 323 us). Prints the Ir of
# advanceTo, the accepted steps and Ir per step, then the ten functions with the most
# exclusive Ir in the whole run at 1e-6. docs/contact_cost.md holds its output.
# Usage: scripts/contact_cost.sh [--simulate PATH] [--keep DIR]
# (after scripts/setup.sh; needs valgrind). For the figures before a change, build that
# commit in a worktree and pass its simulate with --simulate.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SIMULATE="$ROOT/.build/ws/devel/lib/threshing_sim/simulate"
KEEP=""
while [ $# -gt 0 ]; do
  case "$1" in
    --simulate) SIMULATE=$2; shift 2 ;;
    --keep) KEEP=$2; shift 2 ;;
    *) echo "usage: $0 [--simulate PATH] [--keep DIR]" >&2; exit 2 ;;
  esac
done
OUT=${KEEP:-$(mktemp -d)}
mkdir -p "$OUT"
# run NAME TOLERANCE DURATION: prints "Ir steps"
run() {
  valgrind --tool=callgrind --toggle-collect='threshing_sim::advancePast*' \
    --callgrind-out-file="$OUT/$1.cg" "$SIMULATE" "$ROOT/config/default_scene.yaml" \
    --integrator event_driven --tolerance "$2" --duration "$3" --quiet \
    --summary "$OUT/$1.json" >"$OUT/$1.log" 2>&1
  local ir steps
  ir=$(callgrind_annotate --inclusive=yes "$OUT/$1.cg" 2>/dev/null |
       awk '/PROGRAM TOTALS/ {gsub(",", "", $1); print $1}')
  steps=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['steps'])" \
          "$OUT/$1.json")
  echo "$ir $steps"
}
echo "| tolerance | part | stepping Ir (advanceTo) | accepted steps | Ir per step |"
echo "|---|---|---|---|---|"
for tol in 1e-6 1e-7; do
  read -r ir steps < <(run "run_$tol" "$tol" 0.01)
  echo "| $tol | whole run (10 ms) | $ir | $steps | $((ir / steps)) |"
  read -r ir0 steps0 < <(run "pre_$tol" "$tol" 0.000288)
  read -r ir1 steps1 < <(run "contact_$tol" "$tol" 0.000323)
  echo "| $tol | contact (288-323 us) | $((ir1 - ir0)) | $((steps1 - steps0)) | $(((ir1 - ir0) / (steps1 - steps0))) |"
done
echo
echo "Top 10 functions by exclusive Ir, whole run at 1e-6:"
echo
echo "| exclusive Ir | share | function |"
echo "|---|---|---|"
callgrind_annotate "$OUT/run_1e-6.cg" 2>/dev/null | /usr/bin/python3 -c '
import re, sys
lines = sys.stdin.read().split("\n")
start = next(i for i, l in enumerate(lines) if "file:function" in l) + 2
rows = 0
for l in lines[start:]:
    m = re.match(r"\s*([\d,]+)\s+\(\s*([\d.]+)%\)\s+(\S+?):(.*)$", l)
    if not m or rows == 10:
        break
    name = re.sub(r" \[[^]]*\]$", "", m.group(4))
    name = name.replace("threshing_sim::", "").replace("internal::", "")
    name = name.replace("(anonymous namespace)::", "")
    depth, out = 0, ""
    for ch in name:  # drop the argument lists
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        elif depth == 0:
            out += ch
    print("| %s | %s %% | `%s` |" % (m.group(1), m.group(2), out.strip()))
    rows += 1
'
[ -n "$KEEP" ] || rm -rf "$OUT"
