#!/usr/bin/python3
"""Work-precision benchmark: references, error against cost, scaling, the node's budget.

One command regenerates every benchmark figure and table (docs/benchmarks.md, docs/bench.md):

    /usr/bin/python3 scripts/bench.py            # full run (after scripts/setup.sh)

Stages (each run point is cached under .build/bench/cache, keyed by the binary, the scene files
and the arguments, so an interrupted run resumes and a rebuilt binary is measured afresh):

1. References, per benchmark scene of config/bench/: the event-driven integrator at a tight
   tolerance and time stepping at a very small step. Their agreement is printed and tabled. On
   a flexible tooth the reference is also run with more tooth modes, and the change is tabled.
2. Work-precision sweeps: event-driven over tolerances, time stepping over steps. Each point is
   one process of bench/bench_work_precision (pinned to one CPU) that times R repetitions and
   keeps the median wall time per simulated second. Errors against the event-driven reference:
   kernel exit velocity, final pose, peak normal and tangential force, total normal impulse,
   impact count, tip deflection history (RMS); the headline error is the largest of the first
   four. Writes docs/bench/work_precision.csv and docs/bench/wp_<scene>.png.
3. Scaling: cost per simulated second against the kernel count of the stream scene and against
   the tooth's mode count on the single strike, with fitted log-log exponents
   (docs/bench/scaling.csv, docs/bench/scaling.png).
4. The node's budget: threshing_sim_node on the stream scene at real time and its default step
   with growing kernel counts; the largest count whose measured real-time factor stays >= 0.99.
5. docs/bench.md (all tables) and the sections of docs/benchmarks.md between the bench markers.

--quick runs a tiny version into a temporary folder (CI): two knob values per integrator on the
single strike, and asserts that the pipeline works and that the errors fall with the knob.
--stream-kernels N prints the stream scene's kernel override file for N kernels and exits.
"""
import argparse
import concurrent.futures
import csv
import hashlib
import json
import math
import os
import pathlib
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

from tslib import ROOT, markdown, plots
from tslib.binaries import BIN_DIR
from tslib.cache import file_digest

BENCH_DIR = ROOT / "config" / "bench"
CACHE_DIR = ROOT / ".build" / "bench" / "cache"
DOCS = ROOT / "docs"

# Benchmark scenes: name -> (scene file, kernel count of a generated stream or None, label).
SCENES = {
    "single_strike": ("single_strike.yaml", None, "(a) single strike, nylon tooth, 4 modes"),
    "single_strike_rigid": ("single_strike_rigid.yaml", None, "(a) single strike, rigid tooth"),
    "knead_polyurethane": ("knead_polyurethane.yaml", None,
                           "(b) polyurethane tooth kneading a kernel over a bar"),
    "stream": ("stream.yaml", 100, "(c) stream: 4 teeth, grate, 100 kernels"),
}
# Knob sweeps (full run) and the references.
TOLERANCES = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
STEPS_S = [1e-5, 3e-6, 1e-6, 3e-7, 1e-7]
REF_TOLERANCE = 1e-10
REF_DT_S = 1e-8
# The stream is costly: a shorter time-stepping sweep and a coarser cross-check.
STREAM_STEPS_S = STEPS_S
STREAM_REF_DT_S = 1e-8
# Scaling runs.
KERNEL_COUNTS = [1, 10, 100, 1000]
MODE_COUNTS = list(range(0, 9))
SCALING_SETTINGS = {"event_driven": ["--set", "integrator.type=event_driven",
                                     "--set", "integrator.tolerance=1e-6"],
                    "time_stepping": ["--set", "integrator.type=time_stepping",
                                      "--set", "integrator.dt=1e-6"]}
# Node budget: the settings tried (label -> integrator, scene overrides; event-driven syncs
# with the node every 1e-5 s, time stepping at its dt), kernel counts tried, simulated seconds
# per try, and the pass mark. Coarser time steps buy kernels at the price of accuracy (the
# stream's work-precision table gives the error at each dt).
NODE_SETTINGS = {
    "event-driven, tolerance 1e-6 (node step 1e-5 s)": ("event_driven",
                                                         SCALING_SETTINGS["event_driven"]),
    "time stepping, dt 1e-6 s": ("time_stepping", SCALING_SETTINGS["time_stepping"]),
    "time stepping, dt 3e-6 s": ("time_stepping", ["--set", "integrator.type=time_stepping",
                                                   "--set", "integrator.dt=3e-6"]),
    "time stepping, dt 1e-5 s": ("time_stepping", ["--set", "integrator.type=time_stepping",
                                                   "--set", "integrator.dt=1e-5"]),
}
NODE_COUNTS = [1, 10, 20, 30, 40, 50, 100, 200, 500, 1000]
NODE_DURATION_S = 0.2
NODE_RTF_PASS = 0.99
NODE_TIMEOUT_S = 300.0  # a node run that has not finished by then is reported as too slow

METRICS = ["exit_velocity", "pose", "peak_normal", "peak_tangential", "impulse", "impacts",
           "tip_rms"]
HEADLINE = METRICS[:4]
METRIC_LABELS = {"exit_velocity": "exit velocity", "pose": "final pose",
                 "peak_normal": "peak normal force", "peak_tangential": "peak tangential force",
                 "impulse": "total normal impulse", "impacts": "impacts (count difference)",
                 "tip_rms": "tip deflection (RMS)"}
INTEGRATOR_STYLE = {"event_driven": ("tab:blue", "o-"), "time_stepping": ("tab:red", "s--")}

PRINT_LOCK = threading.Lock()
BENCH_CMD = "/usr/bin/python3 scripts/bench.py"


def say(text):
    with PRINT_LOCK:
        print(text, flush=True)


# ------------------------------------------------------------------------------------------
# The stream scene's kernels.

STREAM_PITCH_RAD = 0.04                       # angle between two columns of kernels
STREAM_ROWS_M = [0.195, 0.180, 0.235, 0.250, 0.265, 0.280, 0.295]  # row radii, reachable first
# The idle variant (scaling only): every row beyond the teeth's reach and the grate, so that no
# pair can touch and the cost of the kernels themselves shows.
IDLE_ROWS_M = [0.235, 0.250, 0.265, 0.280, 0.295, 0.310, 0.325]
STREAM_FIRST_OFFSET = 1                       # first column this many pitches ahead of a tooth


# Rows added beyond the last one, this far apart, when a count needs more than the lattice's
# seven rows (the 10 000-kernel scaling points).
STREAM_EXTRA_ROW_PITCH_M = 0.015
# The kernels' pedicel (stream and idle layouts): stiffness [N/m], damping [N s/m], detachment
# force [N], stem length [m]; kernel mass [kg] and long semi-axis [m].
PEDICEL_K, PEDICEL_C, PEDICEL_BREAK, PEDICEL_LENGTH = 1600.0, 0.002, 1.6, 0.003
KERNEL_MASS, KERNEL_A, GRAVITY = 2.8e-5, 5.0e-3, 9.81


def lattice(count, rows, scene=BENCH_DIR / "stream.yaml"):
    """Lattice points (angle about the drum axis, row radius) of the stream scene for `count`
    kernels: columns filled quadrant by quadrant, column o of quadrant q (o + 1) pitches ahead of
    tooth q in the direction of rotation; each column takes the rows in order (reachable
    first), with rows added beyond the last one when the count needs them."""
    import yaml  # python3-yaml, a dependency of the ROS python tools
    with open(scene) as f:
        tree = yaml.safe_load(f)
    drum_angle = tree["drum"]["angle"]
    mounts = [t["mount_angle"] for t in tree["teeth"]]
    quadrant = 2 * math.pi / len(mounts)
    per_quadrant = int(quadrant / STREAM_PITCH_RAD) - STREAM_FIRST_OFFSET
    rows = list(rows)
    while per_quadrant * len(mounts) * len(rows) < count:
        rows.append(rows[-1] + STREAM_EXTRA_ROW_PITCH_M)
    points = []
    for j in range(count):
        # Row-major within a column group, so that the first rows fill first.
        column, row = divmod(j, len(rows)) if len(rows) == len(STREAM_ROWS_M) else (
            j % (per_quadrant * len(mounts)), j // (per_quadrant * len(mounts)))
        offset, q = divmod(column, len(mounts))
        phi = drum_angle + mounts[q] + (offset + STREAM_FIRST_OFFSET) * STREAM_PITCH_RAD
        points.append((phi, rows[row]))
    return points


def stream_kernels(count, rows=STREAM_ROWS_M, scene=BENCH_DIR / "stream.yaml"):
    """The kernel list of the stream scene for `count` kernels, as YAML flow mappings: each
    kernel radial, its pedicel 3 mm beyond its outer end, unstretched (so each starts to swing
    and fall under gravity)."""
    kernels = []
    for phi, r in lattice(count, rows, scene):
        e = (math.cos(phi), math.sin(phi))
        anchor = r + KERNEL_A + PEDICEL_LENGTH
        kernels.append(
            f"{{position: [{r * e[0]:.6f}, {r * e[1]:.6f}], angle: {phi:.6f}, "
            f"semi_axes: [5.0e-3, 1.3e-3], mass: 2.8e-5, youngs_modulus: 2.81e8, "
            f"poisson_ratio: 0.30, pedicel: {{anchor: [{anchor * e[0]:.6f}, {anchor * e[1]:.6f}], "
            f"attach_point: [5.0e-3, 0.0], stiffness: 1600.0, damping: 0.002, rest_length: -1, "
            f"detachment_force: 1.6}}}}")
    return kernels


# Anchors of kernels hanging at rest: a rectangular grid (8 mm across, 16 mm down, so that a
# kernel hanging 13 mm below its anchor clears the next row) from this radius outwards.
HANG_PITCH_M = (0.008, 0.016)
HANG_MIN_RADIUS_M = 0.235


def hanging_anchors(count):
    """The `count` grid anchors nearest the drum axis beyond HANG_MIN_RADIUS_M, nearest first."""
    px, py = HANG_PITCH_M
    reach = HANG_MIN_RADIUS_M
    while True:
        nx, ny = int(reach / px) + 1, int(reach / py) + 1
        points = [(i * px, j * py) for i in range(-nx, nx + 1) for j in range(-ny, ny + 1)]
        points = [p for p in points if HANG_MIN_RADIUS_M <= math.hypot(*p) <= reach]
        if len(points) >= count:
            points.sort(key=lambda p: (round(math.hypot(*p), 9), math.atan2(p[1], p[0])))
            return points[:count]
        reach += 0.05


def hanging_kernels(count):
    """Kernels at rest out of the teeth's reach: each hangs straight down from its anchor at its
    static equilibrium, the stem stretched by m g / k, so that nothing moves until struck."""
    kernels = []
    stem = PEDICEL_LENGTH + KERNEL_MASS * GRAVITY / PEDICEL_K
    for ax, ay in hanging_anchors(count):
        kernels.append(
            f"{{position: [{ax!r}, {ay - stem - KERNEL_A!r}], angle: {math.pi / 2!r}, "
            f"semi_axes: [5.0e-3, 1.3e-3], mass: 2.8e-5, youngs_modulus: 2.81e8, "
            f"poisson_ratio: 0.30, pedicel: {{anchor: [{ax!r}, {ay!r}], "
            f"attach_point: [5.0e-3, 0.0], stiffness: 1600.0, damping: 0.002, "
            f"rest_length: {PEDICEL_LENGTH!r}, detachment_force: 1.6}}}}")
    return kernels


def stream_override_text(count, idle=False):
    """idle: False (the stream), "swinging" (out of reach, unstretched: they swing and fall),
    "rest" or True (out of reach, hanging at rest), or ("sparse", n): n live kernels of the
    stream and count - n at rest out of reach."""
    if idle is True:
        idle = "rest"
    if isinstance(idle, tuple):
        live = stream_kernels(idle[1], STREAM_ROWS_M[:2])  # the two rows in the teeth's reach
        kernels = live + hanging_kernels(count)[idle[1]:]
        what = f", {idle[1]} in reach and the rest hanging at rest out of reach"
        flag = f" --sparse {idle[1]}"
    elif idle == "swinging":
        kernels, what, flag = stream_kernels(count, IDLE_ROWS_M), ", all out of reach", " --idle swinging"
    elif idle == "rest":
        kernels, what, flag = hanging_kernels(count), ", all out of reach, hanging at rest", " --idle"
    else:
        kernels, what, flag = stream_kernels(count), "", ""
    return (f"# Kernels of config/bench/stream.yaml for N = {count}{what} "
            f"(scripts/bench.py --stream-kernels {count}{flag}).\n"
            "kernels: [\n  " + ",\n  ".join(kernels) + "]\n")


def stream_override_file(count, folder, idle=False):
    tag = ("_sparse%d" % idle[1]) if isinstance(idle, tuple) else (
        "" if not idle else "_idle" if idle in (True, "rest") else "_" + str(idle))
    path = pathlib.Path(folder) / f"stream_kernels_{count}{tag}.yaml"
    text = stream_override_text(count, idle)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


# ------------------------------------------------------------------------------------------
# Run points (cached).

class Runner:
    """Runs bench_work_precision points in parallel, one CPU per worker, with a result cache."""

    def __init__(self, bench_bin, jobs, cache_dir, use_cache=True):
        self.bench_bin = pathlib.Path(bench_bin)
        self.jobs = jobs
        self.cache_dir = pathlib.Path(cache_dir)
        self.cache_dir.mkdir(parents=True, exist_ok=True)
        self.use_cache = use_cache
        self.bin_digest = file_digest(self.bench_bin, "sha1")
        self.cpus = sorted(os.sched_getaffinity(0))
        self.free_cpus = list(self.cpus[:max(1, jobs)])
        self.cpu_lock = threading.Lock()
        self.pool = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs))
        self.ran = 0     # points run by this invocation
        self.cached = 0  # points taken from the cache
        self.process_wall_s = 0.0  # summed wall time of every point's process, run or cached

    def key(self, scene, args):
        h = hashlib.sha1(self.bin_digest.encode())
        h.update(file_digest(scene, "sha1").encode())
        for a in args:
            h.update(b"\0" + a.encode())
            if a.endswith(".yaml") and os.path.exists(a):
                h.update(file_digest(a, "sha1").encode())
        return h.hexdigest()

    def _run(self, label, scene, args, reps, budget_s, samples, time_limit_s):
        full = list(args) + ["--reps", str(reps), "--budget", str(budget_s),
                             "--samples", str(samples)]
        if time_limit_s:
            full += ["--time-limit", str(time_limit_s)]
        path = self.cache_dir / (self.key(scene, full) + ".json")
        if self.use_cache and path.exists():
            with open(path) as f:
                result = json.load(f)
            with self.cpu_lock:
                self.cached += 1
                self.process_wall_s += result.get("process_wall_s", 0.0)
            return result
        with self.cpu_lock:
            cpu = self.free_cpus.pop(0)
        try:
            tmp = path.with_suffix(".tmp")
            cmd = [str(self.bench_bin), str(scene)] + full + ["--cpu", str(cpu), "--out", str(tmp)]
            started = time.monotonic()
            proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if proc.returncode not in (0, 1) or not tmp.exists():
                raise RuntimeError(f"{label}: {' '.join(cmd)} failed ({proc.returncode}): "
                                   f"{proc.stderr.strip()}")
            with open(tmp) as f:
                result = json.load(f)
            # The process's own wall time (all repetitions and the sampled run), kept so that
            # a report from the cache can still say what a run from scratch costs.
            result["process_wall_s"] = time.monotonic() - started
            with open(tmp, "w") as f:
                json.dump(result, f)
            os.replace(tmp, path)
            with self.cpu_lock:
                self.ran += 1
                self.process_wall_s += result["process_wall_s"]
            say(f"  {label}: {result['status']}, {result['median_wall_s'] * 1e3:.1f} ms per run "
                f"(median of {len(result['wall_times_s'])}"
                f"{'' if result['completed'] else ', cut short at t = %g s' % result['sim_time_s']}"
                f"), wall {time.monotonic() - started:.1f} s")
            return result
        finally:
            with self.cpu_lock:
                self.free_cpus.append(cpu)

    def submit(self, label, scene, args, reps=1, budget_s=1e9, samples=200, time_limit_s=None):
        return self.pool.submit(self._run, label, scene, args, reps, budget_s, samples,
                                time_limit_s)


def knob_args(integrator, knob):
    if integrator == "event_driven":
        return ["--set", "integrator.type=event_driven", "--set", f"integrator.tolerance={knob:g}"]
    return ["--set", "integrator.type=time_stepping", "--set", f"integrator.dt={knob:g}"]


# ------------------------------------------------------------------------------------------
# Error metrics against a reference.

def rel(a, b):
    return abs(a - b) / abs(b) if b != 0 else abs(a - b)


def errors(run, ref):
    """Relative errors of `run` against `ref` (impacts: absolute count difference)."""
    dv2 = vr2 = dp2 = pr2 = 0.0
    for k, kr in zip(run["kernels"], ref["kernels"]):
        a = kr["semi_axis_a_m"]
        for i in range(2):
            dv2 += (k["velocity_mps"][i] - kr["velocity_mps"][i]) ** 2
            vr2 += kr["velocity_mps"][i] ** 2
            dp2 += (k["position_m"][i] - kr["position_m"][i]) ** 2
            pr2 += (kr["position_m"][i] - kr["initial_position_m"][i]) ** 2
        dp2 += (a * (k["angle_rad"] - kr["angle_rad"])) ** 2
        pr2 += (a * (kr["angle_rad"] - kr["initial_angle_rad"])) ** 2
    e = {"exit_velocity": math.sqrt(dv2 / vr2) if vr2 > 0 else math.sqrt(dv2),
         "pose": math.sqrt(dp2 / pr2) if pr2 > 0 else math.sqrt(dp2),
         "peak_normal": rel(run["peak_normal_force_N"], ref["peak_normal_force_N"]),
         "peak_tangential": rel(run["peak_tangential_force_N"], ref["peak_tangential_force_N"]),
         "impulse": rel(run["total_normal_impulse_Ns"], ref["total_normal_impulse_Ns"]),
         "impacts": abs(run["impacts"] - ref["impacts"])}
    # Tip deflection history: RMS difference over every tooth and sample, relative to the RMS
    # of the reference (rigid teeth: none).
    d2 = w2 = 0.0
    count = 0
    if len(run["sample_times_s"]) == len(ref["sample_times_s"]):
        for tip, tip_ref in zip(run["tip_deflection_m"], ref["tip_deflection_m"]):
            for w, wr in zip(tip, tip_ref):
                d2 += (w - wr) ** 2
                w2 += wr ** 2
                count += 1
    e["tip_rms"] = math.sqrt(d2 / w2) if w2 > 0 else None
    e["headline"] = max(e[m] for m in HEADLINE)
    return e


def fmt(x, digits=2):
    if x is None:
        return "–"
    if isinstance(x, int):
        return str(x)
    if x == 0:
        return "0"
    return f"{x:.{digits}g}" if 1e-3 <= abs(x) < 1e4 else f"{x:.{digits - 1}e}"


def fit_slope(xs, ys):
    """Least-squares slope of log y against log x over the positive pairs (None if < 2)."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x > 0 and y and y > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx > 0 else None


# ------------------------------------------------------------------------------------------
# Stages.

def scene_args(name, gen_dir):
    file, count, _ = SCENES[name]
    args = []
    if count is not None:
        args = ["--set-file", str(stream_override_file(count, gen_dir))]
    return BENCH_DIR / file, args


def samples_for(name, cfg):
    """Tip deflection samples: none for the costly stream (its sampled run would double it)."""
    return 0 if name == "stream" else cfg["samples"]


def modes_of(scene_path):
    import yaml
    with open(scene_path) as f:
        return int(yaml.safe_load(f)["teeth"][0].get("modes", 4))


def references(runner, names, cfg, gen_dir):
    """ED and TS references, and the ED reference with more modes, per scene."""
    futures = {}
    for name in names:
        scene, args = scene_args(name, gen_dir)
        ref_dt = cfg["stream_ref_dt"] if name == "stream" else cfg["ref_dt"]
        samples = samples_for(name, cfg)
        futures[(name, "ed")] = runner.submit(
            f"{name} reference, event-driven tolerance {cfg['ref_tol']:g}", scene,
            args + knob_args("event_driven", cfg["ref_tol"]), samples=samples)
        futures[(name, "ts")] = runner.submit(
            f"{name} cross-check, time stepping dt {ref_dt:g}", scene,
            args + knob_args("time_stepping", ref_dt), samples=samples)
        n = modes_of(scene)
        if n > 0:
            for extra in cfg["mode_steps"]:
                futures[(name, f"modes+{extra}")] = runner.submit(
                    f"{name} reference with {n + extra} modes", scene,
                    args + knob_args("event_driven", cfg["ref_tol"]) +
                    ["--set", f"teeth.*.modes={n + extra}"], samples=samples)
    refs = {}
    for (name, kind), fut in futures.items():
        refs.setdefault(name, {})[kind] = fut.result()
    for name in names:
        r = refs[name]
        r["modes"] = modes_of(scene_args(name, gen_dir)[0])
        r["agreement"] = errors(r["ts"], r["ed"])
        r["mode_change"] = {k: errors(r["ed"], v) for k, v in r.items()
                            if isinstance(k, str) and k.startswith("modes+")}
        a = r["agreement"]
        say(f"{name}: time stepping dt {r['ts']['dt_s']:g} against event-driven tolerance "
            f"{r['ed']['tolerance']:g}: " +
            ", ".join(f"{METRIC_LABELS[m]} {fmt(a[m])}" for m in METRICS))
        for k, e in r["mode_change"].items():
            say(f"{name}: {r['modes']} modes against {r['modes'] + int(k[6:])}: " +
                ", ".join(f"{METRIC_LABELS[m]} {fmt(e[m])}" for m in METRICS))
    return refs


def sweeps(runner, names, cfg, refs, gen_dir):
    futures = []
    for name in names:
        scene, args = scene_args(name, gen_dir)
        steps = cfg["stream_steps"] if name == "stream" else cfg["steps"]
        for integrator, knobs in (("event_driven", cfg["tolerances"]), ("time_stepping", steps)):
            for knob in knobs:
                label = f"{name} {integrator} {knob:g}"
                futures.append((name, integrator, knob, runner.submit(
                    label, scene, args + knob_args(integrator, knob),
                    reps=1 if name == "stream" else cfg["reps"], budget_s=cfg["budget"],
                    samples=samples_for(name, cfg))))
    rows = []
    for name, integrator, knob, fut in futures:
        run = fut.result()
        e = errors(run, refs[name]["ed"])
        rows.append({"scene": name, "integrator": integrator, "knob": knob,
                     "status": run["status"], "deterministic": run["deterministic"],
                     "steps": run["steps"], "reps": len(run["wall_times_s"]),
                     "wall_per_sim_s": run["wall_per_sim_s"],
                     "real_time_factor": 1.0 / run["wall_per_sim_s"],
                     **{m: e[m] for m in METRICS}, "headline": e["headline"]})
    return rows


def scaling(runner, cfg, gen_dir):
    futures = []
    for integrator, settings in SCALING_SETTINGS.items():
        for series, idle in (("kernels", False), ("idle kernels", True)):
            for count in cfg["kernel_counts"]:
                args = ["--set-file", str(stream_override_file(count, gen_dir, idle))] + settings
                futures.append((series, integrator, count, runner.submit(
                    f"scaling: {count} {series}, {integrator}", BENCH_DIR / "stream.yaml", args,
                    reps=cfg["scaling_reps"], budget_s=cfg["budget"], samples=0,
                    time_limit_s=cfg["time_limit"])))
        for modes in cfg["mode_counts"]:
            args = settings + ["--set", f"teeth.*.modes={modes}"]
            futures.append(("modes", integrator, modes, runner.submit(
                f"scaling: {modes} modes, {integrator}", BENCH_DIR / "single_strike.yaml", args,
                reps=cfg["reps"], budget_s=cfg["budget"], samples=0)))
    rows = []
    for series, integrator, n, fut in futures:
        run = fut.result()
        struck = sum(1 for k in run["kernels"] if k["impacts"] > 0)
        rows.append({"series": series, "integrator": integrator, "n": n,
                     "status": run["status"], "completed": run["completed"],
                     "sim_time_s": run["sim_time_s"], "steps": run["steps"],
                     "wall_per_sim_s": run["wall_per_sim_s"],
                     "real_time_factor": 1.0 / run["wall_per_sim_s"],
                     "impacts": run["impacts"], "kernels_with_impacts": struck})
    return rows


def node_budget(cfg, gen_dir, node_counts):
    """The node's measured real-time factor on the stream at growing kernel counts, per
    integrator (stopping at the first count below the pass mark); None without the node."""
    setup = ROOT / ".build" / "ws" / "devel" / "setup.bash"
    if not (BIN_DIR / "threshing_sim_node").exists() or not setup.exists():
        say("node budget: threshing_sim_node not built, skipped")
        return None
    results = []
    port = 11600 + os.getpid() % 200
    for label, (integrator, settings) in NODE_SETTINGS.items():
        for count in node_counts:
            row = node_try(cfg, gen_dir, setup, port, integrator, settings, count)
            if row is None:
                break
            row["setting"] = label
            results.append(row)
            if row["rtf"] < NODE_RTF_PASS:
                break
    return results


def run_bounded(cmd, env, timeout_s):
    """Runs cmd in its own session; (stdout, stderr), or (None, None) when it ran past
    timeout_s (its whole process group, roslaunch and the nodes included, is then stopped:
    SIGINT, then SIGKILL after 20 s)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    try:
        return proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        for sig, wait_s in ((signal.SIGINT, 20), (signal.SIGKILL, 20)):
            try:
                os.killpg(proc.pid, sig)
                proc.communicate(timeout=wait_s)
                break
            except (subprocess.TimeoutExpired, ProcessLookupError):
                continue
        return None, None


def node_try(cfg, gen_dir, setup, port, integrator, settings, count):
    """One node run at real time: its final summary line parsed, or None."""
    import yaml
    kernels = stream_override_file(count, gen_dir)
    # The node reads the scene from a file: the stream scene with these kernels inlined.
    tag = "_".join(a.split("=")[1] for a in settings if "=" in a)
    scene = pathlib.Path(gen_dir) / f"stream_node_{tag}_{count}.yaml"
    with open(BENCH_DIR / "stream.yaml") as f:
        tree = yaml.safe_load(f)
    with open(kernels) as f:
        tree["kernels"] = yaml.safe_load(f)["kernels"]
    # The integrator of SCALING_SETTINGS (the node's default step follows from it).
    for key, value in (a.split("=") for a in settings if "=" in a):
        tree["integrator"][key.split(".")[1]] = float(value) if key.endswith(
            ("tolerance", "dt")) else value
    with open(scene, "w") as f:
        yaml.safe_dump(tree, f)
    cmd = (f"source {setup} && export ROS_IP=127.0.0.1 "
           f"ROS_MASTER_URI=http://127.0.0.1:{port} && "
           f"roslaunch -p {port} --no-summary threshing_sim simulator.launch scene:={scene} "
           f"clock_mode:=wall real_time_factor:=1 duration:={cfg['node_duration']} "
           "status_period:=0")
    env = dict(os.environ, PATH="/usr/bin:" + os.environ.get("PATH", ""))
    stdout, stderr = run_bounded(["bash", "-c", cmd], env, NODE_TIMEOUT_S)
    if stdout is None:
        say(f"node budget, {integrator}: {count} kernels: no summary within "
            f"{NODE_TIMEOUT_S:.0f} s (real-time factor below "
            f"{cfg['node_duration'] / NODE_TIMEOUT_S:.2g})")
        return None
    text = stdout + stderr
    m = re.search(r"simulated ([0-9.]+) s in ([0-9.]+) s of wall time \(real-time factor "
                  r"([0-9.eE+-]+) overall\).*?(\d+) overruns", text)
    if not m:
        say(f"node budget: {count} kernels: no summary line\n"
            f"{text[-800:]}")
        return None
    rtf = float(m.group(3))
    say(f"node budget, {tag}: {count} kernels: real-time factor {rtf:.3g} "
        f"({m.group(1)} s simulated in {m.group(2)} s, {m.group(4)} overruns)")
    return {"integrator": integrator, "n": count, "sim_s": float(m.group(1)),
            "wall_s": float(m.group(2)), "rtf": rtf, "overruns": int(m.group(4))}


# ------------------------------------------------------------------------------------------
# Report.

def plot_work_precision(rows, names, out_dir):
    """Per scene: headline error (left) and exit-velocity error (right) against cost."""
    plt = plots.pyplot()
    paths = []
    for name in names:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
        for ax, metric, ylabel in ((axes[0], "headline", "headline error (largest of four) [-]"),
                                   (axes[1], "exit_velocity", "exit velocity error [-]")):
            for integrator, (color, style) in INTEGRATOR_STYLE.items():
                # In knob order (coarse to fine), so that the line follows the sweep.
                pts = [(r["wall_per_sim_s"], r[metric], r["knob"]) for r in
                       sorted((r for r in rows if r["scene"] == name and
                               r["integrator"] == integrator), key=lambda r: -r["knob"])]
                pts = [p for p in pts if p[1] > 0]
                if not pts:
                    continue
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, color=color,
                          label=integrator.replace("_", "-") +
                          (" (tolerance)" if integrator == "event_driven" else " (dt)"))
                for x, y, knob in pts:
                    ax.annotate(f"{knob:g}", (x, y), textcoords="offset points", xytext=(4, 3),
                                fontsize=7, color=color)
            # Real time and 20x faster than real time.
            for x, text, ls in ((1.0, "real time", ":"), (0.05, "20x", "-.")):
                ax.axvline(x, color="gray", lw=0.8, ls=ls)
                ax.text(x, ax.get_ylim()[0], " " + text, va="bottom", fontsize=7, color="gray")
            ax.set_xlabel("wall time per simulated second [s/s]")
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", lw=0.3)
            ax.legend(fontsize=8, loc="lower left" if metric == "exit_velocity" else "best")
        fig.suptitle(SCENES[name][2], fontsize=10)
        fig.tight_layout()
        path = out_dir / f"wp_{name}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_scaling(rows, out_dir):
    plt = plots.pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for integrator, (color, style) in INTEGRATOR_STYLE.items():
        for series, ls in (("kernels", "-"), ("idle kernels", ":")):
            pts = sorted((r["n"], r["wall_per_sim_s"], r["completed"]) for r in rows
                         if r["series"] == series and r["integrator"] == integrator)
            if pts:
                axes[0].loglog([p[0] for p in pts], [p[1] for p in pts], style[0], ls=ls,
                               color=color, label=f"{integrator.replace('_', '-')}, {series}")
                for n, c, done in pts:
                    if not done:
                        axes[0].annotate("cut short", (n, c), textcoords="offset points",
                                         xytext=(-40, 6), fontsize=7, color=color)
        pts = sorted((r["n"] + 1, r["wall_per_sim_s"]) for r in rows
                     if r["series"] == "modes" and r["integrator"] == integrator)
        axes[1].loglog([p[0] for p in pts], [p[1] for p in pts], style, color=color,
                       label=integrator.replace("_", "-"))
    axes[0].set_xlabel("kernels (stream scene; idle: every kernel out of reach)")
    axes[1].set_xlabel("tooth modes + 1 (single strike)")
    for ax in axes:
        ax.set_ylabel("wall time per simulated second [s/s]")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    path = out_dir / "scaling.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def orders(rows, names):
    """Fitted slopes: log error against log knob, per scene and integrator (headline, exit v)."""
    out = {}
    for name in names:
        for integrator in INTEGRATOR_STYLE:
            sel = [r for r in rows if r["scene"] == name and r["integrator"] == integrator]
            out[(name, integrator)] = {
                m: fit_slope([r["knob"] for r in sel], [r[m] for r in sel])
                for m in ("headline", "exit_velocity", "pose", "impulse")}
    return out


def scaling_exponents(rows):
    out = {}
    for integrator in INTEGRATOR_STYLE:
        k = sorted((r["n"], r["wall_per_sim_s"]) for r in rows
                   if r["series"] == "kernels" and r["integrator"] == integrator)
        idle = sorted((r["n"], r["wall_per_sim_s"]) for r in rows
                      if r["series"] == "idle kernels" and r["integrator"] == integrator)
        m = sorted((r["n"], r["wall_per_sim_s"]) for r in rows
                   if r["series"] == "modes" and r["integrator"] == integrator and r["n"] > 0)
        out[integrator] = {
            "kernels": fit_slope([p[0] for p in k], [p[1] for p in k]),
            "kernels_10_up": fit_slope([p[0] for p in k if p[0] >= 10],
                                       [p[1] for p in k if p[0] >= 10]),
            "idle": fit_slope([p[0] for p in idle], [p[1] for p in idle]),
            "idle_10_up": fit_slope([p[0] for p in idle if p[0] >= 10],
                                    [p[1] for p in idle if p[0] >= 10]),
            "modes": fit_slope([p[0] for p in m], [p[1] for p in m])}
    return out


def dominant(sel):
    """Which of the four headline metrics is the largest, counted over the points."""
    counts = {}
    for r in sel:
        m = max(HEADLINE, key=lambda k: r[k])
        counts[m] = counts.get(m, 0) + 1
    return ", ".join(f"{METRIC_LABELS[m]} ({c} of {len(sel)})"
                     for m, c in sorted(counts.items(), key=lambda kv: -kv[1]))


def best_at(rows, name, integrator, max_wall_per_sim):
    """Smallest headline error among the points at least as fast as the given cost."""
    sel = [r for r in rows if r["scene"] == name and r["integrator"] == integrator
           and r["wall_per_sim_s"] <= max_wall_per_sim]
    return min(sel, key=lambda r: r["headline"]) if sel else None


def table_all_points(rows):
    """docs/bench.md: every point with every metric."""
    lines = ["| scene | integrator | knob | real-time factor | headline error | exit velocity | "
             "final pose | peak normal | peak tangential | normal impulse | impacts ± | "
             "tip RMS |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['integrator'].replace('_', '-')} | {r['knob']:g} | "
            f"{fmt(r['real_time_factor'], 3)} | **{fmt(r['headline'])}** | " +
            " | ".join(fmt(r[m]) for m in METRICS) + " |")
    return "\n".join(lines)


def table_compact(rows, names, ords):
    """Per scene and integrator: the fastest point and the best error at >= 1x and >= 20x."""
    compact = ["| scene | integrator | fastest point: real-time factor, headline error | "
               "best error at ≥ 1× real time | best error at ≥ 20× real time | "
               "slope of log error on log knob (headline / exit velocity) | headline set by |",
               "|---|---|---|---|---|---|---|"]
    for name in names:
        for integrator in INTEGRATOR_STYLE:
            sel = [r for r in rows if r["scene"] == name and r["integrator"] == integrator]
            if not sel:
                continue
            fastest = min(sel, key=lambda r: r["wall_per_sim_s"])
            cells = []
            for limit in (1.0, 0.05):
                b = best_at(rows, name, integrator, limit)
                cells.append(f"{fmt(b['headline'])} (knob {b['knob']:g}, "
                             f"{fmt(b['real_time_factor'], 3)}×)" if b else "none that fast")
            o = ords[(name, integrator)]
            compact.append(
                f"| {name} | {integrator.replace('_', '-')} | {fmt(fastest['real_time_factor'], 3)}×, "
                f"{fmt(fastest['headline'])} (knob {fastest['knob']:g}) | {cells[0]} | {cells[1]} | "
                f"{fmt(o['headline'])} / {fmt(o['exit_velocity'])} | {dominant(sel)} |")
    return "\n".join(compact)


def table_references(refs, names):
    """Each scene's reference against its cross-check and against more tooth modes."""
    lines = ["| scene | modes | reference | cross-check | agreement: exit velocity | "
             "pose | peak normal | peak tangential | impulse | impacts ± | tip RMS | "
             "change with more modes (headline; exit velocity) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        r = refs[name]
        a = r["agreement"]
        mc = "; ".join(f"{r['modes']}→{r['modes'] + int(k[6:])}: {fmt(e['headline'])}; "
                       f"{fmt(e['exit_velocity'])}" for k, e in r["mode_change"].items()) or "rigid"
        lines.append(
            f"| {name} | {r['modes']} | event-driven {r['ed']['tolerance']:g} | time stepping "
            f"{r['ts']['dt_s']:g} | " + " | ".join(fmt(a[m]) for m in METRICS) + f" | {mc} |")
    return "\n".join(lines)


def _cost_cells(r):
    if r is None:
        return "–", "–"
    cut = "" if r["completed"] else f" (cut short at {r['sim_time_s'] * 1e3:.2g} ms)"
    return fmt(r["wall_per_sim_s"], 3) + cut, fmt(r["real_time_factor"], 3)


def table_scaling(scal):
    """Cost per simulated second against kernels, idle kernels and modes, both integrators."""
    lines = ["| series | n | event-driven 1e-6: wall / sim s | real-time factor | "
             "time stepping 1e-6: wall / sim s | real-time factor | kernels struck (ED; TS) |",
             "|---|---|---|---|---|---|---|"]
    for series in ("kernels", "idle kernels", "modes"):
        for n in sorted({r["n"] for r in scal if r["series"] == series}):
            ed, ts = (next((r for r in scal if r["series"] == series and r["n"] == n
                            and r["integrator"] == i), None)
                      for i in ("event_driven", "time_stepping"))
            struck = ("; ".join(str(r["kernels_with_impacts"]) if r else "–" for r in (ed, ts))
                      if series != "modes" else "–")
            lines.append(f"| {series} | {n} | " + " | ".join(_cost_cells(ed)) + " | " +
                         " | ".join(_cost_cells(ts)) + f" | {struck} |")
    return "\n".join(lines)


def text_exponents(scal):
    ex = scaling_exponents(scal) if scal else {}
    return "; ".join(
        f"{i.replace('_', '-')}: cost ∝ kernels^{fmt(e['kernels'], 3)} "
        f"(10–1000: ^{fmt(e['kernels_10_up'], 3)}), idle kernels^{fmt(e['idle'], 3)} "
        f"(10–1000: ^{fmt(e['idle_10_up'], 3)}), ∝ modes^{fmt(e['modes'], 3)} (1–8 modes)"
        for i, e in ex.items())


def text_node(node, cfg):
    """The node's budget: per setting, the real-time factor at each kernel count tried."""
    if not node:
        return "Node budget: not measured in this run (node not built or --no-node)."
    parts = []
    for label in NODE_SETTINGS:
        tried = [n for n in node if n.get("setting") == label]
        if not tried:
            continue
        passing = [n for n in tried if n["rtf"] >= NODE_RTF_PASS]
        parts.append(f"{label}: real-time factor " +
                     ", ".join(f"{n['rtf']:.3g} with {n['n']} kernel"
                               f"{'s' if n['n'] > 1 else ''}" for n in tried) +
                     f"; largest count kept at ≥ {NODE_RTF_PASS}: "
                     f"**{passing[-1]['n'] if passing else 'none (not even 1 kernel)'}**")
    return ("Node budget (`threshing_sim_node` on the stream scene at real-time factor 1, "
            f"wall clock, {cfg['node_duration']:g} s simulated; measured real-time "
            "factor from its final summary, `node_budget.csv`): " + "; ".join(parts) + ".")


def targets_single_strike(rows, ords):
    """The single strike's accuracy-at-speed targets and the measured orders."""
    ss = [r for r in rows if r["scene"] == "single_strike"]
    if not ss:
        return []
    t = []
    for integrator, goal in (("event_driven", 1e-6), ("time_stepping", 1e-2)):
        b = best_at(rows, "single_strike", integrator, 0.05)
        best = min((r for r in ss if r["integrator"] == integrator),
                   key=lambda r: r["headline"], default=None)
        fast_ok = [r for r in ss if r["integrator"] == integrator and r["headline"] <= goal]
        fastest_ok = max(fast_ok, key=lambda r: r["real_time_factor"]) if fast_ok else None
        t.append(f"- single strike, {integrator.replace('_', '-')}: target error ≤ {goal:g} "
                 f"at ≥ 20× real time. Best error at ≥ 20×: "
                 f"{fmt(b['headline']) if b else 'no point that fast'}; fastest point meeting "
                 f"{goal:g}: " + (f"{fmt(fastest_ok['real_time_factor'], 3)}× (knob "
                                  f"{fastest_ok['knob']:g})" if fastest_ok else "none") +
                 (f"; smallest error overall {fmt(best['headline'])}" if best else "") +
                 (" — **met**" if b and b["headline"] <= goal else " — **not met**"))
    o = ords[("single_strike", "time_stepping")]
    t.append(f"- measured order of time stepping on the single strike: "
             f"{fmt(o['exit_velocity'])} (exit velocity), {fmt(o['headline'])} (headline); "
             f"event-driven error against tolerance: {fmt(ords[('single_strike', 'event_driven')]['exit_velocity'])} "
             "(exit velocity)")
    return t


def targets_references(refs, names):
    """Per scene: the cross-check's agreement and the convergence in tooth modes."""
    t = []
    for name in names:
        r = refs[name]
        a = r["agreement"]
        text = (f"- reference of {name}: time stepping at {r['ts']['dt_s']:g} agrees with it to "
                f"{fmt(a['exit_velocity'])} in exit velocity and {fmt(a['headline'])} in the "
                f"headline metrics ({a['impacts']} impacts apart)")
        for k, e in r["mode_change"].items():
            text += (f"; {r['modes']} → {r['modes'] + int(k[6:])} modes changes the exit velocity "
                     f"by {fmt(e['exit_velocity'])} and the headline metrics by "
                     f"{fmt(e['headline'])}")
        if r["mode_change"]:
            worst = max(e["exit_velocity"] for e in r["mode_change"].values())
            text += (" — exit velocity converged in modes to 1 %" if worst <= 0.01 else
                     " — exit velocity **not converged in modes** at the 1 % level")
        t.append(text)
    return t


def targets_scale(scal, node):
    """The 1000-kernel and the node's 100-kernel targets."""
    t = []
    for r in (r for r in scal if r["series"] == "kernels" and r["n"] == 1000):
        t.append(f"- 1000 kernels in `bench_work_precision` ({r['integrator'].replace('_', '-')}, "
                 f"1e-6): {fmt(r['real_time_factor'], 3)}× real time (target ≥ 0.1×) — "
                 f"**{'met' if r['real_time_factor'] >= 0.1 else 'not met'}**")
    for label in NODE_SETTINGS if node else ():
        n100 = next((n for n in node if n["n"] == 100 and n.get("setting") == label), None)
        t.append(f"- 100-kernel stream in the node ({label}): " +
                 (f"real-time factor {n100['rtf']:.3g} (target ≥ 1) — "
                  f"**{'met' if n100['rtf'] >= NODE_RTF_PASS else 'not met'}**" if n100 else
                  "not tried: a smaller count already fell behind real time — **not met**"))
    return t


def text_took(runner, elapsed_s):
    return (f"the points' processes take {runner.process_wall_s / 60:.1f} min of wall time in all "
            f"(run {runner.jobs} at a time on a shared 2-core machine); this invocation took "
            f"{elapsed_s / 60:.1f} min, running {runner.ran} points and taking {runner.cached} "
            "from the cache")


def section_bench(compact, targets, cfg, took, page):
    """The bench-table section of page (docs/benchmarks.md), links relative to it."""
    doc = markdown.link(DOCS / "bench.md", page)
    figures = markdown.link(DOCS / "bench", page)
    return f"""The sweep covers the event-driven tolerance and the time-stepping step on
every scene; each point is the median of several repetitions in one process pinned to one core
(Release), and its errors are measured against the event-driven reference at tolerance
{cfg['ref_tol']:g} (cross-checked by time stepping at a very small step, and with more tooth modes:
[`{doc}`]({doc}), "References"). The headline error is the largest relative error
of the kernel exit velocity, final pose, peak normal force and peak tangential force; the right
panel shows the exit velocity alone. Generated by `{BENCH_CMD}`: {took}. All points and metrics:
[`{doc}`]({doc}) and `docs/bench/work_precision.csv`.

![work-precision, single strike]({figures}/wp_single_strike.png)

{compact}

Targets:

{targets}
"""


def section_scaling(scal, node, cfg, figures):
    """The scaling-table section; figures: the link to docs/bench/ from its page."""
    return f"""Cost per simulated second against the number of kernels (stream scene,
`--stream-kernels N`) and of tooth modes (single strike), from the same command
(`docs/bench/scaling.csv`):

![scaling]({figures}/scaling.png)

{table_scaling(scal)}

Fitted log-log exponents: {text_exponents(scal)}.

{text_node(node, cfg)}
"""


def page_bench_md(refs, rows, names, cfg, compact, scaling_section, targets, took):
    """docs/bench.md: definitions, references, every point, scaling and targets."""
    return f"""# Work-precision benchmark

Generated by `{BENCH_CMD}`; do not edit by hand. Cost of the run: {took}.

## Definitions

Every error is relative to the event-driven reference of its scene (tolerance {cfg['ref_tol']:g}):

- exit velocity: ‖V − V_ref‖ / ‖V_ref‖ over the final velocities of all kernels stacked;
- final pose: ‖P − P_ref‖ / ‖P_ref − P_0‖ over the final positions of all kernels and their angles
  times the semi-major axis a (so the pose error is relative to how far the kernels moved);
- peak normal / tangential force: relative error of the largest normal / tangential contact force
  of the run (the core's maxima over accepted steps and located events; event-driven, a compliant
  normal force's maximum inside a step is located to the tolerance);
- normal impulse: relative error of the total normal impulse;
- impacts: absolute difference of the completed-impact count;
- tip RMS: RMS over the teeth and {cfg['samples']} fixed sample times of the tip deflection
  difference, relative to the RMS of the reference (from a separate, untimed run that lands on the
  sample times).

The headline error is the largest of the first four. Cost is the median wall time of the bare
run (reset + `advanceTo(duration)`, nothing sampled) over up to {cfg['reps']} repetitions
in one process pinned to one core, divided by the simulated time; the real-time factor is its
inverse. Every repetition must end in the bit-identical state (checked; `deterministic` in the CSV).

## References

The event-driven reference against time stepping at a very small step (the cross-check), and
against the same reference with more tooth modes (docs/model.md §9a):

{table_references(refs, names)}

## Work precision

![single strike](bench/wp_single_strike.png)
![single strike, rigid tooth](bench/wp_single_strike_rigid.png)
![knead](bench/wp_knead_polyurethane.png)
![stream](bench/wp_stream.png)

{compact}

All points:

{table_all_points(rows)}

## Scaling

{scaling_section}

## Targets

{targets}
"""


def write_tables(refs, rows, scal, node, names, cfg, elapsed_s, runner, page=None):
    """Markdown: the bench-table and scaling-table sections of page (default: their page,
    docs/benchmarks.md) and the full docs/bench.md."""
    page = page or markdown.page_of("bench-table")
    ords = orders(rows, names)
    compact = table_compact(rows, names, ords)
    targets = "\n".join(targets_single_strike(rows, ords) + targets_references(refs, names) +
                        targets_scale(scal, node))
    took = text_took(runner, elapsed_s)
    bench_section = section_bench(compact, targets, cfg, took, page)
    scaling_section = section_scaling(scal, node, cfg, markdown.link(DOCS / "bench", page))
    doc = page_bench_md(refs, rows, names, cfg, compact,
                        section_scaling(scal, node, cfg, "bench"), targets, took)
    return bench_section, scaling_section, doc


def write_csv(path, rows):
    if not rows:
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else (f"{v:.6g}" if isinstance(v, float) else v))
                        for k, v in r.items()})


# ------------------------------------------------------------------------------------------

def parse_args():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="tiny CI version into --out")
    ap.add_argument("--out", help="output folder (default: docs/; --quick: a temporary folder)")
    ap.add_argument("--bin", default=str(BIN_DIR), help="folder of the built binaries")
    ap.add_argument("--jobs", type=int, default=2, help="parallel points, one CPU each")
    ap.add_argument("--reps", type=int, default=5, help="timed repetitions per point")
    ap.add_argument("--no-cache", action="store_true", help="rerun every point")
    ap.add_argument("--no-node", action="store_true", help="skip the node budget")
    ap.add_argument("--no-readme", action="store_true", help="leave docs/benchmarks.md and docs/architecture.md alone")
    ap.add_argument("--part", choices=["all", "islands"], default="all",
                    help="islands: only the island-local scheme's part (scripts/bench_islands.py:"
                         " scaling to 10 000 kernels, events by kind, instructions per event, "
                         "the node at 100 and 1000 kernels, the targets)")
    ap.add_argument("--stream-kernels", type=int, metavar="N",
                    help="print the stream scene's kernel override file for N kernels and exit")
    ap.add_argument("--idle", nargs="?", const="rest", choices=["rest", "swinging"],
                    help="with --stream-kernels: every kernel out of reach, hanging at rest "
                         "(default) or swinging from unstretched pedicels")
    ap.add_argument("--sparse", type=int, metavar="N",
                    help="with --stream-kernels: N kernels of the stream in reach, the rest "
                         "hanging at rest out of reach")
    return ap.parse_args()


def configuration(args):
    """The sweep's settings, scenes, output folder and cache: the CI's tiny version (--quick) or
    the full one."""
    if args.quick:
        cfg = {"tolerances": [1e-4, 1e-7], "steps": [1e-5, 1e-6], "stream_steps": [1e-5, 1e-6],
               "ref_tol": 1e-9, "ref_dt": 1e-7, "stream_ref_dt": 1e-7, "mode_steps": [2],
               "reps": 2, "budget": 5.0, "samples": 200, "kernel_counts": [1, 10],
               "mode_counts": [0, 2], "scaling_reps": 1, "node_duration": NODE_DURATION_S,
               "time_limit": 10.0}
        out = pathlib.Path(args.out or tempfile.mkdtemp(prefix="bench_quick_"))
        return cfg, ["single_strike"], out, out / "cache"
    cfg = {"tolerances": TOLERANCES, "steps": STEPS_S, "stream_steps": STREAM_STEPS_S,
           "ref_tol": REF_TOLERANCE, "ref_dt": REF_DT_S, "stream_ref_dt": STREAM_REF_DT_S,
           "mode_steps": [1, 2], "reps": args.reps, "budget": 20.0, "samples": 200,
           "kernel_counts": KERNEL_COUNTS, "mode_counts": MODE_COUNTS, "scaling_reps": 3,
           "node_duration": NODE_DURATION_S, "time_limit": 60.0}
    return cfg, list(SCENES), pathlib.Path(args.out) if args.out else DOCS, CACHE_DIR


def quick_problems(rows, refs, names, fig_dir):
    """The CI checks of the quick sweep: errors fall with the knob, the references agree, the
    figures exist."""
    problems = []
    for name in names:
        for integrator in INTEGRATOR_STYLE:
            sel = sorted((r for r in rows if r["scene"] == name and
                          r["integrator"] == integrator), key=lambda r: -r["knob"])
            # Exit velocity and pose converge under both integrators; the force peaks of
            # time stepping are impulses over one step and need not improve between two
            # coarse steps (see docs/bench.md).
            for m in ("exit_velocity", "pose"):
                if not sel[-1][m] < sel[0][m]:
                    problems.append(f"{name} {integrator}: {m} error does not fall with the "
                                    f"knob ({sel[0][m]:.3g} -> {sel[-1][m]:.3g})")
    for name in names:
        a = refs[name]["agreement"]
        if not a["exit_velocity"] < 1e-3:
            problems.append(f"{name}: references disagree on the exit velocity "
                            f"({a['exit_velocity']:.3g})")
    for f in ("wp_single_strike.png", "scaling.png", "work_precision.csv", "scaling.csv"):
        if not (fig_dir / f).exists() or (fig_dir / f).stat().st_size < 500:
            problems.append(f"{f} missing")
    return problems


def main():
    args = parse_args()
    if args.stream_kernels is not None:
        idle = ("sparse", args.sparse) if args.sparse is not None else (args.idle or False)
        sys.stdout.write(stream_override_text(args.stream_kernels, idle))
        return 0

    started = time.monotonic()
    bench_bin = pathlib.Path(args.bin) / "bench_work_precision"
    if not bench_bin.exists():
        raise SystemExit(f"bench: {bench_bin} not found: build first (bash scripts/setup.sh)")
    cfg, names, out, cache = configuration(args)
    fig_dir = out / "bench"
    fig_dir.mkdir(parents=True, exist_ok=True)
    gen_dir = cache.parent / "generated" if not args.quick else out / "generated"
    gen_dir.mkdir(parents=True, exist_ok=True)
    runner = Runner(bench_bin, args.jobs, cache, use_cache=not args.no_cache)
    if args.part == "islands":
        import bench_islands  # scripts/bench_islands.py
        bench_islands.run(args, runner, gen_dir, out, fig_dir)
        return 0

    say(f"bench: references ({', '.join(names)})")
    refs = references(runner, names, cfg, gen_dir)
    say("bench: work-precision sweeps")
    rows = sweeps(runner, names, cfg, refs, gen_dir)
    write_csv(fig_dir / "work_precision.csv", rows)
    plot_work_precision(rows, names, fig_dir)
    say("bench: scaling runs")
    scal = scaling(runner, cfg, gen_dir)
    write_csv(fig_dir / "scaling.csv", scal)
    plot_scaling(scal, fig_dir)
    node = None
    if not args.no_node and not args.quick:
        say("bench: node budget")
        node = node_budget(cfg, gen_dir, NODE_COUNTS)
        if node:
            write_csv(fig_dir / "node_budget.csv", node)
    if not args.quick:
        import bench_islands  # scripts/bench_islands.py
        bench_islands.run(args, runner, gen_dir, out, fig_dir)
    elapsed = time.monotonic() - started
    bench_section, scaling_section, doc = write_tables(refs, rows, scal, node, names, cfg,
                                                       elapsed, runner)
    (out / "bench.md").write_text(doc)
    if not args.quick and not args.no_readme and not args.out:
        markdown.splice("bench-table", bench_section)
        markdown.splice("scaling-table", scaling_section)
    say(f"bench: wrote {out / 'bench.md'}, {fig_dir} in {elapsed / 60:.1f} min")

    # Checks: every point ran, deterministically, and the errors fall with the knob.
    problems = []
    for r in rows:
        if r["status"] == "failed":
            problems.append(f"{r['scene']} {r['integrator']} {r['knob']:g}: failed")
        if not r["deterministic"]:
            problems.append(f"{r['scene']} {r['integrator']} {r['knob']:g}: reruns differ")
    if args.quick:
        problems += quick_problems(rows, refs, names, fig_dir)
    for p in problems:
        say(f"bench: PROBLEM: {p}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
