#!/usr/bin/python3
"""Callgrind instruction counts and CPU times of a sweep's validation and runs in one process
(docs/sweeps.md, "Overhead").

Writes the `simulate --check-batch` lines of every combination of the sweep (default: the
1000 single strikes of config/sweeps/single_strike_1000.yaml), runs them in one
`simulate --check-batch` process under valgrind's callgrind, and prints the instructions of
the whole process and (inclusive) of the model build and its parts, for each binary given.
With --cpu N it then runs, N times in turn for each binary, the validation and all the runs
in one `simulate --batch` process (the runner's lines: base scenes and --set values) and prints
the medians of their CPU time (user + system, wait4):

  scripts/profile_sweep_check.py [--sweep SWEEP.yaml] [--simulate A [B ...]] [--cpu N]
"""
import argparse
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # tslib
from tslib import ROOT  # noqa: E402

from tslib.sweep import runner, spec, task  # noqa: E402

# (label, regular expression of callgrind_annotate's function name)
PARTS = [
    ("modelFromYaml (scene -> compiled model)", r"threshing_sim::modelFromYaml\("),
    ("compileModel", r"threshing_sim::compileModel\("),
    ("compileTooth (modes, K_G, H, mode table)", r"threshing_sim::compileTooth\("),
    ("compileResidual (static flexibility table)", r"threshing_sim::compileResidual\("),
]


def check_batch_instructions(simulate, lines_path, work):
    """{label: instructions} of simulate --check-batch on the lines, and the total."""
    out = pathlib.Path(work) / "callgrind.out"
    proc = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                           str(simulate), "--check-batch", str(lines_path)],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          timeout=3600)
    total = re.search(r"Collected : (\d+)", proc.stderr)
    if total is None:
        raise SystemExit(f"callgrind of {simulate} failed:\n{proc.stderr[-2000:]}")
    annotated = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100",
                                str(out)], capture_output=True, text=True, timeout=600).stdout
    counts = {"total": int(total.group(1))}
    for label, pattern in PARTS:
        counts[label] = 0
        for line in annotated.splitlines():
            if re.search(pattern, line):
                counts[label] = int(line.split()[0].replace(",", ""))
                break
    return counts


def cpu_seconds(command, stdin_path):
    """User + system time of the command (wait4) [s], its output discarded."""
    with open(stdin_path) as stdin:
        proc = subprocess.Popen(command, stdin=stdin, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
    if os.waitstatus_to_exitcode(status) not in (0, 1):  # 1: some run failed (a result)
        raise SystemExit(f"{command} failed ({status})")
    return usage.ru_utime + usage.ru_stime


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sweep", default=str(ROOT / "config/sweeps/single_strike_1000.yaml"))
    parser.add_argument("--simulate", nargs="+", help="simulate binaries (default: the built "
                        "one)")
    parser.add_argument("--cpu", type=int, default=0, help="also the CPU time medians of N "
                        "runs of the validation and of all the runs in one process")
    args = parser.parse_args()
    binaries = args.simulate or [runner.resolve_simulate(None, ROOT)]
    runs = spec.Sweep(args.sweep).runs()
    with tempfile.TemporaryDirectory() as work:
        lines = pathlib.Path(work) / "lines.txt"
        lines.write_text("".join("\t".join(r.arguments) + "\n" for r in runs))
        print(f"simulate --check-batch on the {len(runs)} combinations of "
              f"{pathlib.Path(args.sweep).resolve().relative_to(ROOT)}, callgrind "
              f"(instructions, inclusive):\n")
        results = [check_batch_instructions(b, lines, work) for b in binaries]
        print("| | " + " | ".join(str(b) for b in binaries) + " |")
        print("|---|" + "---|" * len(binaries))
        for label in ["total"] + [label for label, _ in PARTS]:
            cells = [f"{r[label] / 1e9:.2f} G ({100 * r[label] / r['total']:.0f} %)"
                     for r in results]
            print(f"| {label} | " + " | ".join(cells) + " |")
        if args.cpu > 0:
            sweep = spec.Sweep(args.sweep)
            spec.validate(sweep, runs, binaries[0], runner.binary_sha(binaries[0]), jobs=1)
            batch = pathlib.Path(work) / "batch.jsonl"
            batch.write_text("".join(task._batch_line({"key": r.key, **runner._scene_of(r),
                                                        "keep": r.keep}) for r in runs))
            times = {(b, kind): [] for b in binaries for kind in ("check", "batch")}
            for _ in range(args.cpu):
                for b in binaries:
                    times[b, "check"].append(cpu_seconds([str(b), "--check-batch", "-"], lines))
                    times[b, "batch"].append(cpu_seconds([str(b), "--batch", "-"], batch))
            print(f"\nCPU time (user + system), median of {args.cpu}, load average "
                  f"{' '.join(f'{x:.2f}' for x in os.getloadavg())} at the end:\n")
            print("| | " + " | ".join(str(b) for b in binaries) + " |")
            print("|---|" + "---|" * len(binaries))
            for kind, label in (("check", "simulate --check-batch, all combinations"),
                                ("batch", "simulate --batch, all runs")):
                cells = [f"{statistics.median(times[b, kind]):.3f} s" for b in binaries]
                print(f"| {label} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
