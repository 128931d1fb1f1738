# Sourced by scripts/fuzz.sh and scripts/sanitize.sh: compiles the core, the scene loader
# (src/scene and src/scene/loader), simulate (main renamed simulate_main; its other parts are
# SAN_APP_OBJS) and the command-bag reader once with clang 14, ASan, UBSan and libFuzzer's coverage instrumentation, into
# .build/san/obj (two at a time, only what changed). Sets SAN_CXX, SAN_FLAGS, SAN_OBJ
# (directory), SAN_LIB_OBJS (core + scene) and SAN_APP_OBJS.
SAN_CXX=clang++-14
SAN_OBJ="$ROOT/.build/san/obj"
SAN_FLAGS=(-std=c++17 -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined
           -fno-sanitize-recover=undefined -fsanitize=fuzzer-no-link -I"$ROOT/include"
           -I"$ROOT/.build/ws/devel/include" -isystem /usr/include/eigen3)
# Debian's ROS headers outside /usr/include proper (rosbag needs pluginlib, class_loader, ...).
for d in ament_index_cpp class_loader pluginlib rcpputils rcutils xmlrpcpp; do
  [ -d "/usr/include/$d" ] && SAN_FLAGS+=(-isystem "/usr/include/$d")
done
mkdir -p "$SAN_OBJ"
for p in clang-14 libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || {
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq --no-install-recommends clang-14 libclang-rt-14-dev >/dev/null
    break
  }
done
[ -d "$ROOT/.build/ws/devel/include/threshing_sim" ] || bash "$ROOT/scripts/setup.sh"
san_stale() {  # object source [header]: true if the object must be rebuilt
  [ ! -f "$1" ] || [ -n "$(find "$2" ${3:+"$3"} -newer "$1")" ] ||
    [ -n "$(find "$ROOT/include" "$ROOT/src/core" "$ROOT/src/scene" -name '*.h' -newer "$1" |
      head -1)" ]
}
san_jobs=()
SAN_LIB_OBJS=()
# The physics (src/core) without libFuzzer's comparison tracing: its integer compares in inner
# loops (Eigen indices) took two thirds of fuzz_scene's time; edges still guide the fuzzer, and
# the loader, the command line and the bag reader keep the tracing. A change of flags rebuilds.
SAN_CORE_FLAGS="-fno-sanitize-coverage=trace-cmp"
if [ "$(cat "$SAN_OBJ/flags" 2>/dev/null)" != "${SAN_FLAGS[*]} | $SAN_CORE_FLAGS" ]; then
  rm -f "$SAN_OBJ"/*.o
  echo "${SAN_FLAGS[*]} | $SAN_CORE_FLAGS" > "$SAN_OBJ/flags"
fi
for src in "$ROOT"/src/core/*.cc "$ROOT"/src/core/*/*.cc "$ROOT"/src/scene/*.cc \
  "$ROOT"/src/scene/*/*.cc "$ROOT/src/ros/command_bag.cc"; do
  # A file of a folder of src/core (contact/, event_driven/, time_stepping/, async/) or of
  # src/scene (loader/) is named with its folder (event_driven/step.cc and
  # time_stepping/step.cc are two objects).
  rel="${src#"$ROOT"/src/}"
  case "$rel" in
    */*/*) obj="$SAN_OBJ/$(basename "$(dirname "$rel")")_$(basename "$src" .cc).o" ;;
    *) obj="$SAN_OBJ/$(basename "$src" .cc).o" ;;
  esac
  extra=""
  case "$src" in */src/core/*) extra="$SAN_CORE_FLAGS" ;; esac
  san_stale "$obj" "$src" && san_jobs+=("$src|$obj|$extra")
  case "$src" in */command_bag.cc) ;; *) SAN_LIB_OBJS+=("$obj") ;; esac
done
san_stale "$SAN_OBJ/simulate_main.o" "$ROOT/src/app/simulate.cc" "$ROOT/src/app/app.h" &&
  san_jobs+=("$ROOT/src/app/simulate.cc|$SAN_OBJ/simulate_main.o|-Dmain=simulate_main")
# simulate's other parts (options, run, check, batch): SAN_APP_OBJS, linked with simulate_main.o.
SAN_APP_OBJS=()
for src in "$ROOT"/src/app/*.cc; do
  [ "$src" = "$ROOT/src/app/simulate.cc" ] && continue
  obj="$SAN_OBJ/app_$(basename "$src" .cc).o"
  san_stale "$obj" "$src" "$ROOT/src/app/app.h" && san_jobs+=("$src|$obj|")
  SAN_APP_OBJS+=("$obj")
done
if [ ${#san_jobs[@]} -gt 0 ]; then
  echo "sanitizer build: compiling ${#san_jobs[@]} files"
  export SAN_CXX
  printf '%s\n' "${san_jobs[@]}" | SAN_FLAGS_STR="${SAN_FLAGS[*]}" xargs -P 2 -I{} bash -c '
    IFS="|" read -r src obj def <<< "{}"
    $SAN_CXX $SAN_FLAGS_STR $def -c "$src" -o "$obj" || exit 255'
fi
