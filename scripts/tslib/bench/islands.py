"""The island-local scheme's part of the benchmark (scripts/bench.py --part islands).
Measures, with the same pinned, cached bench_work_precision points as the rest of bench.py:

1. Scaling of the stream scene (config/bench/stream.yaml, 2 ms) with the kernel count, up to
   10 000, for four layouts: the stream (kernels in the teeth's path), idle at rest (every
   kernel hanging at its static equilibrium out of reach), idle swinging (out of reach on
   unstretched pedicels, so that each swings and falls), and sparse (10 kernels in reach, the
   rest at rest out of reach); under the island scheme and, where affordable, the global one.
2. Events per kernel per simulated second by kind (RunStats::scheduler).
3. Instructions per contact event and per island step, by callgrind (valgrind), on the single
   strike and the 100- and 1000-kernel streams; and per stage of the step
   (scripts/stage_profile.py, skipped by --quick).
4. The node's real-time factor on the stream at 1, 10, 100 and 1000 kernels.
5. The issue's targets, each with its measured figure.

Writes docs/bench_islands.md, docs/bench/islands_*.csv and .png, and the section of
docs/architecture.md between the islands-table markers.
"""
import json
import os
import pathlib
import re
import shutil
import subprocess
import tempfile

from tslib import BENCH_DIR, DOCS, ROOT, markdown, plots
from tslib.bench import stages as stage_profile
from tslib.bench.config import NODE_DURATION_S, say
from tslib.bench.measure import node_try
from tslib.bench.scenes import stream_override_file
from tslib.bench.stages import DEFAULT_SCENE, STREAM
from tslib.bench.tables import write_csv
from tslib.binaries import BIN_DIR
from tslib.numbers import fmt

STRIKE = BENCH_DIR / "single_strike.yaml"
COUNTS = [0, 1, 10, 100, 1000, 10000]
GLOBAL_MAX = 1000  # the global scheme is run up to this count (it costs kernels x events)
KNOBS = {"event_driven": "integrator.tolerance=1e-6", "time_stepping": "integrator.dt=1e-6"}
# (scheme, integrator) -> the overrides of a run: islands/event-driven first, global last.
SCHEMES = {(scheme, integrator): ["--set", f"integrator.islands={str(scheme == 'islands').lower()}",
                                  "--set", f"integrator.type={integrator}", "--set", knob]
           for scheme in ("islands", "global") for integrator, knob in KNOBS.items()}
LAYOUTS = {"stream": False, "idle at rest": "rest", "idle swinging": "swinging",
           "sparse (10 in reach)": ("sparse", 10)}
EVENT_KINDS = ["island_steps", "islands_built", "tooth_wakes", "kernel_wakes", "predictions",
               "shrinks", "pedicel_steps", "sleeps", "free_advances", "tooth_advances",
               "windows"]


def kernel_file(count, layout, gen_dir):
    if count == 0:
        path = pathlib.Path(gen_dir) / "stream_kernels_0.yaml"
        path.write_text("# No kernels: the stream scene's teeth, drum and grate alone.\n"
                        "kernels: []\n")
        return path
    return stream_override_file(count, gen_dir, layout)


def island_scaling(runner, gen_dir, quick):
    counts = [0, 1, 10] if quick else COUNTS
    futures = []
    for (scheme, integrator), settings in SCHEMES.items():
        for layout, idle in LAYOUTS.items():
            for n in counts:
                if scheme == "global" and (n > GLOBAL_MAX or layout != "stream"):
                    continue
                if layout.startswith("sparse") and n < 10:
                    continue
                args = ["--set-file", str(kernel_file(n, idle, gen_dir))] + settings
                label = f"islands bench: {layout}, {n} kernels, {scheme} {integrator}"
                futures.append(((scheme, integrator, layout, n), runner.submit(
                    label, STREAM, args, reps=1 if quick or n >= 1000 else 3, budget_s=30.0,
                    samples=0, time_limit_s=10.0 if quick else 60.0)))
    rows = []
    for (scheme, integrator, layout, n), fut in futures:
        run = fut.result()
        sched = run.get("scheduler", {})
        struck = sum(1 for k in run["kernels"] if k["impacts"] > 0)
        rows.append({"scheme": scheme, "integrator": integrator, "layout": layout, "n": n,
                     "status": run["status"], "completed": run["completed"],
                     "sim_time_s": run["sim_time_s"], "wall_per_sim_s": run["wall_per_sim_s"],
                     "real_time_factor": 1.0 / run["wall_per_sim_s"],
                     "impacts": run["impacts"], "kernels_struck": struck, "steps": run["steps"],
                     **{k: sched.get(k, 0) for k in EVENT_KINDS}})
    return rows


def callgrind_count(bench_bin, scene, args, workdir):
    """Instructions inside advanceTo (the stepping loop) of one bench_work_precision run."""
    out = pathlib.Path(workdir) / "cg.out"
    json_out = pathlib.Path(workdir) / "cg.json"
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
           "--toggle-collect=threshing_sim::advanceTo*", str(bench_bin), str(scene)] + args + [
               "--reps", "1", "--samples", "0", "--out", str(json_out)]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True,
                   timeout=3600)
    text = subprocess.run(["callgrind_annotate", str(out)], capture_output=True, text=True,
                          check=True).stdout
    m = re.search(r"([\d,]+)\s+\(100\.0%\)\s+PROGRAM TOTALS", text)
    with open(json_out) as f:
        run = json.load(f)
    return int(m.group(1).replace(",", "")), run


# Instructions per second of one core of the reference machine (docs of the async core: a
# 2-vCPU machine at about 3e9 instructions per second per core): a callgrind count converts
# to a real-time factor free of the load other jobs put on a shared machine.
INSTRUCTIONS_PER_S = 3e9


def instruction_cases(gen_dir, quick):
    """(label, scene, extra args, integrator) of the callgrind runs."""
    if quick:
        return [("single strike", STRIKE, [], "event_driven"),
                ("stream, 10 kernels", STREAM, ["--set-file", str(kernel_file(10, False, gen_dir))],
                 "event_driven")]
    tol7 = ["--set", "integrator.tolerance=1e-7"]
    cases = [("default strike (default scene and settings)", DEFAULT_SCENE, [], "event_driven"),
             ("single strike, tolerance 1e-7", STRIKE, tol7, "event_driven")]
    # The idle kernels' targets: each against the same scene with no kernels, both integrators.
    for integrator in ("event_driven", "time_stepping"):
        for label, count, layout in (("stream, no kernels", 0, False),
                                     ("stream, 1000 idle at rest", 1000, "rest"),
                                     ("stream, 1000 idle swinging", 1000, "swinging")):
            cases.append((label, STREAM, ["--set-file", str(kernel_file(count, layout, gen_dir))],
                          integrator))
    for integrator in ("event_driven", "time_stepping"):
        cases.append(("stream, 1000 kernels, 10 in reach", STREAM,
                      ["--set-file", str(kernel_file(1000, ("sparse", 10), gen_dir))], integrator))
    for n in (100, 1000):
        for integrator in ("event_driven", "time_stepping"):
            cases.append((f"stream, {n} kernels", STREAM,
                          ["--set-file", str(kernel_file(n, False, gen_dir))], integrator))
    return cases


def instructions(gen_dir, quick):
    """Instructions of the stepping loop per run, per contact event (impact or compliant
    episode) and per island step, and the real-time factor they give at INSTRUCTIONS_PER_S."""
    if shutil.which("valgrind") is None:
        say("islands bench: valgrind not installed, instruction counts skipped")
        return []
    bench_bin = BIN_DIR / "bench_work_precision"
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for label, scene, extra, integrator in instruction_cases(gen_dir, quick):
            settings = list(SCHEMES[("islands", integrator)])
            if "integrator.tolerance=1e-7" in extra:
                settings = settings[:-2]
            total, run = callgrind_count(bench_bin, scene, extra + settings, work)
            events = max(1, run["contact_episodes"])
            steps = max(1, run["scheduler"]["island_steps"])
            rows.append({"case": label, "integrator": integrator, "instructions": total,
                         "sim_time_s": run["sim_time_s"],
                         "rtf_at_3e9": run["sim_time_s"] * INSTRUCTIONS_PER_S / total,
                         "contact_events": run["contact_episodes"],
                         "island_steps": run["scheduler"]["island_steps"],
                         "per_event": total / events, "per_island_step": total / steps,
                         "island_body_steps": run["scheduler"]["island_body_steps"]})
            say(f"islands bench: {label}, {integrator}: {total:.3g} instructions, "
                      f"{total / events:.3g} per contact event")
    return rows


def stage_table(gen_dir, quick):
    """The current "Instructions per stage" table of scripts/stage_profile.py, on this
    benchmark's kernel files (None under --quick or without valgrind)."""
    if quick or shutil.which("valgrind") is None:
        return None
    case_list = stage_profile.cases(lambda n, sparse: kernel_file(
        n, ("sparse", sparse) if sparse is not None else False, gen_dir))
    results = stage_profile.profile(BIN_DIR / "simulate", case_list, say=say)
    return stage_profile.table(results)


def node_table(gen_dir, quick):
    if quick:
        return []
    cfg = {"node_duration": NODE_DURATION_S}
    setup = ROOT / ".build" / "ws" / "devel" / "setup.bash"
    if not (BIN_DIR / "threshing_sim_node").exists() or not setup.exists():
        return []
    rows = []
    port = 11800 + os.getpid() % 100
    for label, integrator in (("event-driven, tolerance 1e-6", "event_driven"),
                              ("time stepping, dt 1e-6 s", "time_stepping")):
        settings = SCHEMES[("islands", integrator)][2:]
        for n in (1, 10, 100, 1000):
            row = node_try(cfg, gen_dir, setup, port, integrator, settings, n)
            if row is None:  # no summary (or too slow to finish): larger counts are slower
                break
            row["setting"] = label
            rows.append(row)
    return rows



def plot(rows, out_dir):
    plt = plots.pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, integrator in zip(axes, ("event_driven", "time_stepping")):
        for (layout, scheme), style in {("stream", "islands"): "o-", ("stream", "global"): "o--",
                                        ("idle at rest", "islands"): "s-",
                                        ("idle swinging", "islands"): "^-",
                                        ("sparse (10 in reach)", "islands"): "d-"}.items():
            sel = sorted((r for r in rows if r["layout"] == layout and r["scheme"] == scheme
                          and r["integrator"] == integrator and r["n"] > 0),
                         key=lambda r: r["n"])
            if sel:
                ax.loglog([r["n"] for r in sel], [r["wall_per_sim_s"] for r in sel], style,
                          label=f"{layout} ({scheme})")
        ax.axhline(1.0, color="grey", lw=0.8, ls=":")
        ax.set_xlabel("kernels")
        ax.set_ylabel("wall time per simulated second [s]")
        ax.set_title(integrator.replace("_", " "))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "islands_scaling.png", dpi=110)
    plt.close(fig)


def pick(rows, **kw):
    for r in rows:
        if all(r.get(k) == v for k, v in kw.items()):
            return r
    return None


def targets(scal, instr, node):
    """The targets of issue 22 (the contact event's cost) and issue 26 (idle kernels): (case,
    target, measured, met). Real-time factors from callgrind instruction counts at
    INSTRUCTIONS_PER_S (the wall-time factors of the scaling table depend on the machine's
    load); the node's from its wall clock."""
    def cg(case, integrator="event_driven"):
        return next((r for r in instr if r["case"] == case and r["integrator"] == integrator),
                    None)
    def rtf(case, integrator="event_driven"):
        r = cg(case, integrator)
        return r["rtf_at_3e9"] if r else None
    def row(label, goal_text, value, ok):
        out.append((label, goal_text, value, value is not None and ok(value)))
    out = []
    a, b = cg("stream, 100 kernels"), cg("stream, 1000 kernels")
    for r, n in ((a, 100), (b, 1000)):
        row(f"instructions per contact event, bench stream, {n} kernels, event-driven (issue 22)",
            "<= 3e4", r["per_event"] if r else None, lambda v: v <= 3e4)
    row("per-event cost, 1000 against 100 kernels (issue 22)", "<= 1.2",
        b["per_event"] / a["per_event"] if a and b else None, lambda v: v <= 1.2)
    row("default strike, default scene and settings (event-driven, tolerance 1e-6), advance "
        "(issue 22)", ">= 100x real time", rtf("default strike (default scene and settings)"),
        lambda v: v >= 100)
    for integrator, goal in (("event_driven", 1.0), ("time_stepping", 0.2)):
        row(f"1000 kernels, 10 in reach, {integrator.replace('_', ' ')} (issue 22)",
            f">= {goal:g}x real time", rtf("stream, 1000 kernels, 10 in reach", integrator),
            lambda v, goal=goal: v >= goal)
    for integrator, goal in (("event_driven", 0.5), ("time_stepping", 0.1)):
        row(f"bench stream, 1000 kernels, {integrator.replace('_', ' ')} (issue 22)",
            f">= {goal:g}x real time", rtf("stream, 1000 kernels", integrator),
            lambda v, goal=goal: v >= goal)
    nrow = next((r for r in node if r["n"] == 100 and r["integrator"] == "event_driven"), None)
    row("the node with the 100-kernel stream, real-time factor (wall clock) (issue 22)",
        ">= 0.99", nrow["rtf"] if nrow else None, lambda v: v >= 0.99)
    for integrator in ("event_driven", "time_stepping"):
        none = cg("stream, no kernels", integrator)
        for layout in ("at rest", "swinging"):
            idle = cg(f"stream, 1000 idle {layout}", integrator)
            row(f"1000 idle kernels {layout} on pedicels, {integrator.replace('_', ' ')} (2 ms) "
                "(issue 26)", "<= 1.2x the cost with no kernels",
                idle["instructions"] / none["instructions"] if idle and none else None,
                lambda v: v <= 1.2)
    return out


def write_doc(scal, instr, node, tgt, out_dir, fig_rel, stages=None):
    lines = ["| case | target | measured | met |", "|---|---|---|---|"]
    for case, goal, value, met in tgt:
        lines.append(f"| {case} | {goal} | {fmt(value, 3, none='-')} | {'yes' if met else '**no**'} |")
    target_table = "\n".join(lines)
    sc = ["| layout | kernels | scheme | integrator | real-time factor | kernels struck | "
          "impacts | island steps |", "|---|---|---|---|---|---|---|---|"]
    for r in sorted(scal, key=lambda r: (r["layout"], r["integrator"], r["scheme"], r["n"])):
        sc.append(f"| {r['layout']} | {r['n']} | {r['scheme']} | {r['integrator']} | "
                  f"{fmt(r['real_time_factor'], 3, none='-')}{'' if r['completed'] else ' (cut short)'} | "
                  f"{r['kernels_struck']} | {r['impacts']} | {r['island_steps']} |")
    ev = ["| layout | kernels | integrator | " + " | ".join(EVENT_KINDS) + " |",
          "|---|---|---|" + "---|" * len(EVENT_KINDS)]
    for r in sorted(scal, key=lambda r: (r["layout"], r["integrator"], r["n"])):
        if r["scheme"] != "islands" or r["n"] == 0:
            continue
        per = r["n"] * r["sim_time_s"]
        ev.append(f"| {r['layout']} | {r['n']} | {r['integrator']} | " +
                  " | ".join(fmt(r[k] / per, 3, none='-') for k in EVENT_KINDS) + " |")
    ins = ["| case | integrator | instructions | real-time factor at 3e9/s | contact events | "
           "island steps | per event | per island step | bodies per island step |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in instr:
        ins.append(f"| {r['case']} | {r['integrator']} | {r['instructions']:.3g} | "
                   f"{fmt(r['rtf_at_3e9'], 3, none='-')} | {r['contact_events']} | {r['island_steps']} | "
                   f"{r['per_event']:.3g} | {r['per_island_step']:.3g} | "
                   f"{r['island_body_steps'] / max(1, r['island_steps']):.3g} |")
    nd = ["| setting | kernels | real-time factor | overruns |", "|---|---|---|---|"]
    for r in node:
        nd.append(f"| {r['setting']} | {r['n']} | {fmt(r['rtf'], 3, none='-')} | {r['overruns']} |")
    doc = f"""# The island-local scheme: measured

Regenerated by `python3 scripts/bench.py --part islands` (Release, one pinned CPU per point,
medians; callgrind for instruction counts). The stream scene is `config/bench/stream.yaml`
(2 ms); its kernel files come from `scripts/bench.py --stream-kernels N [--idle [swinging]]
[--sparse 10]`.

## The targets (issues 22 and 26)

{target_table}

{kept_section(out_dir, "islands-studies")}

## Scaling with the kernel count

![scaling]({fig_rel}islands_scaling.png)

{chr(10).join(sc)}

## Events per kernel per simulated second, by kind (island scheme)

{chr(10).join(ev)}

## Instructions per contact event and per island step (callgrind)

Instructions inside `advanceTo`, divided by the contact events (impacts and compliant episodes)
and by the island integrator's accepted steps.

{chr(10).join(ins)}

## The node's real-time factor (stream, island scheme)

{chr(10).join(nd) if node else "(not measured in this run)"}

{stages_section(out_dir, stages)}"""
    return doc, target_table


def page_section(out_dir, name):
    """The body of section name on the page this run writes (out_dir/bench_islands.md), or
    else on docs/bench_islands.md; None when neither has it."""
    for page in (pathlib.Path(out_dir) / "bench_islands.md", DOCS / "bench_islands.md"):
        body = markdown.section_body(page.read_text(), name) if page.exists() else None
        if body is not None:
            return body
    return None


def kept_section(out_dir, name):
    """A section of docs/bench_islands.md written by hand between its marker pair (the
    studies behind single figures: their own commands regenerate their numbers), kept as the
    page has it; empty markers on a page without it."""
    m0, m1 = markdown.markers(name)
    return f"{m0}\n{(page_section(out_dir, name) or '').strip()}\n{m1}"


def stages_section(out_dir, stages):
    """The "Instructions per stage" section: the recorded "before" table of the page (or of
    docs/bench_islands.md) kept, the current one from this run (or kept when not measured)."""
    current = stages or page_section(out_dir, "stage-profile") or "(not measured in this run)"
    return stage_profile.section(current, page_section(out_dir, "stage-profile-before"))


def run_islands(args, runner, gen_dir, out, fig_dir):
    quick = args.quick
    scal = island_scaling(runner, gen_dir, quick)
    write_csv(fig_dir / "islands_scaling.csv", scal)
    plot(scal, fig_dir)
    instr = instructions(gen_dir, quick)
    write_csv(fig_dir / "islands_instructions.csv", instr)
    node = [] if args.no_node else node_table(gen_dir, quick)
    write_csv(fig_dir / "islands_node.csv", node)
    tgt = targets(scal, instr, node)
    stages = stage_table(gen_dir, quick)
    doc, table = write_doc(scal, instr, node, tgt, out, "bench/", stages)
    (out / "bench_islands.md").write_text(doc)
    if not quick and not args.no_readme and not args.out:
        markdown.splice("islands-table", table)
    say(f"islands bench: wrote {out / 'bench_islands.md'}")
    return scal
