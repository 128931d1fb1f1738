"""Finding the package's binaries (simulate, bench_work_precision, threshing_sim_node)."""
import os
import pathlib
import shutil
import subprocess

from tslib import ROOT

BIN_DIR = ROOT / ".build/ws/devel/lib/threshing_sim"  # where scripts/setup.sh builds them


def sourced_workspace_candidates(name, environ=None):
    """Where a sourced catkin workspace puts the package's binary: <prefix>/lib/threshing_sim/
    <name> for every prefix of $CMAKE_PREFIX_PATH (devel or install space), in order."""
    environ = os.environ if environ is None else environ
    prefixes = [p for p in environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep) if p]
    return [pathlib.Path(p) / "lib/threshing_sim" / name for p in prefixes]


def _executable(path):
    return path is not None and os.path.isfile(path) and os.access(path, os.X_OK)


def find_binary(name="simulate", given=None, search=False):
    """The path of a built binary of the package.

    given: a path the user named (--simulate); it must be executable, else SystemExit naming it.
    Otherwise $THRESHING_SIM_<NAME>, then the workspace of scripts/setup.sh, then the sourced
    catkin workspaces ($CMAKE_PREFIX_PATH: <prefix>/lib/threshing_sim/<name>, where catkin puts
    it); with search, also PATH and catkin_find. SystemExit saying how to build when none is
    found."""
    if given:
        if not _executable(given):
            raise SystemExit(f"{name} not found at {given}; build it (scripts/setup.sh) or "
                             f"pass the path of a built {name}")
        return pathlib.Path(given)
    candidates = [os.environ.get("THRESHING_SIM_" + name.upper()), BIN_DIR / name]
    candidates += sourced_workspace_candidates(name)
    if search:
        candidates.append(shutil.which(name))
        if shutil.which("catkin_find"):
            try:
                candidates.append(subprocess.run(
                    ["catkin_find", "--first-only", "threshing_sim", name], capture_output=True,
                    text=True, check=False, timeout=60).stdout.strip() or None)
            except (OSError, subprocess.TimeoutExpired):
                pass
    for path in candidates:
        if _executable(path):
            return pathlib.Path(path)
    raise SystemExit(f"{name} not found at {BIN_DIR / name} nor in a sourced catkin workspace "
                     f"(lib/threshing_sim/{name} under $CMAKE_PREFIX_PATH); build it "
                     f"(scripts/setup.sh) or pass the path of a built {name}")
