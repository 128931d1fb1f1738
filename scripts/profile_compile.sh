#!/usr/bin/env bash
# Prints the compile cost table of docs/performance.md ("Compile cost"): valgrind callgrind
# instruction counts (inclusive) of compileModel, of loadScene (YAML parsing + compileModel +
# the scene's own reading) and of yaml-cpp's YAML::Load alone, for each scene given (default:
# the default scene, config/bench/*.yaml and config/scenes/stream.yaml), each run for 1 ns so
# that the stepping does not count.
# Usage: scripts/profile_compile.sh [--simulate PATH] [SCENE.yaml ...]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SIM="$ROOT/.build/ws/devel/lib/threshing_sim/simulate"
if [ "${1:-}" = "--simulate" ]; then SIM=$2; shift 2; fi
[ -x "$SIM" ] || bash "$ROOT/scripts/setup.sh"
cd "$ROOT"
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] ||
  scenes=(config/default_scene.yaml config/bench/*.yaml config/scenes/stream.yaml)
out=$(mktemp)
trap 'rm -f "$out"' EXIT
echo "| scene | compileModel Ir | loadScene Ir | YAML::Load Ir |"
echo "|---|---|---|---|"
for scene in "${scenes[@]}"; do
  valgrind --tool=callgrind --callgrind-out-file="$out" "$SIM" "$scene" --duration 1e-9 \
    >/dev/null 2>&1
  ann=$(callgrind_annotate --inclusive=yes --threshold=100 "$out" 2>/dev/null)
  count() { echo "$ann" | grep -E "$1" | head -1 | awk '{gsub(",", "", $1); print $1}'; }
  echo "| $scene | $(count 'threshing_sim::compileModel\(') |" \
    "$(count 'threshing_sim::loadScene(WithFiles)?\(') | $(count 'YAML::Load\(std::istream') |"
done
