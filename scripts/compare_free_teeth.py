#!/usr/bin/env python3
"""Event-driven integration with and without exact propagation of free teeth, on one scene.

Runs bench_work_precision (the bare stepping loop, median of --reps runs in one process) with
`integrator.free_teeth=exact` and `=integrated` at one tolerance, and a reference run
(`integrated`, tolerance --ref-tolerance), and prints per variant: steps, rejected steps,
median wall time, real-time factor, and the errors against the reference of the kernels' exit
velocity, the tooth tip deflection history (--samples points; from a separate sampled run) and
the peak normal force.
Usage: scripts/compare_free_teeth.py [--scene FILE] [--tolerance X] [--ref-tolerance X]
       [--reps R] [--samples N] [--cpu K] [--bench PATH]
"""
import argparse
import json
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(bench, scene, free_teeth, tolerance, reps, samples, cpu):
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


def exit_velocity_error(run_, ref):
    """Largest velocity difference over the kernels, relative to the reference speed."""
    worst = 0.0
    for k, kr in zip(run_["kernels"], ref["kernels"]):
        dv = math.hypot(k["velocity_mps"][0] - kr["velocity_mps"][0],
                        k["velocity_mps"][1] - kr["velocity_mps"][1])
        worst = max(worst, dv / max(math.hypot(*kr["velocity_mps"]), 1e-12))
    return worst


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
    ap.add_argument("--bench", default=os.path.join(
        ROOT, ".build", "ws", "devel", "lib", "threshing_sim", "bench_work_precision"))
    args = ap.parse_args()

    ref = run(args.bench, args.scene, "integrated", args.ref_tolerance, 1, args.samples, args.cpu)
    rows = []
    for free_teeth in ("integrated", "exact"):
        r = run(args.bench, args.scene, free_teeth, args.tolerance, args.reps, args.samples,
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


if __name__ == "__main__":
    main()
