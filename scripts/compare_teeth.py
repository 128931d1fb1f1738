#!/usr/bin/python3
"""Runs the threshing scenes across tooth variants and drum speeds and reports what they show.

Cases: the scenes config/scenes/{single_strike,knead,stream}.yaml, and the single strike with
the kernel at the tooth's tip (config/scenes/cases/tip_strike.yaml). Each case runs with every
tooth variant (config/scenes/teeth/*.yaml) at every drum speed, by invoking the built
`simulate` binary in parallel over the cores; summaries, per-kernel outcomes, events and (at
one speed) contact force samples land in OUT/runs/. Controls: every flexible tooth frozen (no
bending modes, same material and contact) on every case but the stream, which separates the
effect of bending from that of the contact material; a modal convergence check of the single
strike. Then OUT/report.md is written with plots (PNG): force histories, peak forces, knead
force, damage, detachment and sub-collisions against drum speed, and a Campbell diagram of the
teeth's frequencies (simulate --modes).

With --findings, docs/findings.md (the full report: the paper's three claims judged from these
numbers) and its plots in docs/findings/ are regenerated too, and so is the findings section of docs/threshing_findings.md
(between its findings markers): the three
verdicts with their key numbers, the key plots, and the agreement with the measured threshing
force and the Hertz contact time. --quick runs a tiny sweep (for the CI test).

Force peaks and their times come from the core (RunStats::kernel_tooth_peaks: every accepted
step, the located maxima of compliant normal forces, and both sides of every located event),
not from the force samples, which only feed the force history plots.
"""
import argparse
import concurrent.futures
import csv
import json
import math
import os
import pathlib
import re
import shutil
import subprocess
import sys
import time

import numpy as np

from tslib import markdown, plots
from tslib.binaries import find_binary

plt = plots.pyplot()

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENE_DIR = ROOT / "config/scenes"
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
VALIDITY_FRACTION = 0.1   # model.deflection_validity_fraction's default [-]
COLORS = {"rigid": "black", "spring_steel": "tab:blue", "nylon": "tab:green",
          "polyurethane": "tab:red"}
STYLES = {"rigid": "o-", "spring_steel": "s--", "nylon": "^-.", "polyurethane": "v:"}
RPM_FULL = list(range(600, 1501, 100))
RPM_QUICK = [800, 1200]
HISTORY_RPM = 800          # speed whose contact force histories are recorded and plotted
CONVERGENCE_MODES = [2, 4, 6, 8, 10]
QUICK_STREAM = ["--set", "stream.count=2", "--set", "duration=0.003"]
RADPS_PER_RPM = math.pi / 30.0

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


class Run:
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


# ------------------------------------------------------------------------------------------
# Numbers from the runs.

def touched(kernels):
    """Outcome entries of the kernels a tooth touched."""
    return [k for k in kernels if k["time_of_peak_normal_s"] is not None]


def stick_slip_times(run):
    """Times [s] of the stick <-> slip transitions of every tooth contact, per kernel."""
    times = {}
    for e in run.events():
        if e["kind"] == "tooth_kernel" and {e["from"], e["to"]} == {"stick", "slip"}:
            times.setdefault(int(e["b"]), set()).add(float(e["t_s"]))
    return times


def state_at(tooth_events, kernel, t_s):
    """State (stick, slip, ...) of a kernel's tooth contact at time t_s: the `from` state of the
    first of its tooth events after t_s (the compliant law enters stick or slip without an
    event, so the event before t_s may still say `impact`); None without a later event."""
    return next((e["from"] for e in tooth_events
                 if int(e["b"]) == kernel and float(e["t_s"]) > t_s), None)


def metrics(run):
    """Per-run numbers for the tables, plots and findings."""
    kernels = run.kernels()
    hit = touched(kernels)
    transitions = stick_slip_times(run)
    tooth_events = [e for e in run.events() if e["kind"] == "tooth_kernel"]
    macros = sum(k["macro_collisions"] for k in kernels)
    subs = sum(k["sub_collisions"] for k in kernels)
    return {
        "peak_normal_N": max((k["peak_normal_force_N"] for k in hit), default=0.0),
        "knead_N": max((k["peak_tangential_force_N"] for k in hit), default=0.0),
        "max_contact_N": max(k["max_contact_force_N"] for k in kernels),
        "subs_per_macro": subs / macros if macros else float("nan"),
        "separations_us": [1e6 * k["peak_separation_s"] for k in hit],
        # Whether each touched kernel's tangential peak falls on a stick-slip transition (the
        # same time to the last bit: both are the time of one accepted step).
        "peak_at_transition": [k["time_of_peak_tangential_s"] in transitions.get(k["kernel"], ())
                               for k in hit],
        "state_at_normal_peak": [state_at(tooth_events, k["kernel"], k["time_of_peak_normal_s"])
                                 for k in hit],
        "damaged": sum(k["damage"] != "none" for k in kernels) / len(kernels),
        "detached": sum(k["detached"] for k in kernels) / len(kernels),
        "tip": run.summary()["max_tip_deflection_ratio"],
        "rod": run.rod(),
    }


def first_tooth_episode(run):
    """Duration [us] and approach speed [m/s] of the first tooth-kernel contact episode."""
    start = None
    for e in run.events():
        if e["kind"] != "tooth_kernel":
            continue
        if start is None and e["from"] == "separated" and e["to"] == "impact":
            start = float(e["t_s"])
        elif start is not None and e["is_impact"] == "1":
            return 1e6 * (float(e["t_s"]) - start), -float(e["vn_before_mps"])
    return float("nan"), float("nan")


def tooth_episodes(run, kernel):
    """(start, end) [ms] of every tooth contact episode (sub-collision) of one kernel."""
    episodes, start = [], None
    for e in run.events():
        if e["kind"] != "tooth_kernel" or int(e["b"]) != kernel:
            continue
        if e["from"] == "separated" and e["to"] == "impact":
            start = 1e3 * float(e["t_s"])
        elif e["is_impact"] == "1" and start is not None:
            episodes.append((start, 1e3 * float(e["t_s"])))
            start = None
    return episodes


def nan_mean(values):
    values = [v for v in values if not math.isnan(v)]
    return float(np.mean(values)) if values else float("nan")


def ratio_range(numerators, denominators):
    """(min, max) of numerator / denominator over the speeds both have (nan without any)."""
    ratios = [numerators[r] / denominators[r] for r in numerators
              if r in denominators and denominators[r] > 0]
    return (min(ratios), max(ratios)) if ratios else (float("nan"), float("nan"))


def analyse(runs, sample_us):
    """Every number the report and the findings state."""
    table, frozen, euler, modal = {}, {}, {}, {}
    for run in runs:
        if run.group == "sweep":
            table.setdefault((run.case, run.variant), {})[run.rpm] = metrics(run)
        elif run.group == "frozen":
            frozen.setdefault((run.case, run.variant), {})[run.rpm] = metrics(run)
        elif run.group == "euler_bernoulli":
            euler[(run.case, run.variant)] = metrics(run)
        elif run.group == "modal":
            modal[(run.case, run.variant)] = metrics(run)
    a = {"table": table, "frozen": frozen, "euler": euler, "modal": modal, "sample_us": sample_us,
         "threshold_us": 2 * sample_us}

    # Claim 1: share of touched kernels whose two peaks lie more than two sampling intervals
    # apart (simulate lands on every sample time near a tooth, so the interval bounds the
    # integrator's steps there and thus the resolution of the peak times).
    a["separation"] = {}
    for key, by_rpm in table.items():
        seps = [abs(s) for m in by_rpm.values() for s in m["separations_us"]]
        at_transition = [t for m in by_rpm.values() for t in m["peak_at_transition"]]
        states = [st for m in by_rpm.values() for st in m["state_at_normal_peak"]]
        a["separation"][key] = {
            "n": len(seps),
            "separated": sum(s > a["threshold_us"] for s in seps),
            "separated_at_transition": sum(s > a["threshold_us"] and t
                                           for s, t in zip(seps, at_transition)),
            "together_sliding": sum(s <= a["threshold_us"] and st == "slip"
                                    for s, st in zip(seps, states)),
            "median_us": float(np.median(seps)) if seps else float("nan")}

    # Claim 2: sub-collisions per macro-collision against the rigid tooth and the frozen tooth.
    a["subs"] = {}
    for (case, variant), by_rpm in table.items():
        rigid = table.get((case, "rigid"), {})
        still = frozen.get((case, variant), {})
        more = fewer = caused = compared = 0
        for rpm, m in by_rpm.items():
            if rpm not in rigid or math.isnan(m["subs_per_macro"] + rigid[rpm]["subs_per_macro"]):
                continue
            compared += 1
            more += m["subs_per_macro"] > rigid[rpm]["subs_per_macro"]
            fewer += m["subs_per_macro"] < rigid[rpm]["subs_per_macro"]
            caused += (rpm in still and m["subs_per_macro"] > still[rpm]["subs_per_macro"]
                       and m["subs_per_macro"] > rigid[rpm]["subs_per_macro"])
        a["subs"][(case, variant)] = {
            "mean": nan_mean([m["subs_per_macro"] for m in by_rpm.values()]),
            "more": more, "fewer": fewer, "by_bending": caused, "n": compared,
            "rigid_max": max((m["subs_per_macro"] for m in by_rpm.values()
                              if not math.isnan(m["subs_per_macro"])), default=float("nan"))}

    # Claim 3: knead force on the knead scene against the rigid tooth and the frozen tooth.
    knead = {v: {r: m["knead_N"] for r, m in table.get(("knead", v), {}).items()}
             for v in VARIANTS}
    knead_frozen = {v: {r: m["knead_N"] for r, m in frozen.get(("knead", v), {}).items()}
                    for v in FLEXIBLE}
    a["knead"] = {v: {"to_rigid": ratio_range(knead[v], knead["rigid"]),
                      "to_frozen": ratio_range(knead[v], knead_frozen[v]),
                      "frozen_to_rigid": ratio_range(knead_frozen[v], knead["rigid"])}
                  for v in FLEXIBLE if knead[v]}

    # Threshing force and contact time of the single strike.
    a["strike"] = {}
    for run in runs:
        if run.group == "sweep" and run.case == "single_strike":
            duration_us, speed_mps = first_tooth_episode(run)
            a["strike"][(run.variant, run.rpm)] = {
                "peak_N": table[(run.case, run.variant)][run.rpm]["peak_normal_N"],
                "contact_us": duration_us, "speed_mps": speed_mps}

    # Modal convergence of the single strike.
    a["convergence"] = {}
    for run in runs:
        if run.group == "convergence":
            duration_us, _ = first_tooth_episode(run)
            m = metrics(run)
            a["convergence"][(run.variant, run.modes)] = (m["peak_normal_N"], duration_us,
                                                          m["subs_per_macro"])
    return a


# ------------------------------------------------------------------------------------------
# Plots.

def save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_histories(runs, case, path):
    """Normal and tangential tooth force on one kernel (the hardest hit) against time, per
    variant, each sub-collision (contact episode) shaded."""
    fig, axes = plt.subplots(len(runs), 1, figsize=(9, 2.3 * len(runs)), squeeze=False)
    for ax, run in zip(axes[:, 0], runs):
        hit = touched(run.kernels())
        if not hit:
            ax.set_title(f"{case}, {run.variant}: no tooth contact", fontsize=9)
            continue
        kernel = max(hit, key=lambda k: k["peak_normal_force_N"])["kernel"]
        t, fn, ft = [], [], []
        with open(run.dir / "forces.csv") as f:
            for row in csv.DictReader(f):
                if row["kind"] == "tooth_kernel" and int(row["b"]) == kernel:
                    t.append(1e3 * float(row["t_s"]))
                    fn.append(float(row["normal_force_N"]))
                    ft.append(float(row["tangential_force_N"]))
        episodes = tooth_episodes(run, kernel)
        for i, (start, end) in enumerate(episodes):
            ax.axvspan(start, end, color="tab:orange" if i % 2 else "tab:purple", alpha=0.15,
                       lw=0)
        ax.plot(t, fn, lw=1, color="tab:blue", label="normal")
        ax.plot(t, ft, lw=1, color="tab:red", label="tangential")
        if episodes:
            pad = 0.05 * (episodes[-1][1] - episodes[0][0]) + 0.02
            ax.set_xlim(episodes[0][0] - pad, episodes[-1][1] + pad)
        ax.set_title(f"{case}, {run.variant}, {run.rpm} rpm, kernel {kernel}: "
                     f"{len(episodes)} tooth contact episodes (shaded)", fontsize=9)
        ax.set_ylabel("force [N]")
        ax.legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time [ms]")
    save(fig, path)


def plot_against_speed(table, cases, key, ylabel, path, band=None, lines=()):
    """One panel per case: table[(case, variant)][rpm][key] against drum speed."""
    fig, axes = plt.subplots(1, len(cases), figsize=(3.8 * len(cases), 3.4), squeeze=False)
    for ax, case in zip(axes[0], cases):
        for variant in VARIANTS:
            by_rpm = table.get((case, variant))
            if by_rpm:
                rpms = sorted(by_rpm)
                ax.plot(rpms, [by_rpm[r][key] for r in rpms], STYLES[variant], ms=4,
                        mfc="none", color=COLORS[variant], label=variant)
        if band:
            ax.axhspan(*band[0], color="grey", alpha=0.2, label=band[1])
        for value, style, text in lines:
            ax.axhline(value, ls=style, lw=0.8, color="grey", label=text)
        ax.set_title(case)
        ax.set_xlabel("drum speed [rpm]")
        ax.set_ylabel(ylabel)
    axes[0, 0].legend(fontsize=7)
    save(fig, path)


def plot_campbell(freqs, rpms, path):
    """Tooth bending frequencies against drum speed (the first 12 modes, or as many as every
    speed retains: the automatic count varies with the tip speed), with rotation orders and the
    inverse Hertz contact time (modes far above it are barely excited by an impact)."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for variant, per_rpm in freqs.items():
        n = min([12] + [len(f) for f in per_rpm])
        for j, mode in enumerate(np.array([f[:n] for f in per_rpm]).T):
            ax.plot(rpms, mode, "o-", ms=2, color=COLORS[variant],
                    label=variant if j == 0 else None)
    rpm_axis = np.array(rpms, dtype=float)
    for order in (1, 2, 6):
        ax.plot(rpm_axis, order * rpm_axis / 60.0, ":", color="grey", lw=0.8)
        ax.text(rpm_axis[-1], order * rpm_axis[-1] / 60.0, f" {order}x", fontsize=7)
    ax.axhline(1e6 / HERTZ_TIME_US[1], ls="--", color="grey", lw=0.8)
    ax.text(rpm_axis[0], 1e6 / HERTZ_TIME_US[1], " 1 / Hertz contact time", fontsize=7,
            va="bottom")
    ax.set_yscale("log")
    ax.set_xlabel("drum speed [rpm]")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title("Campbell diagram: tooth bending modes and rotation orders (6 teeth: 6x)")
    ax.legend(fontsize=7)
    save(fig, path)


def make_plots(out, runs, a, freqs, rpms, history_rpm):
    """Writes every plot into out; returns their (file name, caption) in report order."""
    plots = []
    for case in CASES:
        history = [r for r in runs if r.group == "sweep" and r.case == case
                   and r.rpm == history_rpm]
        if history:
            name = f"force_history_{case}.png"
            plot_histories(history, case, out / name)
            plots.append((name, f"Tooth contact forces, {case} at {history_rpm} rpm"))
    limits = [(139.0, "--", "plastic damage 139 N"), (146.0, ":", "fracture 146 N")]
    cases = [c for c in CASES if any(k[0] == c for k in a["table"])]
    for key, ylabel, name, caption, extra, shown in [
            ("peak_normal_N", "peak normal tooth force [N]", "peak_forces.png",
             "Peak normal tooth force against drum speed",
             {"band": (MEASURED_FORCE_N, "measured threshing force"), "lines": limits}, cases),
            ("knead_N", "peak tangential tooth force [N]", "knead_force.png",
             "Knead force (peak tangential tooth force) against drum speed", {}, cases),
            ("damaged", "fraction of kernels damaged", "damage_fraction.png",
             "Damage fraction (largest contact force >= 139 N) against drum speed", {}, cases),
            ("detached", "fraction of kernels detached", "detachment_fraction.png",
             "Detachment fraction against drum speed", {},
             [c for c in cases if c != "knead"]),  # the knead kernel has no pedicel
            ("subs_per_macro", "sub-collisions per macro-collision", "sub_collisions.png",
             "Sub-collisions per tooth macro-collision against drum speed", {}, cases)]:
        plot_against_speed(a["table"], shown, key, ylabel, out / name, **extra)
        plots.append((name, caption))
    plot_campbell(freqs, rpms, out / "campbell.png")
    plots.append(("campbell.png", "Campbell diagram of the teeth"))
    return plots


# ------------------------------------------------------------------------------------------
# Report and findings.

def fmt(value):
    if isinstance(value, float) and math.isnan(value):
        return "-"
    return f"{value:.3g}"


def fmt_range(pair):
    return f"{fmt(pair[0])}-{fmt(pair[1])}"


def markdown_table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def speed_table(by_variant, key):
    """Variants as rows, speeds as columns."""
    rpms = sorted({r for by_rpm in by_variant.values() for r in by_rpm})
    rows = [[v] + [fmt(by_variant[v][r][key]) if r in by_variant[v] else "-" for r in rpms]
            for v in VARIANTS if v in by_variant]
    return markdown_table(["tooth"] + [f"{r} rpm" for r in rpms], rows)


def strike_table(a):
    rows = []
    for (variant, rpm), s in sorted(a["strike"].items(),
                                    key=lambda item: (VARIANTS.index(item[0][0]), item[0][1])):
        in_band = MEASURED_FORCE_N[0] <= s["peak_N"] <= MEASURED_FORCE_N[1]
        rows.append([variant, rpm, fmt(s["speed_mps"]), fmt(s["peak_N"]),
                     "yes" if in_band else "no", fmt(s["contact_us"])])
    return markdown_table(["tooth", "rpm", "impact speed [m/s]", "peak normal force [N]",
                           "in 43.9-71.9 N", "first contact [us]"], rows)


def write_report(out, a, n_runs, rpms, plots):
    lines = ["# Tooth comparison", "",
             f"{n_runs} simulations: cases {', '.join(CASES)}; teeth {', '.join(VARIANTS)}; "
             f"drum speeds {', '.join(str(r) for r in rpms)} rpm; controls with frozen teeth "
             f"on {', '.join(FROZEN_CASES)}. Force peaks from the core at every accepted step; "
             f"force histories sampled every {fmt(a['sample_us'])} us near contacts. Generated by "
             "scripts/compare_teeth.py.", ""]
    for name, caption in plots:
        lines += [f"## {caption}", "", f"![{caption}]({name})", ""]
    columns = [("peak_normal_N", "Peak normal tooth force [N]"),
               ("knead_N", "Peak tangential tooth force (knead) [N]"),
               ("max_contact_N", "Largest contact force on a kernel [N]"),
               ("subs_per_macro", "Sub-collisions per tooth macro-collision"),
               ("damaged", "Fraction of kernels damaged"),
               ("detached", "Fraction of kernels detached")]
    for case in CASES:
        by_variant = {v: by_rpm for (c, v), by_rpm in a["table"].items() if c == case}
        if not by_variant:
            continue
        lines += [f"## Scene {case}", ""]
        for key, caption in columns:
            lines += [f"{caption}:", "", speed_table(by_variant, key), ""]
        still = {v: by_rpm for (c, v), by_rpm in a["frozen"].items() if c == case}
        if still:
            for key, caption in columns[:4]:
                lines += [f"{caption}, teeth frozen (no modes):", "", speed_table(still, key),
                          ""]
    lines += ["## Single strike: threshing force and contact time", "", strike_table(a), ""]
    (out / "report.md").write_text("\n".join(lines))


def peaks_numbers(a):
    """Claim 1 numbers: the verdict, totals over every case and tooth, and which cases show
    separated peaks in nearly every contact or in none."""
    sep = {k: s for k, s in a["separation"].items() if s["n"]}
    total = sum(s["n"] for s in sep.values())
    separated = sum(s["separated"] for s in sep.values())
    share = separated / total if total else float("nan")
    together = total - separated
    return {
        "total": total, "separated": separated, "share": share, "together": together,
        "at_transition": sum(s["separated_at_transition"] for s in sep.values()),
        "together_sliding": sum(s["together_sliding"] for s in sep.values()),
        "verdict": ("holds" if share > 0.9 else "holds in part" if share > 0.1 else
                    "does not hold"),
        "mostly": [f"{c}/{v}" for (c, v), s in sep.items() if s["separated"] >= 0.9 * s["n"]],
        "never": [f"{c}/{v}" for (c, v), s in sep.items() if s["separated"] == 0],
        "widest": max(((s["median_us"], f"{c}/{v}") for (c, v), s in sep.items()),
                      default=(float("nan"), "-"))}


def claim_peaks(a):
    """Claim 1 verdict and text."""
    sep = a["separation"]
    rows = []
    for case in CASES:
        for v in VARIANTS:
            s = sep.get((case, v))
            if s and s["n"]:
                rows.append([case, v, s["n"], f"{fmt(100 * s['separated'] / s['n'])} %",
                             s["separated_at_transition"], s["n"] - s["separated"],
                             s["together_sliding"], fmt(s["median_us"])])
    p = peaks_numbers(a)
    text = (f"Time between the peak tangential and the peak normal tooth force on each kernel a "
            f"tooth touched (the core's peaks, at every accepted step and event); separated "
            f"means more than {fmt(a['threshold_us'])} us apart (two sampling intervals: "
            "simulate stops the integrator at every sample near a tooth, so its steps there are "
            f"no longer). Separated in {p['separated']} of {p['total']} kernel contacts "
            f"({fmt(100 * p['share'])} %); in {p['at_transition']} of those {p['separated']} the "
            "tangential peak falls on a stick-slip transition of the contact (same accepted "
            f"step). Of the {p['together']} contacts whose peaks coincide, "
            f"{p['together_sliding']} slide at the normal peak.\n\n"
            + markdown_table(["case", "tooth", "kernels touched", "separated",
                              "separated, tangential peak at stick-slip", "together",
                              "together, sliding at normal peak",
                              "median abs time between peaks [us]"], rows)
            + f"\n\nThe widest median separation: {p['widest'][1]}, {fmt(p['widest'][0])} us. "
            "Where the peaks part, the contact sticks while the normal force rises and the "
            "tangential force peaks at a stick-slip transition (the friction force is largest "
            "where it reaches mu N), or the largest tangential and the largest normal force "
            "belong to different contact episodes. Where they coincide at every speed ("
            + (", ".join(p["never"]) or "nowhere") + "), the contact slides through its force "
            "peak: a sliding Coulomb contact carries tangential force mu N, so both peak at the "
            "same instant.")
    return p["verdict"], text


def claim_subs(a):
    """Claim 2 verdict and text."""
    subs = a["subs"]
    rows = []
    for case in CASES:
        if (case, "rigid") not in subs:
            continue
        row = [case, fmt(subs[(case, "rigid")]["mean"])]
        for v in FLEXIBLE:
            s = subs.get((case, v))
            if not s:
                row.append("-")
                continue
            control = f", {s['by_bending']} by bending" if case in FROZEN_CASES else ""
            row.append(f"{fmt(s['mean'])} (more {s['more']}/{s['n']}, fewer {s['fewer']}/"
                       f"{s['n']}{control})")
        rows.append(row)
    flexible = [s for (c, v), s in subs.items() if v != "rigid"]
    more = sum(s["more"] for s in flexible)
    fewer = sum(s["fewer"] for s in flexible)
    by_bending = sum(s["by_bending"] for s in flexible)
    rigid_several = [c for (c, v), s in subs.items() if v == "rigid" and s["rigid_max"] > 1]
    bending = [f"{c}/{v}" for (c, v), s in subs.items() if s["by_bending"] > 0]
    uncontrolled = [f"{c}/{v} ({s['more']} of {s['n']} speeds)" for (c, v), s in subs.items()
                    if c not in FROZEN_CASES and v != "rigid" and s["more"] > s["fewer"]]
    verdict = ("holds" if more > fewer and not rigid_several else
               "holds in part" if by_bending > 0 else "does not hold")
    text = ("Mean sub-collisions per tooth macro-collision over the speeds (macro-collision: the "
            "contact episodes of one tooth-kernel pair less than `macro_collision_gap`, 2 ms, "
            "apart; each episode is a sub-collision). In brackets: at how many speeds the "
            "flexible tooth has more or fewer than the rigid tooth, and at how many it has more "
            "than both the rigid tooth and itself frozen (no bending modes, same material and "
            "contact), i.e. extra sub-collisions caused by its bending.\n\n"
            + markdown_table(["case", "rigid"] + FLEXIBLE, rows)
            + f"\n\nOver all cases and speeds a flexible tooth had more sub-collisions per "
            f"macro-collision than the rigid tooth {more} times and fewer {fewer} times; "
            f"{by_bending} of those excesses are caused by bending (the frozen tooth has fewer). "
            "The rigid tooth produces several sub-collisions in "
            + (", ".join(rigid_several) or "no case")
            + ": there the kernel is thrown back onto the tooth by the concave bar, by its "
            "pedicel or by its own spin after an off-centre hit, with or without bending. "
            "Sub-collisions caused by bending (more than both the rigid and the frozen tooth at "
            "some speed): " + (", ".join(bending) or "none") + ". More often than the rigid "
            "tooth where no frozen control was run, so that bending and the kernels' own "
            "rebounds cannot be told apart: " + (", ".join(uncontrolled) or "none")
            + ". Where the compliant contact "
            "holds on through the tooth's vibration, the vibration shows as ripples on the "
            "force of one contact episode (see the knead force history) rather than as "
            "separate episodes.")
    return verdict, text


def claim_knead(a):
    """Claim 3 verdict and text."""
    k = a["knead"]
    rows = [[v, fmt_range(k[v]["to_rigid"]), fmt_range(k[v]["frozen_to_rigid"]),
             fmt_range(k[v]["to_frozen"])] for v in FLEXIBLE if v in k]
    below = [v for v in FLEXIBLE if v in k and k[v]["to_rigid"][1] < 1.0]
    verdict = ("holds" if len(below) == len(k) else "holds in part" if below else
               "does not hold")
    text = ("Knead force: the peak tangential tooth force on the knead scene (kernel pressed "
            "between the tooth and a concave bar). Ranges over the drum speeds of the ratio of "
            "the flexible tooth to the rigid steel tooth, of the same tooth frozen (no bending) "
            "to the rigid tooth, and of the flexible tooth to itself frozen:\n\n"
            + markdown_table(["tooth", "flexible / rigid", "frozen / rigid",
                              "flexible / frozen"], rows)
            + f"\n\nBelow the rigid tooth at every speed: {', '.join(below) or 'none'}. Two "
            "causes separate: the contact material (frozen / rigid: the soft polyurethane "
            "contact alone cuts the force) and the bending (flexible / frozen below 1: the "
            "tooth gives way to the wedged kernel).")
    return verdict, text


def damage_table(a):
    """Per case and tooth: mean damaged and detached fractions over the speeds, and the speeds
    with any damage."""
    rows = []
    for case in CASES:
        for v in VARIANTS:
            by_rpm = a["table"].get((case, v))
            if not by_rpm:
                continue
            damaged = [r for r, m in sorted(by_rpm.items()) if m["damaged"] > 0]
            rows.append([case, v, fmt(nan_mean([m["damaged"] for m in by_rpm.values()])),
                         ", ".join(str(r) for r in damaged) or "none",
                         fmt(nan_mean([m["detached"] for m in by_rpm.values()]))])
    return markdown_table(["case", "tooth", "damaged (mean fraction)", "speeds with damage [rpm]",
                           "detached (mean fraction)"], rows)


def agreement_paragraph(a):
    """Single strike: peak normal force against the measured threshing force, its growth with
    the impact speed, and the first contact's duration against the Hertz estimate."""
    strike = a["strike"]
    in_band = [k for k, s in strike.items()
               if MEASURED_FORCE_N[0] <= s["peak_N"] <= MEASURED_FORCE_N[1]]
    band_rpms = sorted({rpm for (v, rpm) in in_band if v == "rigid"})
    # Contact times at the speeds of the Hertz estimate: stiff teeth (the kernel's modulus
    # dominates the contact) apart from the soft polyurethane.
    in_range = {k: s for k, s in strike.items()
                if HERTZ_SPEED_MPS[0] <= s["speed_mps"] <= HERTZ_SPEED_MPS[1]}
    stiff = [s["contact_us"] for (v, _), s in in_range.items() if v != "polyurethane"]
    soft = [s["contact_us"] for (v, _), s in in_range.items() if v == "polyurethane"]
    # Force against impact speed, rigid tooth: the log-log slope (Hertz: 6/5).
    rigid = [(s["speed_mps"], s["peak_N"]) for (v, _), s in strike.items() if v == "rigid"]
    exponent = (float(np.polyfit(np.log([p[0] for p in rigid]), np.log([p[1] for p in rigid]),
                                 1)[0]) if len(rigid) > 1 else float("nan"))
    return (
        f"Single strike: {len(in_band)} of {len(strike)} runs give a peak normal force within "
        f"the measured threshing force {MEASURED_FORCE_N[0]}-{MEASURED_FORCE_N[1]} N, the "
        f"rigid tooth at {', '.join(str(r) for r in band_rpms) or 'no speed'}"
        + (" rpm" if band_rpms else "") + ". For the "
        f"rigid tooth the peak force grows as the impact speed to the power {fmt(exponent)} "
        "(log-log fit; Hertz: 1.2). At impact speeds of "
        f"{HERTZ_SPEED_MPS[0]:g}-{HERTZ_SPEED_MPS[1]:g} m/s the first contact lasted "
        f"{fmt(min(stiff, default=float('nan')))}-{fmt(max(stiff, default=float('nan')))} us "
        "for the rigid, steel and nylon teeth, whose contact modulus the kernel dominates, "
        f"against the Hertz estimate {HERTZ_TIME_US[0]:g}-{HERTZ_TIME_US[1]:g} us of docs/model.md "
        f"§9a; {fmt(min(soft, default=float('nan')))}-"
        f"{fmt(max(soft, default=float('nan')))} us for the soft polyurethane, whose low "
        "modulus lengthens the contact and lowers its force.")


def rotation_paragraph(history_rpm):
    return (f"The teeth's sections now turn as shear-flexible ones (`teeth.*.section_rotation: "
            f"shear_corrected`, docs/model.md §9b), no longer with the Euler-Bernoulli slope, "
            f"whose high modes kept the stick forces from converging in the mode count. At "
            f"{history_rpm} rpm, the peak tooth forces of the single strikes and the knead with "
            f"each (both at the automatic mode count; the rigid tooth has no sections to turn), "
            f"and the knead force over the rigid tooth's:")


def rotation_table(a, history_rpm):
    """Peak forces with the shear-corrected and the Euler-Bernoulli sections."""
    rows = []
    for case in FROZEN_CASES:
        for v in FLEXIBLE:
            before = a["euler"].get((case, v))
            if before is None:
                continue
            now = a["table"][(case, v)][history_rpm]
            rigid = a["table"][(case, "rigid")][history_rpm]["knead_N"]
            rows.append([case, v,
                         f"{fmt(now['peak_normal_N'])} / {fmt(before['peak_normal_N'])}",
                         f"{fmt(now['knead_N'])} / {fmt(before['knead_N'])}",
                         f"{fmt(now['knead_N'] / rigid)} / {fmt(before['knead_N'] / rigid)}"])
    return markdown_table(["case", "tooth", "peak normal [N], shear-corrected / Euler-Bernoulli",
                           "peak tangential [N], shear-corrected / Euler-Bernoulli",
                           "tangential / rigid tooth's, shear-corrected / Euler-Bernoulli"], rows)


def rod_cases():
    """The cases whose soft teeth are rods, in words."""
    return ", ".join(f"the {case} with the {' and '.join(v)} "
                     f"{'teeth' if len(v) > 1 else 'tooth'}"
                     for case, v in LARGE_DEFLECTION.items())


def invalid_runs(a):
    """(case, tooth, rpm, tip / L) of the sweep's modal runs past the small-deflection range."""
    return [(case, v, rpm, m["tip"]) for (case, v), by_rpm in sorted(a["table"].items())
            for rpm, m in sorted(by_rpm.items()) if not m["rod"] and m["tip"] > VALIDITY_FRACTION]


def rod_paragraph(a, history_rpm):
    beyond = invalid_runs(a)
    check = ("No modal run of the sweep leaves the range." if not beyond else
             "Modal runs of the sweep past it (add them to `LARGE_DEFLECTION`): " +
             "; ".join(f"{c} {v} {r} rpm ({fmt(t)} L)" for c, v, r, t in beyond) + ".")
    return (f"The modal tooth is a small-deflection beam, valid to a tip deflection of "
            f"{VALIDITY_FRACTION:g} L (the core warns past it). Where it bends further at some "
            f"speed, the tooth is the geometrically exact large-deflection rod "
            f"(`config/scenes/cases/large_deflection.yaml`, docs/large_deflection.md; its "
            f"automatic count of shape functions): {rod_cases()}. {check} The same cases at "
            f"{history_rpm} rpm with the modal tooth against the rod (largest tip deflection "
            f"over L; the stream is chaotic, its maxima compare one seed's kernels):")


def rod_table(a, history_rpm):
    """Peak forces and tip deflection of the rod runs and their modal reruns."""
    rows = []
    for (case, v), before in sorted(a["modal"].items()):
        now = a["table"].get((case, v), {}).get(history_rpm)
        if now is None:
            continue
        rows.append([case, v, f"{fmt(now['peak_normal_N'])} / {fmt(before['peak_normal_N'])}",
                     f"{fmt(now['knead_N'])} / {fmt(before['knead_N'])}",
                     f"{fmt(now['tip'])} / {fmt(before['tip'])}"])
    return markdown_table(["case", "tooth", "peak normal [N], rod / modal",
                           "peak tangential [N], rod / modal", "tip deflection / L, rod / modal"],
                          rows)


def write_findings(path, a, plots, rpms, history_rpm):
    convergence = (markdown_table(
        ["tooth"] + [f"{m} modes" for m in CONVERGENCE_MODES],
        [[v] + [" / ".join(fmt(x) for x in a["convergence"][(v, m)]) for m in CONVERGENCE_MODES]
         for v in FLEXIBLE if (v, CONVERGENCE_MODES[0]) in a["convergence"]])
        if a["convergence"] else "Not run (--quick).")
    claims = [("Normal and tangential force peaks are not simultaneous", *claim_peaks(a)),
              ("Many sub-collisions per macro-collision from the tooth's vibration",
               *claim_subs(a)),
              ("A flexible tooth kneads with less force than a rigid one", *claim_knead(a))]
    lines = [
        "# Findings: the paper's three claims in this model", "",
        "Generated by `scripts/compare_teeth.py --findings`: every number on this page comes "
        "from that command (rerun it to regenerate the page and its plots). Cases: "
        "`config/scenes/{single_strike,knead,stream}.yaml` and the single strike with "
        "`config/scenes/cases/tip_strike.yaml`; teeth: `config/scenes/teeth/{rigid,"
        "spring_steel,nylon,polyurethane}.yaml` (values and sources in the files); drum "
        f"speeds {rpms[0]}-{rpms[-1]} rpm; {rod_cases()} as large-deflection rods (below); "
        "force peaks and their times from the core at every "
        "accepted step, at located maxima of the compliant normal forces and on both sides of "
        "every located event (steps near a tooth at most "
        f"{fmt(a['sample_us'])} us); force histories sampled every {fmt(a['sample_us'])} us near "
        "contacts; all contacts compliant (Hertz with Hunt-Crossley damping, Coulomb "
        "friction), integrated event-driven. The stream is one seed of a chaotic process (its "
        "kernels hit each other and the bars), so its numbers scatter from speed to speed: read "
        "them as trends. " + partial_paragraph(), "",
        "| claim | verdict |", "|---|---|"]
    lines += [f"| {title} | {verdict} |" for title, verdict, _ in claims]
    lines.append("")
    for i, (title, verdict, text) in enumerate(claims, 1):
        lines += [f"## Claim {i}: {title}: {verdict}", "", text, ""]
    lines += [
        "## Threshing force and Hertz contact time", "",
        agreement_paragraph(a), "",
        strike_table(a), "",
        "## Damage and detachment", "",
        "A kernel is damaged when the largest normal force of any of its contacts reaches the "
        "plastic threshold (139 N; fracture 146 N). The knead kernel has no pedicel.", "",
        damage_table(a), "",
        "## Large deflection: where the tooth is a rod", "",
        rod_paragraph(a, history_rpm), "",
        rod_table(a, history_rpm), "",
        "## What the shear-corrected sections changed", "",
        rotation_paragraph(history_rpm), "",
        rotation_table(a, history_rpm), "",
        "## Modal convergence", "",
        f"Single strike at {history_rpm} rpm with 2 to 10 bending modes: peak normal force "
        "[N] / first contact [us] / sub-collisions per macro-collision. The scenes choose the "
        "count automatically (`modes: auto`) and carry the static correction of the truncated "
        "modes; their mode convergence is in [convergence.md](convergence.md).", "",
        convergence, "", "## Plots", ""]
    for name, caption in plots:
        lines += [f"### {caption}", "", f"![{caption}](findings/{name})", ""]
    path.write_text("\n".join(lines))


# ------------------------------------------------------------------------------------------
# The findings section (docs/threshing_findings.md, between the findings markers).

# Key plots of the section: (file name, what it shows there).
README_PLOTS = [
    ("force_history_knead.png", "Claim 1: normal (blue) and tangential (red) tooth force on the "
     "kernel kneaded against the bar, each contact episode shaded"),
    ("sub_collisions.png", "Claim 2: sub-collisions per tooth macro-collision against drum "
     "speed"),
    ("knead_force.png", "Claim 3: knead force (peak tangential tooth force) against drum speed"),
    ("peak_forces.png", "Peak normal tooth force against drum speed, with the measured "
     "threshing force (band) and the damage thresholds")]


def duration(seconds):
    """A wall time for people: seconds below two minutes, else minutes."""
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


def rel(folder, name):
    """name inside folder, as a link ("findings.md" where folder is ".")."""
    return name if folder == "." else f"{folder}/{name}"


def readme_section(a, rpms, docs_rel, n_runs, jobs, wall_s):
    """Markdown of the findings section (between the markers); docs_rel: the folder of
    findings.md relative to the section's page."""
    verdicts = [("1. The peaks of the normal and the tangential force are not simultaneous",
                 claim_peaks(a)[0]),
                ("2. One macro-collision holds many sub-collisions, caused by the tooth's "
                 "high-frequency vibration", claim_subs(a)[0]),
                ("3. A flexible tooth gives a smaller knead force than a rigid one",
                 claim_knead(a)[0])]

    # Claim 1.
    p = peaks_numbers(a)
    claim1 = (
        f"**Claim 1 ({verdicts[0][1]}).** The two peaks lie more than "
        f"{fmt(a['threshold_us'])} us apart in {p['separated']} of {p['total']} tooth-kernel "
        f"contacts ({fmt(100 * p['share'])} %); in {p['at_transition']} of them the tangential "
        "peak falls on a stick-slip transition: the contact sticks while the normal force "
        "rises, and the friction force is largest where it reaches mu N. Apart in at least "
        f"90 % of the contacts: {', '.join(p['mostly']) or 'none'}. The widest median "
        f"separation is {fmt(p['widest'][0])} us ({p['widest'][1]}). Not apart in any contact: "
        f"{', '.join(p['never']) or 'none'}. Of all {p['together']} contacts whose peaks "
        f"coincide, {p['together_sliding']} slide at the normal peak, where Coulomb friction "
        "is mu N and peaks with N.")

    # Claim 2.
    subs = a["subs"]
    flexible = {k: s for k, s in subs.items() if k[1] != "rigid"}
    more = sum(s["more"] for s in flexible.values())
    fewer = sum(s["fewer"] for s in flexible.values())
    compared = sum(s["n"] for s in flexible.values())
    controlled = sum(s["n"] for (c, _), s in flexible.items() if c in FROZEN_CASES)
    by_bending = sum(s["by_bending"] for s in flexible.values())
    bending = [f"{c}/{v} ({s['by_bending']} of {s['n']} speeds)"
               for (c, v), s in flexible.items() if s["by_bending"] > 0]
    rigid = {c: s["mean"] for (c, v), s in subs.items() if v == "rigid"
             and not math.isnan(s["mean"])}
    rigid_several = [f"{c} {fmt(m)}" for c, m in rigid.items() if m > 1]
    claim2 = (
        f"**Claim 2 ({verdicts[1][1]}).** Against the rigid tooth at the same case and speed, "
        f"a flexible tooth had more sub-collisions per macro-collision {more} times and fewer "
        f"{fewer} times out of {compared}. Extra sub-collisions caused by bending (more than "
        "both the rigid tooth and the same tooth frozen, without bending modes) appear in "
        f"{by_bending} of {controlled} controlled comparisons: "
        f"{', '.join(bending) or 'none'}. The rigid tooth itself averages more than one "
        f"sub-collision per macro-collision in {', '.join(rigid_several) or 'no case'}: the "
        "bar, the pedicel or the kernel's own spin bring the kernel back onto the tooth "
        "without any vibration. Where the compliant contact lasts through the tooth's "
        "vibration, the vibration shows as ripples on one episode's force rather than as "
        "separate sub-collisions.")

    # Claim 3.
    k = a["knead"]
    ratios = ", ".join(f"{v} {fmt_range(k[v]['to_rigid'])}" for v in FLEXIBLE if v in k)
    frozen = ", ".join(f"{v} {fmt_range(k[v]['frozen_to_rigid'])}" for v in FLEXIBLE if v in k)
    bent = ", ".join(f"{v} {fmt_range(k[v]['to_frozen'])}" for v in FLEXIBLE if v in k)
    below = [v for v in FLEXIBLE if v in k and k[v]["to_rigid"][1] < 1.0]
    not_below = [v for v in FLEXIBLE if v in k and v not in below]
    claim3 = (
        f"**Claim 3 ({verdicts[2][1]}).** Knead force (peak tangential tooth force on the "
        "kernel wedged between the tooth and the concave bar, knead scene) of the flexible "
        f"tooth over the rigid one, {rpms[0]}-{rpms[-1]} rpm: {ratios or 'not run'}. Below the "
        f"rigid tooth at every speed: {', '.join(below) or 'none'}"
        + (f"; not at every speed: {', '.join(not_below)}" if not_below else "")
        + ". Two causes separate: the contact material (the "
        f"same tooth frozen over the rigid one: {frozen or '-'}) and the bending (flexible "
        f"over frozen: {bent or '-'}; below 1, the bending tooth gives way to the wedged "
        "kernel).")

    cases = [c for c in CASES if any(key[0] == c for key in a["table"])]
    teeth = [v for v in VARIANTS if any(key[1] == v for key in a["table"])]
    lines = [
        f"Generated by `scripts/compare_teeth.py --findings` from the built `simulate`: "
        f"{n_runs} simulations (cases {', '.join(cases)}; teeth {', '.join(teeth)}; "
        f"{rpms[0]}-{rpms[-1]} rpm; controls with frozen teeth; {rod_cases()} as "
        "large-deflection rods, where the modal tooth bends past 0.1 L), all contacts "
        "compliant, integrated event-driven. Force peaks and their "
        "times are the core's (every accepted step, the located maxima of compliant normal "
        "forces, and both sides of every located event). "
        f"This run took {duration(wall_s)} on {jobs} workers. The full report, with every "
        f"table and plot, is [`{rel(docs_rel, 'findings.md')}`]({rel(docs_rel, 'findings.md')}).",
        "",
        "```bash",
        "bash scripts/setup.sh                              # build",
        "/usr/bin/python3 scripts/compare_teeth.py --findings  "
        "# rewrites this section, docs/findings.md, docs/findings/*.png",
        "```", "",
        "| claim (Qian, Jin & Zhang 2017) | in this model |", "|---|---|"]
    lines += [f"| {title} | {verdict} |" for title, verdict in verdicts]
    lines += ["", claim1, "", claim2, "", claim3, "",
              "**Threshing force and contact time.** " + agreement_paragraph(a), ""]
    for name, caption in README_PLOTS:
        lines += [f"![{name}]({rel(docs_rel, 'findings/' + name)})", "", f"*{caption}.*", ""]
    return "\n".join(lines).rstrip("\n")


def write_summary(page, docs, a, rpms, n_runs, jobs, wall_s):
    """Rewrites the findings section of page (default: its page, docs/threshing_findings.md),
    with links to docs (the folder of findings.md) relative to the page; returns the page."""
    page = pathlib.Path(page) if page else markdown.page_of("findings")
    docs_rel = os.path.relpath(pathlib.Path(docs).resolve(), page.resolve().parent)
    return markdown.splice("findings", readme_section(a, rpms, docs_rel, n_runs, jobs, wall_s),
                           page)


# ------------------------------------------------------------------------------------------


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--simulate", help="path of the built simulate binary "
                        "(default: .build/ws/devel/lib/threshing_sim/simulate)")
    parser.add_argument("--out", default=str(ROOT / "out/compare"),
                        help="output folder (default: out/compare)")
    parser.add_argument("--rpm", type=int, nargs="+", help="drum speeds [rpm] "
                        f"(default {RPM_FULL[0]}-{RPM_FULL[-1]} by 100; --quick: {RPM_QUICK})")
    parser.add_argument("--jobs", type=int, default=os.cpu_count(),
                        help="parallel simulations (default: the number of cores)")
    parser.add_argument("--quick", action="store_true",
                        help="tiny sweep: rigid and polyurethane teeth, two speeds, a "
                        "two-kernel stream, no convergence check")
    parser.add_argument("--findings", action="store_true",
                        help="also write docs/findings.md, docs/findings/*.png and the "
                        "findings section of docs/threshing_findings.md")
    parser.add_argument("--docs", default=str(ROOT / "docs"),
                        help="folder of findings.md and findings/ (default: docs)")
    parser.add_argument("--summary", "--readme", dest="summary",
                        help="page whose findings section --findings rewrites "
                        "(default: docs/threshing_findings.md)")
    parser.add_argument("--reuse", action="store_true",
                        help="keep the runs already in OUT/runs and run only the missing ones "
                        "(to redo the report; the default reruns everything)")
    args = parser.parse_args()

    simulate = find_binary("simulate", args.simulate)
    out = pathlib.Path(args.out)
    rpms = sorted(args.rpm or (RPM_QUICK if args.quick else RPM_FULL))
    variants = ["rigid", "polyurethane"] if args.quick else VARIANTS
    history_rpm = HISTORY_RPM if HISTORY_RPM in rpms else rpms[0]
    if not args.reuse:
        shutil.rmtree(out / "runs", ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)

    # The sweep, the frozen-tooth controls and the modal convergence check.
    runs = [Run(out, "sweep", c, v, r, forces=r == history_rpm, quick=args.quick)
            for c in CASES for v in variants for r in rpms]
    runs += [Run(out, "frozen", c, v, r, modes=0)
             for c in FROZEN_CASES for v in variants if v != "rigid" for r in rpms]
    if not args.quick:
        runs += [Run(out, "convergence", "single_strike", v, history_rpm, modes=m)
                 for v in FLEXIBLE for m in CONVERGENCE_MODES]
        runs += [Run(out, "euler_bernoulli", c, v, history_rpm, rotation="euler_bernoulli")
                 for c in FROZEN_CASES for v in FLEXIBLE]
        runs += [Run(out, "modal", c, v, history_rpm, model="modal")
                 for c, teeth in LARGE_DEFLECTION.items() for v in teeth]
    print(f"compare_teeth: {len(runs)} simulations on {args.jobs} workers -> {out}", flush=True)
    started = time.monotonic()
    run_all(runs, simulate, args.jobs, args.reuse)
    wall_s = time.monotonic() - started
    freqs = {v: tooth_frequencies(simulate, v, rpms) for v in variants if v != "rigid"}

    # Numbers, plots, report, findings.
    sample_us = 1e6 * runs[0].summary()["outcomes"]["sample_interval_s"]
    a = analyse(runs, sample_us)
    plots = make_plots(out, runs, a, freqs, rpms, history_rpm)
    write_report(out, a, len(runs), rpms, plots)
    print(f"compare_teeth: wrote {out / 'report.md'} and {len(plots)} plots")
    if args.findings:
        docs = pathlib.Path(args.docs)
        figures = docs / "findings"
        figures.mkdir(parents=True, exist_ok=True)
        for name, _ in plots:
            shutil.copy(out / name, figures / name)
        write_findings(docs / "findings.md", a, plots, rpms, history_rpm)
        page = write_summary(args.summary, docs, a, rpms, len(runs), args.jobs, wall_s)
        print(f"compare_teeth: wrote {docs / 'findings.md'}, {figures}/ and the findings "
              f"section of {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
