"""The benchmark's settings: scenes, knob sweeps, scaling and node settings, metrics."""
import threading

from tslib import ROOT


CACHE_DIR = ROOT / ".build" / "bench" / "cache"

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
