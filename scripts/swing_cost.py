#!/usr/bin/env python3
"""Issue 34's swinging-kernels target, measured as a user runs it: callgrind on `simulate`
(config/bench/stream.yaml, 2 ms, island scheme, event-driven) with 1000 kernels swinging on
their pedicels (scripts/bench.py --idle swinging) against the scene without kernels, counting
the instructions inside advancePast* (the run's stepping, the end's catch-up of the lone
kernels included) and of the whole process. Prints the markdown table of docs/bench_islands.md
("Idle kernels swinging"), one row per simulate binary given (--before for the reference).

    python3 scripts/swing_cost.py [--simulate BIN] [--before BIN] [--extra ARGS]

Needs valgrind; about a minute per binary on one core.
"""
import argparse
import pathlib
import re
import subprocess
import tempfile

from tslib import ROOT
from tslib.bench.islands import kernel_file

SIMULATE = ROOT / ".build/ws/devel/lib/threshing_sim/simulate"
SCENE = ROOT / "config/bench/stream.yaml"


def callgrind(simulate, kernels, extra, toggle, work):
    """Instructions of one simulate run (inside the toggle's functions, or all of it)."""
    out = pathlib.Path(work) / "cg.out"
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
    if toggle:
        cmd.append(f"--toggle-collect={toggle}")
    cmd += [str(simulate), str(SCENE), "--set-file", str(kernels), "--quiet"] + extra
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True,
                   timeout=3600)
    text = subprocess.run(["callgrind_annotate", str(out)], capture_output=True, text=True,
                          check=True).stdout
    m = re.search(r"([\d,]+)\s+\(100\.0%\)\s+PROGRAM TOTALS", text)
    return int(m.group(1).replace(",", ""))


def measure(simulate, extra, gen):
    none = kernel_file(0, False, gen)
    swinging = kernel_file(1000, "swinging", gen)
    with tempfile.TemporaryDirectory() as work:
        row = {}
        for key, toggle in (("advance", "threshing_sim::advancePast*"), ("whole", None)):
            row[key + "_0"] = callgrind(simulate, none, extra, toggle, work)
            row[key + "_1000"] = callgrind(simulate, swinging, extra, toggle, work)
    return row


def spaced(n):
    return f"{n:,}".replace(",", " ")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--simulate", default=str(SIMULATE), help="simulate binary (after)")
    ap.add_argument("--before", help="simulate binary of the reference (before)")
    ap.add_argument("--extra", default="", help="more simulate arguments (space separated)")
    args = ap.parse_args()
    extra = args.extra.split()
    gen = tempfile.mkdtemp(prefix="swing_gen_")
    runs = ([("before", args.before)] if args.before else []) + [("after", args.simulate)]
    print("| simulate | advancePast, no kernels | advancePast, 1000 swinging | ratio "
          "| whole process, no kernels | whole process, 1000 swinging | ratio |")
    print("|---|---|---|---|---|---|---|")
    for label, binary in runs:
        r = measure(binary, extra, gen)
        print(f"| {label} | {spaced(r['advance_0'])} | {spaced(r['advance_1000'])} "
              f"| {r['advance_1000'] / r['advance_0']:.1f} | {spaced(r['whole_0'])} "
              f"| {spaced(r['whole_1000'])} | {r['whole_1000'] / r['whole_0']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
