#!/usr/bin/python3
"""Measures the sweep runner's overhead (docs/sweeps.md, "Overhead").

Runs `scripts/sweep run SWEEP` from scratch (fresh output folder, nothing cached) as a child
process and compares its wall time with the runs' own CPU time (user + system of each simulate
process, from wait4, column cpu_s of runs.csv) divided by the workers:

  ratio         = wall / (sum of the runs' CPU / workers)          target <= 1.10
  overhead/run  = (wall * workers - sum of the runs' CPU) / runs   core time lost per run
  runner CPU    = CPU of the whole command tree (wait4) - sum of the runs' CPU

With --cluster it also starts a dask-scheduler and two dask-workers on 127.0.0.1, runs the same
sweep against them and checks that the table equals the local one apart from wall/CPU times and
worker names. The load average is printed before and after: the ratio only means something on
a machine that is otherwise idle.
"""
import argparse
import csv
import os
import pathlib
import shutil
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))

from sweeplib import cluster as cluster_module  # noqa: E402
from sweeplib import runner  # noqa: E402


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


def report(label, workers, wall, tree_cpu, n, run_cpu):
    ideal = run_cpu / workers
    print(f"{label}: {n} runs on {workers} workers")
    print(f"  wall {wall:.2f} s; runs' own CPU {run_cpu:.2f} s ({1e3 * run_cpu / n:.1f} ms per "
          f"run); CPU / workers {ideal:.2f} s")
    print(f"  ratio wall / (CPU / workers) = {wall / ideal:.3f} (target <= 1.10)")
    print(f"  overhead per run = {1e3 * (wall * workers - run_cpu) / n:.2f} ms of core time")
    print(f"  runner CPU (command tree - runs) = {tree_cpu - run_cpu:.2f} s "
          f"({1e3 * (tree_cpu - run_cpu) / n:.2f} ms per run)")


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sweep", default=str(ROOT / "config/sweeps/single_strike_1000.yaml"))
    parser.add_argument("--simulate", help="simulate binary (default: the built one)")
    parser.add_argument("--workers", type=int, default=os.cpu_count(),
                        help="local cluster size (default: the number of cores)")
    parser.add_argument("--out", default=str(ROOT / "out/sweep_overhead"))
    parser.add_argument("--cluster", action="store_true", help="also run the sweep on a "
                        "scheduler with two workers on 127.0.0.1 and compare the tables")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"{os.cpu_count()} cores")
    local = out / "local"
    wall, tree_cpu, _ = timed_sweep(args, local, ["--workers", str(args.workers)])
    n, run_cpu, bad = table_stats(local)
    report("local cluster", args.workers, wall, tree_cpu, n, run_cpu)
    if bad:
        print(f"  {len(bad)} runs not ok, e.g. run {bad[0]['run']}: {bad[0]['status']} "
              f"{bad[0]['message']}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if not args.cluster:
        return 0
    with cluster_module.LoopbackCluster(out / "cluster_processes", workers=2) as cluster:
        remote = out / "cluster"
        wall, _, _ = timed_sweep(args, remote, ["--scheduler", cluster.address])
    n2, run_cpu2, _ = table_stats(remote)
    print(f"scheduler with two workers: {n2} runs, wall {wall:.2f} s, ratio "
          f"{wall / (run_cpu2 / 2):.3f}")
    diffs = runner.compare_tables(local / "runs.csv", remote / "runs.csv")
    print("tables equal apart from wall_s, cpu_s, worker" if not diffs else
          f"{len(diffs)} differences, e.g. {diffs[0]}")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
