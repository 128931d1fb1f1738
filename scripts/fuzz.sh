#!/usr/bin/env bash
# Builds the libFuzzer targets of test/fuzz/ with Debian's clang 14 (ASan + UBSan + libFuzzer)
# into .build/fuzz and runs each for a bounded time on its corpus (test/fuzz/corpus/<target>,
# seeded from config/), with the YAML dictionary test/fuzz/yaml.dict for the scene targets.
# A crash, sanitizer report, hang (-timeout) or out-of-memory fails the script.
#   scripts/fuzz.sh [SECONDS_PER_TARGET]      (default 40; scripts/test.sh runs 30 s x 3 targets)
#   FUZZ_RUNS=1000000 scripts/fuzz.sh         (a fixed number of inputs per target instead)
#   FUZZ_TARGETS="fuzz_command_bag" ...     (some of the targets only)
#   FUZZ_TIMEOUT=30 ...                        (hang limit per input, default 2 s; on a shared
#                                              machine, a long run reports inputs slower than 2 s
#                                              instead, to be re-run alone)
# Needs the catkin build (scripts/setup.sh) for the generated message headers.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SECONDS_PER_TARGET=${1:-40}
OUT="${FUZZ_OUT:-$ROOT/.build/fuzz}"  # FUZZ_OUT: another directory for a long run
mkdir -p "$OUT"

# shellcheck source=scripts/sanitizer_objects.sh
source "$ROOT/scripts/sanitizer_objects.sh"
link() {  # name fuzz-target-source objects... -- libs...
  local name=$1 src=$2; shift 2
  local objs=() libs=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do objs+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  libs=("$@")
  if [ ! -x "$OUT/$name" ] || [ -n "$(find "$src" "${objs[@]}" -newer "$OUT/$name" | head -1)" ]; then
    echo "fuzz: linking $name"
    "$SAN_CXX" "${SAN_FLAGS[@]}" -fsanitize=fuzzer "$src" "${objs[@]}" -o "$OUT/$name" "${libs[@]}"
  fi
}
link fuzz_scene "$ROOT/test/fuzz/fuzz_scene.cc" "${SAN_LIB_OBJS[@]}" -- -lyaml-cpp
link fuzz_simulate_cli "$ROOT/test/fuzz/fuzz_simulate_cli.cc" "$SAN_OBJ/simulate_main.o" \
  "${SAN_APP_OBJS[@]}" "${SAN_LIB_OBJS[@]}" -- -lyaml-cpp
link fuzz_command_bag "$ROOT/test/fuzz/fuzz_command_bag.cc" "$SAN_OBJ/command_bag.o" -- \
  -lrosbag -lrosbag_storage -lroscpp_serialization -lrostime -lcpp_common -lroscpp \
  -lconsole_bridge -lboost_system -lclass_loader -lboost_filesystem -ltinyxml2 -lroslib \
  -lament_index_cpp -lrcpputils -lrcutils  # pluginlib's templates (the target keeps a loader)

export FUZZ_ROOT="$ROOT"
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1
export LSAN_OPTIONS=suppressions="$ROOT/test/fuzz/lsan.supp"
status=0
for target in ${FUZZ_TARGETS:-fuzz_scene fuzz_simulate_cli fuzz_command_bag}; do
  corpus="$ROOT/test/fuzz/corpus/$target"
  work="$OUT/corpus_$target"
  mkdir -p "$work"
  dict=(-dict="$ROOT/test/fuzz/yaml.dict") max_len=4096
  [ "$target" = fuzz_command_bag ] && dict=() && max_len=16384
  limit=(-max_total_time="$SECONDS_PER_TARGET")
  [ -n "${FUZZ_RUNS:-}" ] && limit=(-runs="$FUZZ_RUNS")
  log="$OUT/$target.log"
  echo "fuzz: $target (${limit[*]})"
  # New inputs go to the scratch corpus; the committed corpus is read only.
  if (cd "$OUT" && "$OUT/$target" "$work" "$corpus" "${dict[@]}" "${limit[@]}" \
        -timeout="${FUZZ_TIMEOUT:-2}" -report_slow_units=2 \
        -rss_limit_mb=2048 -max_len="$max_len" -print_final_stats=1 -artifact_prefix="$OUT/$target-" \
        >"$log" 2>&1); then
    grep -E "^stat::number_of_executed_units|^Done" "$log" | tail -2 || true
  else
    echo "fuzz: $target FAILED (log: $log)"; tail -40 "$log"; status=1
  fi
done
exit $status
