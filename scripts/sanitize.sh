#!/usr/bin/env bash
# Builds the core's and the scene loader's unit tests with ASan + UBSan (Debian's clang 14, a
# separate build directory .build/asan, objects reused between runs) and runs them; any
# sanitizer report fails. Time-bound: each test binary gets at most 300 s.
#   scripts/sanitize.sh [TEST ...]   (default: the tests below)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
OUT="$ROOT/.build/asan"
mkdir -p "$OUT"
tests=("$@")
[ ${#tests[@]} -gt 0 ] || tests=(core/test_geometry core/test_lcp core/test_work_budget
                                  core/test_simulator scene/test_scene_loader)
# shellcheck source=scripts/sanitizer_objects.sh
source "$ROOT/scripts/sanitizer_objects.sh"
objs=("${SAN_LIB_OBJS[@]}")
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export ASAN_OPTIONS=detect_leaks=1
status=0
for t in "${tests[@]}"; do
  bin="$OUT/$(basename "$t")"
  src="$ROOT/test/$t.cc"
  if [ ! -x "$bin" ] || [ -n "$(find "$src" "${objs[@]}" -newer "$bin" | head -1)" ]; then
    # The core's unit tests run the global scheme, as CMakeLists.txt builds them.
    "$SAN_CXX" "${SAN_FLAGS[@]}" -DTHRESHING_SIM_SOURCE_DIR="\"$ROOT\"" \
      -DTHRESHING_SIM_GLOBAL_SCHEME "$src" "${objs[@]}" \
      -o "$bin" -lyaml-cpp -lgtest -lgtest_main -pthread
  fi
  if (cd "$ROOT" && timeout 300 "$bin" --gtest_brief=1 >"$bin.log" 2>&1); then
    echo "sanitize: $(basename "$t") passed"
  else
    echo "sanitize: $(basename "$t") FAILED (log: $bin.log)"; tail -30 "$bin.log"; status=1
  fi
done
exit $status
