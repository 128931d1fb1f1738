"""scripts/bench.py's command line: the stages in order, the checks of the quick version."""
import argparse
import pathlib
import sys
import tempfile
import time

from tslib import DOCS, markdown
from tslib.bench import islands
from tslib.bench.config import (CACHE_DIR, INTEGRATOR_STYLE, KERNEL_COUNTS, MODE_COUNTS,
                                NODE_COUNTS, NODE_DURATION_S, REF_DT_S, REF_TOLERANCE, SCENES,
                                STEPS_S, STREAM_REF_DT_S, STREAM_STEPS_S, TOLERANCES, say)
from tslib.bench.measure import node_budget, references, scaling, sweeps
from tslib.bench.plots import plot_scaling, plot_work_precision
from tslib.bench.runner import Runner
from tslib.bench.scenes import stream_override_text
from tslib.bench.tables import write_csv, write_tables
from tslib.binaries import BIN_DIR


def parse_args(doc):
    ap = argparse.ArgumentParser(description=doc,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="tiny CI version into --out")
    ap.add_argument("--out", help="output folder (default: docs/; --quick: a temporary folder)")
    ap.add_argument("--bin", default=str(BIN_DIR), help="folder of the built binaries")
    ap.add_argument("--jobs", type=int, default=2, help="parallel points, one CPU each")
    ap.add_argument("--reps", type=int, default=5, help="timed repetitions per point")
    ap.add_argument("--no-cache", action="store_true", help="rerun every point")
    ap.add_argument("--no-node", action="store_true", help="skip the node budget")
    ap.add_argument("--no-readme", action="store_true", help="leave docs/benchmarks.md and docs/architecture.md alone")
    ap.add_argument("--part", choices=["all", "islands"], default="all",
                    help="islands: only the island-local scheme's part (scripts/tslib/bench/islands.py:"
                         " scaling to 10 000 kernels, events by kind, instructions per event, "
                         "the node at 100 and 1000 kernels, the targets)")
    ap.add_argument("--stream-kernels", type=int, metavar="N",
                    help="print the stream scene's kernel override file for N kernels and exit")
    ap.add_argument("--idle", nargs="?", const="rest", choices=["rest", "swinging"],
                    help="with --stream-kernels: every kernel out of reach, hanging at rest "
                         "(default) or swinging from unstretched pedicels")
    ap.add_argument("--sparse", type=int, metavar="N",
                    help="with --stream-kernels: N kernels of the stream in reach, the rest "
                         "hanging at rest out of reach")
    return ap.parse_args()


def configuration(args):
    """The sweep's settings, scenes, output folder and cache: the CI's tiny version (--quick) or
    the full one."""
    if args.quick:
        cfg = {"tolerances": [1e-4, 1e-7], "steps": [1e-5, 1e-6], "stream_steps": [1e-5, 1e-6],
               "ref_tol": 1e-9, "ref_dt": 1e-7, "stream_ref_dt": 1e-7, "mode_steps": [2],
               "reps": 2, "budget": 5.0, "samples": 200, "kernel_counts": [1, 10],
               "mode_counts": [0, 2], "scaling_reps": 1, "node_duration": NODE_DURATION_S,
               "time_limit": 10.0}
        out = pathlib.Path(args.out or tempfile.mkdtemp(prefix="bench_quick_"))
        return cfg, ["single_strike"], out, out / "cache"
    cfg = {"tolerances": TOLERANCES, "steps": STEPS_S, "stream_steps": STREAM_STEPS_S,
           "ref_tol": REF_TOLERANCE, "ref_dt": REF_DT_S, "stream_ref_dt": STREAM_REF_DT_S,
           "mode_steps": [1, 2], "reps": args.reps, "budget": 20.0, "samples": 200,
           "kernel_counts": KERNEL_COUNTS, "mode_counts": MODE_COUNTS, "scaling_reps": 3,
           "node_duration": NODE_DURATION_S, "time_limit": 60.0}
    return cfg, list(SCENES), pathlib.Path(args.out) if args.out else DOCS, CACHE_DIR


def quick_problems(rows, refs, names, fig_dir):
    """The CI checks of the quick sweep: errors fall with the knob, the references agree, the
    figures exist."""
    problems = []
    for name in names:
        for integrator in INTEGRATOR_STYLE:
            sel = sorted((r for r in rows if r["scene"] == name and
                          r["integrator"] == integrator), key=lambda r: -r["knob"])
            # Exit velocity and pose converge under both integrators; the force peaks of
            # time stepping are impulses over one step and need not improve between two
            # coarse steps (see docs/bench.md).
            for m in ("exit_velocity", "pose"):
                if not sel[-1][m] < sel[0][m]:
                    problems.append(f"{name} {integrator}: {m} error does not fall with the "
                                    f"knob ({sel[0][m]:.3g} -> {sel[-1][m]:.3g})")
    for name in names:
        a = refs[name]["agreement"]
        if not a["exit_velocity"] < 1e-3:
            problems.append(f"{name}: references disagree on the exit velocity "
                            f"({a['exit_velocity']:.3g})")
    for f in ("wp_single_strike.png", "scaling.png", "work_precision.csv", "scaling.csv"):
        if not (fig_dir / f).exists() or (fig_dir / f).stat().st_size < 500:
            problems.append(f"{f} missing")
    return problems


def main(doc=None):
    """scripts/bench.py; doc: its --help text (the entry point's docstring)."""
    args = parse_args(doc)
    if args.stream_kernels is not None:
        idle = ("sparse", args.sparse) if args.sparse is not None else (args.idle or False)
        sys.stdout.write(stream_override_text(args.stream_kernels, idle))
        return 0

    started = time.monotonic()
    bench_bin = pathlib.Path(args.bin) / "bench_work_precision"
    if not bench_bin.exists():
        raise SystemExit(f"bench: {bench_bin} not found: build first (bash scripts/setup.sh)")
    cfg, names, out, cache = configuration(args)
    fig_dir = out / "bench"
    fig_dir.mkdir(parents=True, exist_ok=True)
    gen_dir = cache.parent / "generated" if not args.quick else out / "generated"
    gen_dir.mkdir(parents=True, exist_ok=True)
    runner = Runner(bench_bin, args.jobs, cache, use_cache=not args.no_cache)
    if args.part == "islands":
        islands.run_islands(args, runner, gen_dir, out, fig_dir)
        return 0

    say(f"bench: references ({', '.join(names)})")
    refs = references(runner, names, cfg, gen_dir)
    say("bench: work-precision sweeps")
    rows = sweeps(runner, names, cfg, refs, gen_dir)
    write_csv(fig_dir / "work_precision.csv", rows)
    plot_work_precision(rows, names, fig_dir)
    say("bench: scaling runs")
    scal = scaling(runner, cfg, gen_dir)
    write_csv(fig_dir / "scaling.csv", scal)
    plot_scaling(scal, fig_dir)
    node = None
    if not args.no_node and not args.quick:
        say("bench: node budget")
        node = node_budget(cfg, gen_dir, NODE_COUNTS)
        if node:
            write_csv(fig_dir / "node_budget.csv", node)
    if not args.quick:
        islands.run_islands(args, runner, gen_dir, out, fig_dir)
    elapsed = time.monotonic() - started
    bench_section, scaling_section, doc = write_tables(refs, rows, scal, node, names, cfg,
                                                       elapsed, runner)
    (out / "bench.md").write_text(doc)
    if not args.quick and not args.no_readme and not args.out:
        markdown.splice("bench-table", bench_section)
        markdown.splice("scaling-table", scaling_section)
    say(f"bench: wrote {out / 'bench.md'}, {fig_dir} in {elapsed / 60:.1f} min")

    # Checks: every point ran, deterministically, and the errors fall with the knob.
    problems = []
    for r in rows:
        if r["status"] == "failed":
            problems.append(f"{r['scene']} {r['integrator']} {r['knob']:g}: failed")
        if not r["deterministic"]:
            problems.append(f"{r['scene']} {r['integrator']} {r['knob']:g}: reruns differ")
    if args.quick:
        problems += quick_problems(rows, refs, names, fig_dir)
    for p in problems:
        say(f"bench: PROBLEM: {p}")
    return 1 if problems else 0
