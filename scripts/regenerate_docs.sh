#!/usr/bin/env bash
# Regenerates every measured figure and table of README.md and docs/ from a Release build. Each
# section's page is in scripts/tslib/markdown.py (SECTIONS):
#   scene-reference  scripts/scene_reference.sh               (docs/scene_reference.md)
#   default-timing   scripts/time_default_scene.py            (README, "Headline figures")
#   default-output   simulate config/default_scene.yaml        (README, "Headline figures")
#   node-rtf         scripts/measure_node_rtf.sh               (docs/ros_interface.md)
#   profile          scripts/profile_core.sh [--streams]       (docs/performance.md)
#   free-teeth       scripts/compare_free_teeth.py --callgrind  (docs/performance.md)
#   modal-split      scripts/compare_modal_split.py --callgrind (docs/performance.md)
#   stability        scripts/stability_table.py                (docs/numerical_stability.md +
#                                                               docs/stability.md)
#   stability-full   the same, scene 10 for 10 000 revolutions (docs/numerical_stability.md +
#                    docs/stability_full.md; not a default part: about 50 minutes, both
#                    integrators side by side)
#   findings         scripts/compare_teeth.py --findings       (docs/threshing_findings.md +
#                                                               docs/findings*)
#   bench            scripts/bench.py                          (docs/benchmarks.md + docs/bench*)
#   islands          scripts/bench.py --part islands           (docs/architecture.md +
#                                                               docs/bench_islands.md)
#   stage-profile    scripts/stage_profile.py --docs           (docs/bench_islands.md,
#                    "Instructions per stage" alone; the islands part includes it; about 8
#                    minutes under valgrind)
#   sweeps           scripts/sweep_overhead.py --workers 2 1 --cluster --docs (README +
#                    docs/sweeps*; not a default part: its ratio needs an otherwise idle machine)
# Usage: scripts/regenerate_docs.sh [PART ...]   (default: all parts, in the order above; about
# 15 minutes on 2 cores). Timings are medians on a possibly shared machine: compare them as
# ratios within one run.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
PY=/usr/bin/python3
BIN="$ROOT/.build/ws/devel/lib/threshing_sim"
parts=("$@")
[ ${#parts[@]} -gt 0 ] ||
  parts=(scene-reference default-timing default-output node-rtf profile free-teeth modal-split stability
    findings bench)

bash scripts/setup.sh
# The instruction counts need valgrind (not part of the build's set-up).
if printf '%s\n' "${parts[@]}" | grep -qx 'profile\|free-teeth\|modal-split\|stage-profile\|islands' &&
  ! command -v valgrind >/dev/null; then
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends valgrind >/dev/null
fi
for part in "${parts[@]}"; do
  echo "regenerate_docs: $part ($(date -u +%H:%M:%S))"
  case "$part" in
    scene-reference) bash scripts/scene_reference.sh ;;
    default-timing) $PY scripts/time_default_scene.py | $PY scripts/readme_section.py "$part" ;;
    default-output) "$BIN/simulate" config/default_scene.yaml |
                      $PY scripts/readme_section.py "$part" --fence "" ;;
    node-rtf) bash scripts/measure_node_rtf.sh | $PY scripts/readme_section.py "$part" --fence "" ;;
    profile)
      bash scripts/profile_core.sh | $PY scripts/readme_section.py profile
      bash scripts/profile_core.sh --streams | $PY scripts/readme_section.py profile-streams ;;
    free-teeth) $PY scripts/compare_free_teeth.py --callgrind |
                  $PY scripts/readme_section.py "$part" --fence "" ;;
    modal-split) $PY scripts/compare_modal_split.py --callgrind |
                   $PY scripts/readme_section.py "$part" --fence "" ;;
    stability) $PY scripts/stability_table.py --simulate "$BIN/simulate" \
                 --output docs/stability.md --summary docs/numerical_stability.md ;;
    stability-full)
      # One run per integrator, side by side (one core each), then one table from both.
      tmp=$(mktemp -d)
      pids=()
      for integrator in event_driven time_stepping; do
        $PY scripts/stability_table.py --simulate "$BIN/simulate" --scenes 10 --full \
          --integrators "$integrator" --save "$tmp/$integrator.json" --output /dev/null &
        pids+=($!)
      done
      for pid in "${pids[@]}"; do wait "$pid" || true; done  # a failed property is in the table
      $PY scripts/stability_table.py --render "$tmp/event_driven.json" "$tmp/time_stepping.json" \
        --output docs/stability_full.md --summary docs/numerical_stability.md --marker stability-full
      rm -rf "$tmp" ;;
    findings) $PY scripts/compare_teeth.py --findings ;;
    bench) $PY scripts/bench.py ;;
    islands) $PY scripts/bench.py --part islands ;;
    stage-profile) $PY scripts/stage_profile.py --docs ;;
    sweeps) $PY scripts/sweep_overhead.py --workers 2 1 --cluster --docs ;;
    *) echo "regenerate_docs: unknown part '$part'" >&2; exit 2 ;;
  esac
done
echo "regenerate_docs: done ($(date -u +%H:%M:%S))"
