"""scripts/convergence_table.py's command line."""
import argparse
import concurrent.futures
import os
import pathlib

from tslib.convergence import runs
from tslib import ROOT, schema
from tslib.binaries import find_binary
from tslib.convergence.docs import knead_text, rotation_text, verdict, write_docs
from tslib.convergence.runs import (ROD_SUFFIX, knead_before_after, rod_reruns, rotation_study,
                                    scenes, study, usable)


def main(doc=""):
    """scripts/convergence_table.py; doc: its docstring (the first line is the --help text)."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("--simulate", type=pathlib.Path, default=None)
    p.add_argument("--quick", action="store_true", help="two bench scenes, no README")
    p.add_argument("--out", type=pathlib.Path, default=ROOT / "docs/convergence.md")
    p.add_argument("--work", type=pathlib.Path, default=ROOT / ".build/convergence")
    p.add_argument("--jobs", type=int, default=max(1, min(2, os.cpu_count() or 1)))
    p.add_argument("--time-limit", type=float, default=runs.TIME_LIMIT_S,
                   help="seconds per simulation before its level counts as timed out")
    p.add_argument("--reuse", action="store_true",
                   help="keep the summaries already in --work (to redo the tables)")
    a = p.parse_args()
    runs.TIME_LIMIT_S, runs.REUSE = a.time_limit, a.reuse
    simulate = find_binary("simulate", a.simulate)
    schema.use(simulate)
    a.work.mkdir(parents=True, exist_ok=True)
    todo = scenes(a.quick)
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = [pool.submit(study, simulate, name, args, a.work) for name, args in todo]
        knead = pool.submit(knead_before_after, simulate, a.work)
        rotation_future = pool.submit(rotation_study, simulate, a.work)
        results = [f.result() for f in futures]
        rods = rod_reruns(todo, results)
        results += [f.result() for f in [pool.submit(study, simulate, name, args, a.work)
                                         for name, args in rods]]
        order = [name for name, _ in todo]  # each rod rerun right after its modal row
        results.sort(key=lambda r: (order.index(r[0] if r[0] in order else
                                                r[0].replace(ROD_SUFFIX, "")), r[0]))
        before, after = knead.result()
        rotation = rotation_future.result()
    for name, rows in results:
        print(f"{name}: {' '.join(verdict(rows))}  " +
              "  ".join(f"{n}: N {m['fn']:.4g} T {m['ft']:.4g} v {m['v']:.4g}" for n, m in rows
                        if usable(m)))
    print(knead_text(before, after))
    print(rotation_text(rotation))
    write_docs(results, before, after, rotation, a.out, None if a.quick else ROOT / "README.md")
