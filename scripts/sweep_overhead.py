#!/usr/bin/python3
"""Measures the sweep runner's overhead (docs/sweeps.md, "Overhead").

Runs `scripts/sweep run SWEEP` from scratch (fresh output folder, nothing cached) as a child
process and compares its wall time with the CPU time of the runs. Runs share simulate --batch
processes, so a run's CPU is the one simulate measures for it in-process (thread CPU clock, from
reading its line to writing its result; column cpu_s of runs.csv); the batch processes' own CPU
(user + system from wait4: the runs plus process start, dynamic linking and the lines' I/O) is
in run_stats.json:

  ratio         = wall / (sum of the runs' CPU / workers)                  target <= 1.10
  ratio (processes) = wall / (sum of the simulate processes' CPU / workers)
                  (the old definition: one simulate process per run, its wait4 CPU)
  overhead/run  = (wall * workers - sum of the runs' CPU) / runs   core time lost per run
  runner CPU    = CPU of the whole command tree (wait4) - the simulate --batch processes' CPU
                  (local runs only: validation, Python, the table)

and where the wall time goes: the resolution (simulate --check-batch --resolve-only: the runs'
scenes and keys), the validation in the batch processes (each share read, loaded and compiled
before the barrier; the runs' own CPU holds it), the runs (from the go to the last result) and
the rest (Python start, imports, the table at the end).
With --cluster it also starts a dask-scheduler and two dask-workers on 127.0.0.1, runs the same
sweep against them and checks that the table equals the local one apart from wall/CPU times and
worker names. The load average is printed before and after: the ratio only means something on
a machine that is otherwise idle.
"""
import argparse
import csv
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # tslib
from tslib import ROOT  # noqa: E402

from tslib.sweep import cluster as cluster_module  # noqa: E402
from tslib.sweep import runner  # noqa: E402
from tslib import markdown  # noqa: E402


def timed_sweep(args, out, extra):
    """Runs the sweep command; returns (wall [s], CPU of the command tree [s], stderr)."""
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, str(ROOT / "scripts/sweep"), "run", args.sweep, "--out", str(out)]
    if args.simulate:
        command += ["--simulate", args.simulate]
    started = time.perf_counter()
    with open(out.parent / f"{out.name}.log", "w") as log:
        proc = subprocess.Popen(command + extra, stdout=log, stderr=log)
        _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - started
    proc.returncode = os.waitstatus_to_exitcode(status)
    text = (out.parent / f"{out.name}.log").read_text()
    if proc.returncode != 0:
        raise SystemExit(f"sweep failed ({proc.returncode}):\n{text}")
    # wait4's usage covers the command and every descendant it reaped: the simulate processes
    # and, with worker processes, the workers.
    return wall, usage.ru_utime + usage.ru_stime, text


def table_stats(out):
    with open(out / "runs.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    bad = [r for r in rows if r["status"] != "ok"]
    return len(rows), sum(float(r["cpu_s"]) for r in rows), bad


def report(label, workers, wall, tree_cpu, n, run_cpu, stats):
    """Lines of the measurement (tree_cpu None: not measured, the workers are not children);
    returns them with the ratio and its lower bound (None without tree_cpu)."""
    ideal = run_cpu / workers
    proc_cpu = stats["process_cpu_s"]
    bound = None
    hold = stats.get("hold_s", 0.0)
    rest = wall - stats["validate_s"] - hold - stats["dispatch_s"]
    shares = stats["batches"] if hold else None
    lines = [f"{label}: {n} runs on {workers} workers, {stats['processes']} simulate --batch "
             "processes " + (f"({shares} shares of at most {stats['batch']} runs, validated "
                             "first)" if shares else f"(batches of at most {stats['batch']})"),
             f"  wall {wall:.2f} s (target <= 6 s) = resolution {stats['validate_s']:.2f} s + "
             f"validation in the batch processes {hold:.2f} s + runs {stats['dispatch_s']:.2f} s "
             f"+ start and table {rest:.2f} s",
             f"  runs' own CPU {run_cpu:.2f} s ({1e3 * run_cpu / n:.2f} ms per run, thread CPU "
             f"in simulate); CPU / workers {ideal:.2f} s",
             f"  ratio wall / (runs' CPU / workers) = {wall / ideal:.3f} (target <= 1.10)",
             f"  simulate processes' CPU {proc_cpu:.2f} s ({1e3 * proc_cpu / n:.2f} ms per run); "
             f"ratio wall / (processes' CPU / workers) = {wall / (proc_cpu / workers):.3f}",
             f"  overhead per run = {1e3 * (wall * workers - run_cpu) / n:.2f} ms of core time"]
    if "runner_cpu_s" in stats:
        lines.append(f"  the sweep command's own CPU (Python: start, imports, the table, the "
                     f"results; not its children) {stats['runner_cpu_s']:.2f} s")
    if tree_cpu is not None:
        runner_cpu, check_cpu = tree_cpu - proc_cpu, stats["validate_cpu_s"]
        bound = 1 + (runner_cpu + proc_cpu - run_cpu) / run_cpu
        lines += [f"  runner CPU (command tree - simulate --batch processes) = {runner_cpu:.2f} s "
                  f"({1e3 * runner_cpu / n:.2f} ms per run, {100 * runner_cpu / run_cpu:.1f} % of "
                  f"the runs' CPU)",
                  f"    of which resolution (simulate --check-batch --resolve-only) "
                  f"{check_cpu:.2f} s ({1e3 * check_cpu / n:.2f} ms per run), the rest (Python, "
                  f"Dask, the table) {runner_cpu - check_cpu:.2f} s"]
        if workers == os.cpu_count():  # every core runs runs: the CPU bounds the wall time
            lines.append(f"  lower bounds with every core busy: ratio >= 1 + (runner CPU + "
                         f"processes' CPU - runs' CPU) / runs' CPU = {bound:.3f}; wall >= the "
                         f"command tree's CPU / cores = {tree_cpu / workers:.2f} s")
        else:
            bound = None
    print("\n".join(lines), flush=True)
    return lines, wall / ideal, bound


def run_stats(out):
    return json.loads((out / "run_stats.json").read_text())


def load_average():
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sweep", default=str(ROOT / "config/sweeps/single_strike_1000.yaml"))
    parser.add_argument("--simulate", help="simulate binary (default: the built one)")
    parser.add_argument("--workers", type=int, nargs="+", default=[os.cpu_count()],
                        help="local cluster sizes to measure (default: the number of cores)")
    parser.add_argument("--out", default=str(ROOT / "out/sweep_overhead"))
    parser.add_argument("--cluster", action="store_true", help="also run the sweep on a "
                        "scheduler with two workers on 127.0.0.1 and compare the tables")
    parser.add_argument("--dask-local", action="store_true", help="also run the sweep on a "
                        "local Dask cluster of worker processes (scripts/sweep --processes), "
                        "with the first --workers count")
    parser.add_argument("--docs", action="store_true", help="write the results into "
                        "docs/sweeps.md and the README (sections sweep-overhead), and the "
                        "first plot of the sweep's report into docs/sweeps/")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    # SIGTERM ends like Ctrl-C, so that the cluster started here is stopped.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    out.mkdir(parents=True, exist_ok=True)
    cores = os.cpu_count()
    text = [f"Measured by `scripts/sweep_overhead.py{' --cluster' if args.cluster else ''}"
            f"{' --dask-local' if args.dask_local else ''}"
            f"{' --workers ' + ' '.join(map(str, args.workers)) if args.workers != [cores] else ''}"
            f"` on {os.path.relpath(args.sweep, ROOT)} ({cores} cores):", ""]
    summary = []
    for workers in args.workers:
        before = load_average()
        local = out / f"local_{workers}"
        wall, tree_cpu, _ = timed_sweep(args, local, ["--workers", str(workers)])
        n, run_cpu, bad = table_stats(local)
        lines, ratio, bound = report(f"local, {workers} worker thread(s)", workers, wall,
                                     tree_cpu, n, run_cpu, run_stats(local))
        lines.append(f"  load average (1, 5, 15 min) before {before}, after {load_average()}")
        if bad:
            lines.append(f"  {len(bad)} runs not ok, e.g. run {bad[0]['run']}: "
                         f"{bad[0]['status']} {bad[0]['message']}")
        print(lines[-1])
        text += lines
        summary.append((workers, ratio, wall, bound, tree_cpu / workers, before))
    first = out / f"local_{args.workers[0]}"
    if args.dask_local:
        workers, before = args.workers[0], load_average()
        dask_local = out / f"dask_local_{workers}"
        wall, tree_cpu, _ = timed_sweep(args, dask_local, ["--workers", str(workers),
                                                           "--processes"])
        n, run_cpu, _ = table_stats(dask_local)
        lines, _, _ = report(f"local Dask cluster (--processes), {workers} worker process(es)",
                          workers, wall, tree_cpu, n, run_cpu, run_stats(dask_local))
        lines.append(f"  load average (1, 5, 15 min) before {before}, after {load_average()}")
        print(lines[-1])
        text += lines
    if args.cluster:
        with cluster_module.LoopbackCluster(out / "cluster_processes", workers=2) as cluster:
            remote = out / "cluster"
            before = load_average()
            wall, _, _ = timed_sweep(args, remote, ["--scheduler", cluster.address])
        n2, run_cpu2, _ = table_stats(remote)
        diffs = runner.compare_tables(first / "runs.csv", remote / "runs.csv")
        lines, ratio, _ = report("dask-scheduler with two dask-worker processes on 127.0.0.1", 2,
                              wall, None, n2, run_cpu2, run_stats(remote))
        lines += [f"  load average (1, 5, 15 min) before {before}, after {load_average()}",
                  "  table equal to the local one apart from wall_s, cpu_s, worker" if not diffs
                  else f"  {len(diffs)} differences from the local table, e.g. {diffs[0]}"]
        print("\n".join(lines[-2:]))
        text += lines
        summary.append(("cluster", not diffs, ratio, wall))
    if args.docs:
        subprocess.run([sys.executable, str(ROOT / "scripts/sweep"), "report", str(first)],
                       check=True, timeout=600)
        figures = ROOT / "docs/sweeps"
        figures.mkdir(parents=True, exist_ok=True)
        plot = sorted(first.glob("plot_0_*.png"))[0]
        shutil.copy(plot, figures / "peak_normal_force.png")
        markdown.splice("sweep-overhead", "```\n" + "\n".join(text) + "\n```")
        markdown.splice("sweep-overhead-readme", readme_text(summary))
    return 1 if args.cluster and not summary[-1][1] else 0


def readme_text(summary):
    parts = []
    for entry in summary:
        if entry[0] == "cluster":
            _, equal, ratio, wall = entry
            parts.append(f"on a dask-scheduler with two dask-workers, {wall:.1f} s and a ratio of "
                         f"{ratio:.2f}, " + ("with a table equal to the local one apart from wall "
                                             "times" if equal else "with a different table"))
            continue
        workers, ratio, wall, bound, cpu_wall, before = entry
        parts.append(f"on {workers} local worker(s), {wall:.1f} s of wall time and wall / (runs' "
                     f"CPU / workers) = {ratio:.2f} at a load average of {before.split()[0]}" +
                     (f"; from the CPU times, with every core busy, at least {cpu_wall:.1f} s "
                      f"and {bound:.2f}" if bound else ""))
    return ("**Overhead** (`scripts/sweep_overhead.py`, the 1000 single-strike runs of "
            "`config/sweeps/single_strike_1000.yaml` in `simulate --batch` processes): " +
            "; ".join(parts) + ". Details, the cost model and conditions: "
            "[`docs/sweeps.md`](docs/sweeps.md#overhead).")


if __name__ == "__main__":
    sys.exit(main())
