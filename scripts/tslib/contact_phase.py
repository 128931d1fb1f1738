"""The contact phase's report (issue 33): its work-precision table against the adaptive
event-driven reference on the bench scenes, and its cost (callgrind instructions of the stepping
loop, per contact event) against the adaptive step, both from `simulate` as a user runs it.

Accuracy: every scene runs once at tolerance 1e-10 with every step adaptive (the reference),
once adaptive at the scene's own tolerance (the default), and with the contact phase at
integrator.contact_steps 10, 20, 40 and 80 (its event-driven parts at the scene's tolerance).
Errors are relative to the reference: the kernels' exit velocity (the worst kernel, relative to
its speed), the total normal impulse, the peak normal and tangential forces, and the difference
of the completed-impact counts.

Cost: the instructions inside advancePast (valgrind callgrind, --toggle-collect) of one run,
per contact event (compliant episodes of the summary), and the real-time factor they give at
3e9 instructions per second; and the whole process's instructions (loading and the end
included) for the default strike.
"""
import json
import os
import subprocess
import tempfile

from tslib import ROOT
from tslib.bench.islands import INSTRUCTIONS_PER_S, kernel_file
from tslib.callgrind import total_instructions
from tslib.numbers import exit_velocity_error, fmt, rel_error

STEP_COUNTS = (10, 20, 40, 80)  # integrator.contact_steps of the work-precision sweep
DEFAULT_STEPS = 40              # the contract's step count

# (label, scene, extra simulate arguments) of the accuracy table.
ACCURACY_SCENES = [
    ("default strike", "config/default_scene.yaml", []),
    ("scenes single strike (20 modes)", "config/scenes/single_strike.yaml", []),
    ("long run, 8 ms (hard case 10)", "config/hard/10_long_run.yaml", ["--duration", "0.008"]),
    ("bench knead, polyurethane", "config/bench/knead_polyurethane.yaml", []),
    ("scenes knead (20 modes)", "config/scenes/knead.yaml", []),
]


def phase_summary(simulate, scene, args, workdir, tag):
    """The summary of one `simulate` run of scene (relative to the repository) with args."""
    out = os.path.join(workdir, f"{tag}.json")
    subprocess.run([str(simulate), str(ROOT / scene), "--quiet", "--summary", out] + args,
                   check=True, stdout=subprocess.DEVNULL, timeout=3600)
    with open(out) as f:
        return json.load(f)


def accuracy_row(label, run, ref, setting):
    """One row of the work-precision table."""
    return {"scene": label, "setting": setting, "status": run["status"], "steps": run["steps"],
            "exit_velocity": exit_velocity_error(run, ref),
            "impulse": rel_error(run["total_normal_impulse_Ns"], ref["total_normal_impulse_Ns"]),
            "peak_normal": rel_error(run["peak_normal_force_N"], ref["peak_normal_force_N"]),
            "peak_tangential": rel_error(run["peak_tangential_force_N"],
                                         ref["peak_tangential_force_N"]),
            "impacts": run["impacts"] - ref["impacts"]}


def accuracy(simulate, say, scenes=ACCURACY_SCENES, counts=STEP_COUNTS):
    """The work-precision rows of every scene: adaptive at its tolerance, then each step count."""
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for i, (label, scene, extra) in enumerate(scenes):
            say(f"contact phase: {label}")
            ref = phase_summary(simulate, scene, extra + ["--tolerance", "1e-10"], work, f"r{i}")
            adaptive = phase_summary(simulate, scene, extra, work, f"a{i}")
            rows.append(accuracy_row(label, adaptive, ref, "adaptive (scene tolerance)"))
            for n in counts:
                run = phase_summary(simulate, scene,
                                   extra + ["--set", f"integrator.contact_steps={n}"], work,
                                   f"c{i}_{n}")
                rows.append(accuracy_row(label, run, ref, f"contact phase, {n} steps"))
    return rows


def accuracy_table(rows):
    """The work-precision rows as a markdown table."""
    lines = ["| scene | setting | steps | exit velocity | impulse | peak normal | "
             "peak tangential | impacts ± |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['setting']} | {r['steps']} | "
                     f"{fmt(r['exit_velocity'])} | {fmt(r['impulse'])} | "
                     f"{fmt(r['peak_normal'])} | {fmt(r['peak_tangential'])} | "
                     f"{r['impacts']} |")
    return "\n".join(lines)


def callgrind_stepping(simulate, scene, args, workdir, tag, whole=False):
    """(instructions, summary) of one `simulate` run under callgrind: inside advancePast only,
    or with whole the whole process (loading and the end included)."""
    out = os.path.join(workdir, f"{tag}.cg")
    summary = os.path.join(workdir, f"{tag}.json")
    toggle = [] if whole else ["--toggle-collect=threshing_sim::advancePast*"]
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"] + toggle +
                   [str(simulate), str(ROOT / scene), "--quiet", "--summary", summary] + args,
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   timeout=7200)
    with open(summary) as f:
        return total_instructions(out), json.load(f)


def cost_cases(gen_dir, quick):
    """(label, scene, extra arguments) of the cost table."""
    cases = [("default strike (default scene and settings)", "config/default_scene.yaml", [])]
    stream = "config/bench/stream.yaml"
    counts = [(100, False)] if quick else [(100, False), (1000, ("sparse", 10)), (1000, False)]
    for n, layout in counts:
        name = f"bench stream, {n} kernels" + (", 10 in reach" if layout else "")
        cases.append((name, stream, ["--set-file", str(kernel_file(n, layout, gen_dir))]))
    return cases


def cost(simulate, say, quick=False):
    """Stepping-loop instructions of every cost case, adaptive and under the contact phase at
    DEFAULT_STEPS, with the contact events and the real-time factor at 3e9 instructions/s; and
    the default strike's whole-process counts."""
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for i, (label, scene, extra) in enumerate(cost_cases(work, quick)):
            for setting, args in (("adaptive", []), (f"contact phase, {DEFAULT_STEPS} steps",
                                                     ["--set",
                                                      f"integrator.contact_steps={DEFAULT_STEPS}"])):
                say(f"contact phase cost: {label}, {setting}")
                total, run = callgrind_stepping(simulate, scene, extra + args, work, f"k{i}")
                events = max(1, run["contact_episodes"])
                row = {"case": label, "setting": setting, "instructions": total,
                       "events": run["contact_episodes"], "per_event": total / events,
                       "rtf_at_3e9": run["sim_time_s"] * INSTRUCTIONS_PER_S / total,
                       "impacts": run["impacts"], "whole": None}
                if i == 0:
                    row["whole"], _ = callgrind_stepping(simulate, scene, extra + args, work,
                                                         f"w{i}", whole=True)
                rows.append(row)
    return rows


def cost_table(rows):
    """The cost rows as a markdown table, with each case's ratio adaptive / contact phase."""
    lines = ["| case | setting | instructions (stepping loop) | contact events | per event | "
             "real-time factor at 3e9/s | whole process | adaptive / this |",
             "|---|---|---|---|---|---|---|---|"]
    adaptive = {}
    for r in rows:
        if r["setting"] == "adaptive":
            adaptive[r["case"]] = r["instructions"]
        ratio = adaptive.get(r["case"], r["instructions"]) / r["instructions"]
        lines.append(f"| {r['case']} | {r['setting']} | {fmt(float(r['instructions']), 3)} | "
                     f"{r['events']} | {fmt(r['per_event'], 3)} | {fmt(r['rtf_at_3e9'], 3)} | "
                     f"{fmt(float(r['whole']), 3) if r['whole'] else '–'} | {fmt(ratio, 3)} |")
    return "\n".join(lines)
