"""scripts/stability_table.py's command line: the runs of every scene and integrator, --save
and --render."""
import argparse
import json
import os
import sys
import time

import yaml

from tslib import ROOT, schema
from tslib.binaries import find_binary
from tslib.stability.page import fmt_duration, write_document
from tslib.stability.runs import evaluate, run_simulate, without_wall_time
from tslib.stability.scenes import HARD_DIR, HARD_SCENES, INTEGRATORS


# ---------------------------------------------------------------------------------------------
# Main.

def parse_args():
    parser = argparse.ArgumentParser(
        description="Run the long versions of the hard cases and write the stability table.")
    parser.add_argument("--simulate", help="path of the simulate binary (default: "
                        "$THRESHING_SIM_SIMULATE, PATH, catkin_find)")
    parser.add_argument("--scenes", nargs="+", metavar="NN",
                        help="scene numbers to run (default: all), e.g. 01 10")
    parser.add_argument("--integrators", nargs="+", choices=INTEGRATORS, default=list(INTEGRATORS))
    parser.add_argument("--scale", type=float, default=1.0,
                        help="multiply every long duration by this (e.g. 0.01 for a quick look)")
    parser.add_argument("--full", action="store_true",
                        help="run every scene's full long duration (scene 10: 10 000 revolutions "
                        "instead of 300, 33 times as long)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="an extra scene override for every run, e.g. "
                        "teeth.0.model=large_deflection (with --scenes of scenes that have it)")
    parser.add_argument("--output", help="write the markdown document here (default: stdout)")
    parser.add_argument("--save", metavar="FILE.json",
                        help="also write the results (rows, notes, command) as JSON")
    parser.add_argument("--summary", "--readme", dest="readme", metavar="PAGE.md",
                        help="also replace the table between the <!-- MARKER --> and "
                        "<!-- MARKER-end --> lines of this page "
                        "(docs/numerical_stability.md)")
    parser.add_argument("--marker", default="stability-table",
                        help="the markers' name (default: stability-table)")
    parser.add_argument("--render", metavar="FILE.json", nargs="+",
                        help="run nothing: write the document from results saved by --save "
                        "(several files, e.g. two integrators run in parallel, are joined in "
                        "the order given)")
    args = parser.parse_args()
    if not args.scale > 0:
        parser.error("--scale must be > 0")
    return parser, args


def render_saved(args):
    """--render: the document from results saved by --save (joined in the order given)."""
    commands, rows, notes, all_ok, wall_s = [], [], [], True, 0.0
    for path in args.render:
        with open(path) as f:
            saved = json.load(f)
        commands.append(saved["command"])
        rows += [tuple(r) for r in saved["rows"]]
        notes += [n for n in saved["notes"] if n not in notes]
        all_ok = all_ok and saved["all_ok"]
        wall_s = max(wall_s, saved.get("wall_s", 0.0))  # the runs went side by side
    write_document("\n    ".join(commands), rows, notes, args.output, wall_s, args.readme,
                   args.marker)
    return 0 if all_ok else 1


def run_row(simulate, scene, doc, integrator, args):
    """One scene under one integrator: its long run, two short reruns for determinism, the
    properties checked (printed) and the table row. Returns (row, all properties passed)."""
    duration = scene.duration_s * args.scale
    if scene.quick_duration_s and not args.full:
        duration = scene.quick_duration_s * args.scale
    print("scene %s %s: %g s ..." % (scene.key, integrator, duration),
          file=sys.stderr, flush=True)
    code, summary, wall, memory, stderr = run_simulate(simulate, scene, integrator, duration)
    short = min(duration / 10, 10.0)
    _, first, _, _, _ = run_simulate(simulate, scene, integrator, short)
    _, second, _, _, _ = run_simulate(simulate, scene, integrator, short)
    rerun_same = (first is not None and second is not None
                  and without_wall_time(first) == without_wall_time(second))
    props = evaluate(scene, doc, integrator, duration, code, summary, memory, rerun_same)
    failed = [p for p in props if not p[1]]
    passed = "%d/%d" % (len(props) - len(failed), len(props))
    if failed:
        passed += ": FAILED " + "; ".join("%s (%s)" % (n, d) for n, _, d in failed)
    for name, ok, detail in props:
        print("  %-16s %s  %s" % (name, "ok  " if ok else "FAIL", detail), file=sys.stderr)
    if stderr:
        print("  stderr: " + stderr[-500:], file=sys.stderr)
    title = "%s %s" % (scene.key, scene.title)
    if summary is None:
        return (title, integrator, fmt_duration(duration), passed, "-", "-", "-",
                "%.1f" % wall), not failed
    gain = max(summary["max_energy_gain_at_impact_J"],
               summary["energy_final_J"] - summary["energy_initial_J"]
               - summary["drive_work_J"])
    return (title, integrator, fmt_duration(summary["sim_time_s"]), passed, "%.2e" % gain,
            "%.2e" % summary["max_penetration_m"],
            "%.3g" % (summary["steps"] / summary["sim_time_s"]), "%.1f" % wall), not failed


def shown_command(simulate):
    """The command as run, with a workspace-independent simulate path (--save and --render,
    which only keep or read a copy of the results, left out)."""
    shown, argv = [], sys.argv[1:]
    for i, a in enumerate(argv):
        if a == "--save" or (i > 0 and argv[i - 1] == "--save") or a.startswith("--save="):
            continue
        if a == "--render" or (i > 0 and argv[i - 1] == "--render"):
            continue
        if a == simulate and os.path.isabs(a):
            # The repository's own build as a relative path; another workspace's as WORKSPACE/.
            rel = os.path.relpath(a, ROOT)
            if not rel.startswith(".."):
                a = rel
            elif "/devel/lib/" in a:
                a = "WORKSPACE/devel/lib/" + a.split("/devel/lib/", 1)[1]
        shown.append(a if " " not in a else "'%s'" % a)
    return "scripts/stability_table.py " + " ".join(shown)


def main():
    parser, args = parse_args()
    if args.render:
        return render_saved(args)
    simulate = str(find_binary("simulate", args.simulate, search=True))
    schema.use(simulate)
    scenes = [s for s in HARD_SCENES if not args.scenes or s.key in args.scenes]
    if not scenes:
        parser.error("no scene matches %s" % args.scenes)
    for s in scenes:
        s.overrides += args.set

    rows, notes, all_ok = [], [], True
    started = time.monotonic()
    for scene in scenes:
        with open(os.path.join(HARD_DIR, scene.file)) as f:
            doc = yaml.safe_load(f)
        if scene.note and not (scene.quick_duration_s and args.full):
            notes.append("Scene %s: %s." % (scene.key, scene.note))
        for integrator in args.integrators:
            row, ok = run_row(simulate, scene, doc, integrator, args)
            rows.append(row)
            all_ok = all_ok and ok
    wall_s = time.monotonic() - started
    command = shown_command(simulate)
    if args.save:
        with open(args.save, "w") as f:
            json.dump({"command": command, "rows": rows, "notes": notes, "all_ok": all_ok,
                       "wall_s": wall_s}, f, indent=1)
    write_document(command, rows, notes, args.output, wall_s, args.readme, args.marker)
    return 0 if all_ok else 1
