#!/usr/bin/env python3
"""Median wall time of `simulate` on a scene for both integrators and the event-driven one's
contact phase (the README's figures).

Runs each integrator REPEAT times one after another on one core, reads wall_time_s from the
summary JSON (stepping loop only) and prints the median and the real-time factor, with the
kernel's exit speed and the peak normal and tangential contact forces of each integrator.
Usage: scripts/time_default_scene.py [--scene FILE] [--repeat N] [--simulate PATH]
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile

from tslib import ROOT
from tslib.binaries import BIN_DIR


def run_once(simulate, scene, extra, summary):
    subprocess.run([simulate, scene, "--quiet", "--summary", summary] + extra, check=True)
    with open(summary) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scene", default=os.path.join(ROOT, "config", "default_scene.yaml"))
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--simulate", default=str(BIN_DIR / "simulate"))
    args = ap.parse_args()
    settings = [("event_driven, tolerance 1e-6", ["--integrator", "event_driven", "--tolerance", "1e-6"]),
                ("time_stepping, dt 1e-6", ["--integrator", "time_stepping", "--dt", "1e-6"]),
                ("event_driven, contact phase 40 steps (opt-in)",
                 ["--integrator", "event_driven", "--tolerance", "1e-6",
                  "--set", "integrator.contact_steps=40"])]
    print(f"scene {os.path.relpath(args.scene, ROOT)}, median of {args.repeat} runs")
    print("| integrator | sim time [s] | steps | wall time [ms] | real-time factor | kernel exit speed [m/s] | peak normal force [N] | peak tangential force [N] |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        summary = os.path.join(tmp, "s.json")
        speeds, peaks = [], []
        for name, extra in settings:
            runs = [run_once(args.simulate, args.scene, extra, summary) for _ in range(args.repeat)]
            wall = statistics.median(r["wall_time_s"] for r in runs)
            r = runs[0]
            v = r["kernels"][0]["velocity_mps"] if r["kernels"] else [0, 0]
            speeds.append((v[0] ** 2 + v[1] ** 2) ** 0.5)
            peaks.append((r["peak_normal_force_N"], r["peak_tangential_force_N"]))
            print(f"| {name} | {r['sim_time_s']:.4g} | {r['steps']} | {1e3 * wall:.1f} | "
                  f"{r['sim_time_s'] / wall:.3g} | {(v[0] ** 2 + v[1] ** 2) ** 0.5:.4f} | "
                  f"{r['peak_normal_force_N']:.2f} | {r['peak_tangential_force_N']:.2f} |")
    if len(speeds) >= 2 and speeds[0] > 0:
        def rel(a, b):
            return f"{100 * abs(a - b) / b:.2g} %" if b > 0 else "n/a"
        print()
        print(f"The two integrators agree on the kernel's exit speed to "
              f"{rel(speeds[1], speeds[0])}, on the peak normal force to "
              f"{rel(peaks[1][0], peaks[0][0])} and on the peak tangential force to "
              f"{rel(peaks[1][1], peaks[0][1])}.")
        if len(speeds) == 3:
            print(f"The contact phase ([docs/contact_phase.md](docs/contact_phase.md)) agrees "
                  f"with the adaptive event-driven run on the exit speed to "
                  f"{rel(speeds[2], speeds[0])}, on the peak normal force to "
                  f"{rel(peaks[2][0], peaks[0][0])} and on the peak tangential force to "
                  f"{rel(peaks[2][1], peaks[0][1])}.")


if __name__ == "__main__":
    main()
