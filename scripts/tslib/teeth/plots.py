"""The tooth comparison's plots: force histories, quantities against drum speed, the Campbell
diagram."""

import csv

import numpy as np

from tslib import plots
from tslib.teeth.analysis import tooth_episodes, touched
from tslib.teeth.cases import (CASES, COLORS, HERTZ_TIME_US, MEASURED_FORCE_N, STYLES, VARIANTS,
                               damage_thresholds)


plt = plots.pyplot()

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
    # The core's damage thresholds (damage.plastic_force and fracture_force defaults).
    plastic, fracture = damage_thresholds()
    limits = [(plastic, "--", f"plastic damage {plastic:g} N"),
              (fracture, ":", f"fracture {fracture:g} N")]
    cases = [c for c in CASES if any(k[0] == c for k in a["table"])]
    for key, ylabel, name, caption, extra, shown in [
            ("peak_normal_N", "peak normal tooth force [N]", "peak_forces.png",
             "Peak normal tooth force against drum speed",
             {"band": (MEASURED_FORCE_N, "measured threshing force"), "lines": limits}, cases),
            ("knead_N", "peak tangential tooth force [N]", "knead_force.png",
             "Knead force (peak tangential tooth force) against drum speed", {}, cases),
            ("damaged", "fraction of kernels damaged", "damage_fraction.png",
             f"Damage fraction (largest contact force >= {plastic:g} N) against drum speed", {},
             cases),
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
