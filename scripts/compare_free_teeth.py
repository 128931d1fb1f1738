#!/usr/bin/env python3
"""Event-driven integration with and without exact propagation of free teeth, on one scene.

Runs bench_work_precision (the bare stepping loop, median of --reps runs in one process) with
`integrator.free_teeth=exact` and `=integrated` at one tolerance, and a reference run
(`integrated`, tolerance --ref-tolerance), and prints per variant: steps, rejected steps,
median wall time, real-time factor, and the errors against the reference of the kernels' exit
velocity, the tooth tip deflection history (--samples points; from a separate sampled run) and
the peak normal force. With --callgrind it also counts the instructions of the stepping loop
(valgrind callgrind, advanceTo only: stable on a shared machine where wall times are not) of one
run of each variant, over the whole run and up to --contact-start and --contact-end [s] (their
difference is the cost of the window between, e.g. a strike).
Usage: scripts/compare_free_teeth.py [--scene FILE] [--tolerance X] [--ref-tolerance X]
       [--reps R] [--samples N] [--cpu K] [--bench PATH]
       [--callgrind [--contact-start S --contact-end S]]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

from tslib import ROOT
from tslib.binaries import BIN_DIR
from tslib.callgrind import total_instructions
from tslib.numbers import exit_velocity_error


def run_point(bench, scene, free_teeth, tolerance, reps, samples, cpu):
    """One bench_work_precision point as a dict (its JSON output)."""
    cmd = [bench, scene, "--set", "integrator.type=event_driven",
           "--set", "integrator.free_teeth=" + free_teeth,
           "--set", "integrator.tolerance=%r" % tolerance,
           "--reps", str(reps), "--samples", str(samples)]
    if cpu >= 0:
        cmd += ["--cpu", str(cpu)]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    result = json.loads(out)
    if result["status"] != "ok" or not result["deterministic"]:
        sys.exit("compare_free_teeth: run failed or not deterministic: " + " ".join(cmd))
    return result


def stepping_instructions(bench, scene, free_teeth, tolerance, duration=None):
    """Instructions (callgrind Ir) of advanceTo in one bare run of bench_work_precision."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", "--toggle-collect=threshing_sim::advanceTo*",
               "--callgrind-out-file=" + out, bench, scene,
               "--set", "integrator.type=event_driven",
               "--set", "integrator.free_teeth=" + free_teeth,
               "--set", "integrator.tolerance=%r" % tolerance, "--reps", "1", "--samples", "0"]
        if duration is not None:
            cmd += ["--set", "duration=%r" % duration]
        subprocess.run(cmd, check=True, capture_output=True)
        total = total_instructions(out)
    if total is None:
        sys.exit("compare_free_teeth: no instruction count in the callgrind output")
    return total


def tip_error(run_, ref):
    """Largest tip deflection difference over teeth and samples, relative to the largest
    reference tip deflection."""
    worst, scale = 0.0, 0.0
    for tips, tips_ref in zip(run_["tip_deflection_m"], ref["tip_deflection_m"]):
        for w, wr in zip(tips, tips_ref):
            worst = max(worst, abs(w - wr))
            scale = max(scale, abs(wr))
    return worst / scale if scale > 0 else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=os.path.join(ROOT, "config", "default_scene.yaml"))
    ap.add_argument("--tolerance", type=float, default=1e-6)
    ap.add_argument("--ref-tolerance", type=float, default=1e-10)
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--cpu", type=int, default=-1)
    ap.add_argument("--callgrind", action="store_true")
    ap.add_argument("--contact-start", type=float, default=2.8e-4)
    ap.add_argument("--contact-end", type=float, default=5e-4)
    ap.add_argument("--bench", default=str(BIN_DIR / "bench_work_precision"))
    args = ap.parse_args()

    ref = run_point(args.bench, args.scene, "integrated", args.ref_tolerance, 1, args.samples, args.cpu)
    rows = []
    for free_teeth in ("integrated", "exact"):
        r = run_point(args.bench, args.scene, free_teeth, args.tolerance, args.reps, args.samples,
                args.cpu)
        rows.append((free_teeth, r))
    print("scene %s, event-driven tolerance %g; reference: integrated at %g (%d steps)" %
          (os.path.relpath(args.scene, ROOT), args.tolerance, args.ref_tolerance, ref["steps"]))
    print()
    print("| free teeth | steps | rejected | wall time [ms] | real-time factor "
          "| exit velocity error | tip history error | peak normal force error |")
    print("|---|---|---|---|---|---|---|---|")
    for name, r in rows:
        peak_err = abs(r["peak_normal_force_N"] - ref["peak_normal_force_N"]) / max(
            ref["peak_normal_force_N"], 1e-12)
        print("| %s | %d | %d | %.3g | %.3g | %.2g | %.2g | %.2g |" % (
            name, r["steps"], r["rejected_steps"], 1e3 * r["median_wall_s"],
            r["sim_time_s"] / r["median_wall_s"], exit_velocity_error(r, ref), tip_error(r, ref),
            peak_err))
    exact, integrated = rows[1][1], rows[0][1]
    print()
    print("exact against integrated at the same tolerance: exit velocity %.2g, tip history %.2g" %
          (exit_velocity_error(exact, integrated), tip_error(exact, integrated)))
    if args.callgrind:
        print()
        print("| free teeth | stepping Ir, whole run | up to %g s | up to %g s | between |" %
              (args.contact_start, args.contact_end))
        print("|---|---|---|---|---|")
        for name, _ in rows:
            total = stepping_instructions(args.bench, args.scene, name, args.tolerance)
            ir0 = stepping_instructions(args.bench, args.scene, name, args.tolerance,
                                        args.contact_start)
            ir1 = stepping_instructions(args.bench, args.scene, name, args.tolerance,
                                        args.contact_end)
            print("| %s | %.3g M | %.3g M | %.3g M | %.3g M |" %
                  (name, total / 1e6, ir0 / 1e6, ir1 / 1e6, (ir1 - ir0) / 1e6))


if __name__ == "__main__":
    main()
