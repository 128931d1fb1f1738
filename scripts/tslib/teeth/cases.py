"""The tooth comparison's cases, teeth and speeds, and its runs: one simulate invocation per
case, tooth variant and drum speed (ToothRun), run in parallel (run_all), and the teeth's
frequencies (simulate --modes)."""
import concurrent.futures
import csv
import json
import re
import subprocess
import time

from tslib import SCENE_DIR, schema
# Case name -> (scene file stem, override file in config/scenes/cases or None).
CASES = {"single_strike": ("single_strike", None), "tip_strike": ("single_strike", "tip_strike"),
         "knead": ("knead", None), "stream": ("stream", None)}
FROZEN_CASES = ["single_strike", "tip_strike", "knead"]  # the stream is too costly to double
VARIANTS = ["rigid", "spring_steel", "nylon", "polyurethane"]
FLEXIBLE = VARIANTS[1:]
# Case -> the teeth whose modal tooth bends past the small-deflection range there (the core's
# deflection_validity_fraction, 0.1 L, at some drum speed of the sweep): they run as
# large-deflection rods (LD_FILE). The "modal" group reruns them with the modal tooth at
# HISTORY_RPM, and the findings page lists any modal run of the sweep that leaves the range.
LARGE_DEFLECTION = {"knead": ["nylon", "polyurethane"], "stream": ["polyurethane"]}
LD_FILE = SCENE_DIR / "cases" / "large_deflection.yaml"


def validity_fraction():
    """The core's deflection_validity default [-] (simulate --print-schema): the tip
    deflection over L past which the modal tooth leaves its validity range."""
    return schema.default("deflection_validity")


def damage_thresholds():
    """The core's (plastic, fracture) force thresholds of kernel damage [N] (the damage
    section's defaults, simulate --print-schema)."""
    return schema.default("damage.plastic_force"), schema.default("damage.fracture_force")



COLORS = {"rigid": "black", "spring_steel": "tab:blue", "nylon": "tab:green",
          "polyurethane": "tab:red"}
STYLES = {"rigid": "o-", "spring_steel": "s--", "nylon": "^-.", "polyurethane": "v:"}
RPM_FULL = list(range(600, 1501, 100))
RPM_QUICK = [800, 1200]
HISTORY_RPM = 800          # speed whose contact force histories are recorded and plotted
CONVERGENCE_MODES = [2, 4, 6, 8, 10]
QUICK_STREAM = ["--set", "stream.count=2", "--set", "duration=0.003"]
from tslib.numbers import RADPS_PER_RPM  # noqa: E402

# Physical references (docs/model.md §10 and §9a).
MEASURED_FORCE_N = (43.9, 71.9)   # measured threshing force on a kernel
HERTZ_TIME_US = (32.0, 43.0)      # Hertz contact time of a paddy kernel hit at 13-25 m/s
HERTZ_SPEED_MPS = (13.0, 25.0)


# ------------------------------------------------------------------------------------------
# Runs.

def scene_args(case, variant):
    """simulate arguments of a case with a tooth variant: the scene, the tooth file, the case
    file, and LD_FILE where the tooth is a large-deflection rod (LARGE_DEFLECTION)."""
    scene, case_file = CASES[case]
    args = [str(SCENE_DIR / f"{scene}.yaml"),
            "--set-file", str(SCENE_DIR / "teeth" / f"{variant}.yaml")]
    if case_file:
        args += ["--set-file", str(SCENE_DIR / "cases" / f"{case_file}.yaml")]
    if variant in LARGE_DEFLECTION.get(case, []):
        args += ["--set-file", str(LD_FILE)]
    return args


class ToothRun:
    """One simulate invocation: a case with a tooth variant at a drum speed."""

    def __init__(self, out, group, case, variant, rpm, modes=None, forces=False, quick=False,
                 rotation=None, model=None):
        self.group = group    # "sweep", "frozen" (modes 0), "convergence", "euler_bernoulli"
        #                       or "modal"
        self.case = case
        self.variant = variant
        self.rpm = rpm
        self.modes = modes    # override of every tooth's mode count, or None
        self.forces = forces
        self.quick = quick
        self.rotation = rotation  # override of teeth.*.section_rotation, or None
        self.model = model        # override of teeth.*.model (after LD_FILE), or None
        name = f"{rpm}rpm" + ("" if modes is None else f"_{modes}modes")
        self.dir = out / "runs" / group / case / variant / name

    def command(self, simulate):
        cmd = [str(simulate)] + scene_args(self.case, self.variant)
        cmd += ["--set", f"drum.speed={self.rpm * RADPS_PER_RPM!r}"]
        if self.modes is not None:
            cmd += ["--set", f"teeth.*.modes={self.modes}"]
        if self.rotation is not None:
            cmd += ["--set", f"teeth.*.section_rotation={self.rotation}"]
        if self.model is not None:
            cmd += ["--set", f"teeth.*.model={self.model}"]
        if self.quick and CASES[self.case][0] == "stream":
            cmd += QUICK_STREAM
        cmd += ["--summary", str(self.dir / "summary.json"),
                "--outcomes", str(self.dir / "outcomes.csv"),
                "--events", str(self.dir / "events.csv"), "--quiet"]
        if self.forces:
            cmd += ["--forces", str(self.dir / "forces.csv")]
        return cmd

    def execute(self, simulate, reuse=False):
        """Runs simulate (unless reuse and its summary exists); returns (self, error message or
        None, wall time [s])."""
        if reuse and (self.dir / "summary.json").is_file():
            return self, None, 0.0
        self.dir.mkdir(parents=True, exist_ok=True)
        started = time.monotonic()
        proc = subprocess.run(self.command(simulate), capture_output=True, text=True)
        wall_s = time.monotonic() - started
        if proc.returncode != 0:
            return self, proc.stderr.strip() or f"exit status {proc.returncode}", wall_s
        return self, None, wall_s

    def rod(self):
        """Whether the run's tooth is the large-deflection rod."""
        return self.model is None and self.variant in LARGE_DEFLECTION.get(self.case, [])

    def label(self):
        modes = "" if self.modes is None else f", {self.modes} modes"
        return f"{self.group} {self.case} {self.variant} {self.rpm} rpm{modes}"

    def summary(self):
        with open(self.dir / "summary.json") as f:
            return json.load(f)

    def kernels(self):
        return self.summary()["outcomes"]["per_kernel"]

    def events(self):
        with open(self.dir / "events.csv") as f:
            return list(csv.DictReader(f))


def run_all(runs, simulate, jobs, reuse):
    """Runs every simulation on `jobs` workers, printing progress as they finish."""
    started = time.monotonic()
    failures = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = [pool.submit(r.execute, simulate, reuse) for r in runs]
        for done, future in enumerate(concurrent.futures.as_completed(futures), 1):
            run, error, wall_s = future.result()
            if error:
                failures.append((run, error))
            state = "FAILED: " + error.splitlines()[-1] if error else "ok"
            print(f"[{done:3d}/{len(runs)}] {time.monotonic() - started:6.1f} s  {run.label()}: "
                  f"{state} ({wall_s:.1f} s)", flush=True)
    # A run the core stopped on its work budget wrote its summary up to the stop: its outcomes
    # so far are kept and the findings page lists it (PARTIAL); any other failure stops here.
    hard = []
    for run, error in failures:
        status = run.summary()["status"] if (run.dir / "summary.json").is_file() else ""
        if "[work_budget]" in status:
            PARTIAL.append((run, status))
        else:
            hard.append((run, error))
    if hard:
        run, error = hard[0]
        raise SystemExit(f"{len(hard)} simulations failed, e.g. {run.label()}:\n{error}")


PARTIAL = []  # (run, status) of the runs stopped by the work budget (run_all)


def partial_paragraph():
    """The runs stopped early by the core's work budget, for the findings page."""
    if not PARTIAL:
        return "Every simulation ran to its end."
    items = []
    for run, status in sorted(PARTIAL, key=lambda p: p[0].label()):
        t = re.search(r"at t = ([0-9.e+-]+) s", status)
        items.append(f"{run.label()} (at {float(t.group(1)) * 1e3:.2f} ms)" if t else run.label())
    return (f"{len(PARTIAL)} of the simulations stopped before their end on the core's work "
            "budget (`work_budget`: a stretch of contact events every 0.1 us or less, kernels "
            "resting or sliding on each other, the bars or a tooth); their outcomes up to the "
            "stop are used: " + "; ".join(items) + ".")


def tooth_frequencies(simulate, variant, rpms):
    """Bending frequencies [Hz] of the variant's tooth at each drum speed (simulate --modes);
    empty for the rigid tooth."""
    freqs = []
    for rpm in rpms:
        out = subprocess.run(
            [str(simulate), str(SCENE_DIR / "single_strike.yaml"), "--set-file",
             str(SCENE_DIR / "teeth" / f"{variant}.yaml"), "--set",
             f"drum.speed={rpm * RADPS_PER_RPM!r}", "--modes"],
            capture_output=True, text=True, check=True).stdout
        line = next((ln for ln in out.splitlines() if "rpm):" in ln), None)
        if line is None:
            return []
        freqs.append([float(v) for v in line.split("):")[1].replace("Hz", "").split(",")])
    return freqs
