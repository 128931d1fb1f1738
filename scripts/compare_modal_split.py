#!/usr/bin/python3
"""Event-driven integration with and without the Lawson split of the modal teeth in contact.

Runs `simulate` on each scene with `integrator.modal_split=none` and `=exact` at one tolerance,
under the global scheme and the island scheme, and a reference run (`none`, global scheme, at
--ref-tolerance), and prints per variant: steps (global plus island steps), rejected steps,
impacts, and the relative errors against the reference of the peak normal and tangential
forces, the total normal impulse and the kernels' exit velocities. With --callgrind it also
counts the instructions of the stepping loop (valgrind callgrind, advancePast only; stable on a
shared machine where wall times are not) of one run of each variant.

Usage: scripts/compare_modal_split.py [--scene FILE]... [--tolerance X] [--ref-tolerance X]
       [--duration S] [--callgrind] [--simulate PATH]
(default scenes: config/default_scene.yaml (4 modes), config/scenes/single_strike.yaml and
config/scenes/knead.yaml (modes: auto; a strike and a tooth pressed against a kernel on a bar);
needs valgrind for --callgrind)
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
from tslib.numbers import exit_velocity_error, rel_error


def options(split, islands, tolerance, duration):
    """simulate's options for one variant."""
    out = ["--integrator", "event_driven", "--tolerance", repr(tolerance),
           "--set", "integrator.modal_split=" + split,
           "--set", "integrator.islands=" + islands]
    if duration is not None:
        out += ["--duration", repr(duration)]
    return out


def run_setting(simulate, scene, opts):
    """One run's summary (simulate --summary)."""
    with tempfile.TemporaryDirectory() as tmp:
        summary = os.path.join(tmp, "summary.json")
        subprocess.run([simulate, scene, "--quiet", "--summary", summary] + opts, check=True,
                       capture_output=True)
        with open(summary) as f:
            result = json.load(f)
    if result["status"] != "ok":
        sys.exit("compare_modal_split: run failed: %s %s" % (scene, " ".join(opts)))
    return result


def advance_instructions(simulate, scene, opts):
    """Instructions (callgrind Ir) of advancePast (the stepping loop) in one run."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", "--toggle-collect=threshing_sim::advancePast*",
               "--callgrind-out-file=" + out, simulate, scene, "--quiet"] + opts
        subprocess.run(cmd, check=True, capture_output=True)
        total = total_instructions(out)
    if total is None:
        sys.exit("compare_modal_split: no instruction count in the callgrind output")
    return total


def steps(r):
    return r["steps"] + r.get("scheduler", {}).get("island_steps", 0)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", action="append")
    ap.add_argument("--tolerance", type=float, default=1e-6)
    ap.add_argument("--ref-tolerance", type=float, default=1e-10)
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--callgrind", action="store_true")
    ap.add_argument("--simulate", default=str(BIN_DIR / "simulate"))
    args = ap.parse_args()
    scenes = args.scene or [os.path.join(ROOT, "config", "default_scene.yaml"),
                            os.path.join(ROOT, "config", "scenes", "single_strike.yaml"),
                            os.path.join(ROOT, "config", "scenes", "knead.yaml")]

    print("event-driven, tolerance %g; reference: modal_split none, global scheme, tolerance %g"
          % (args.tolerance, args.ref_tolerance))
    print()
    head = ("| scene | islands | modal split | steps | rejected | impacts (ref) | peak normal "
            "| peak tangential | normal impulse | exit velocity |")
    if args.callgrind:
        head += " stepping Ir |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for scene in scenes:
        ref = run_setting(args.simulate, scene, options("none", "false", args.ref_tolerance,
                                                args.duration))
        for islands in ("false", "true"):
            for split in ("none", "exact"):
                opts = options(split, islands, args.tolerance, args.duration)
                r = run_setting(args.simulate, scene, opts)
                row = "| %s | %s | %s | %d | %d | %d (%d) | %.2g | %.2g | %.2g | %.2g |" % (
                    os.path.relpath(scene, ROOT), islands, split, steps(r), r["rejected_steps"],
                    r["impacts"], ref["impacts"],
                    rel_error(r["peak_normal_force_N"], ref["peak_normal_force_N"]),
                    rel_error(r["peak_tangential_force_N"], ref["peak_tangential_force_N"]),
                    rel_error(r["total_normal_impulse_Ns"], ref["total_normal_impulse_Ns"]),
                    exit_velocity_error(r, ref))
                if args.callgrind:
                    row += " %.4g M |" % (advance_instructions(args.simulate, scene, opts) / 1e6)
                print(row, flush=True)


if __name__ == "__main__":
    main()
