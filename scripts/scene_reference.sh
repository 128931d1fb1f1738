#!/usr/bin/env bash
# Regenerates the key table of docs/scene_reference.md (between its scene-reference markers)
# from the scene loader's schema (simulate --print-schema): every key with its type, unit,
# default, range or words, and meaning. test_hostile_inputs checks that the committed table is
# current.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SIM="$ROOT/.build/ws/devel/lib/threshing_sim/simulate"
[ -x "$SIM" ] || bash "$ROOT/scripts/setup.sh"
"$SIM" --print-schema | PYTHONPATH="$ROOT/scripts" /usr/bin/python3 -c '
import sys
from tslib import markdown
print("wrote", markdown.splice("scene-reference", sys.stdin.read()))'
