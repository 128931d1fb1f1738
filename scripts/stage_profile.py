#!/usr/bin/python3
"""Instructions per stage of the stepping loop, by callgrind (issue 22, item 1).

Runs `valgrind --tool=callgrind` on `simulate` for three cases:

- the default single strike (config/default_scene.yaml, event-driven, tolerance 1e-6, 10 ms);
- the 100-kernel bench stream (config/bench/stream.yaml, island scheme, event-driven,
  tolerance 1e-6, its 2 ms);
- the 1000-kernel stream with 10 kernels in reach (the same settings; kernel files of
  `scripts/bench.py --stream-kernels N [--sparse 10]`, as scripts/bench.py --part islands runs
  them),

reads the call graph of each profile and prints a markdown table: the inclusive instructions of
every stage of STAGES (the one table that maps function names to stages), per run, per contact
event (impacts of the simulate summary) and per integrator step (island steps on the island
scheme, steps on the global one).

Each case runs twice under callgrind: whole (the whole run; the model set-up, loadScene) and
collecting inside advanceTo only (the stepping loop and every other stage). A stage's inclusive
count is the sum over the calls that enter the stage from outside it (caller not in the stage,
callee in it) of the calls' inclusive costs, read from the raw callgrind file: the inclusive
figures of `callgrind_annotate --inclusive=yes` count a stage twice where two of its functions
call each other. Recursive activations (callgrind's name'2) are inside their stage; a stage
entered again through a function of another stage is counted twice. Stages nest (the
right-hand side holds the narrow phase and the contact forces), so the rows do not add up to
the total. The totals and advanceTo's count are checked against callgrind_annotate's, and
advanceTo of the whole run against the stepping-only profile.

    python3 scripts/stage_profile.py                  # prints the table
    python3 scripts/stage_profile.py --docs           # and splices it into docs/bench_islands.md
    python3 scripts/stage_profile.py --simulate OTHER/simulate --docs --section stage-profile-before

scripts/bench.py --part islands runs the same code (scripts/tslib/bench/stages.py: cases(),
profile(), table()) with its own kernel files; run alone, this script runs
`scripts/bench.py --stream-kernels` for the kernel files.
"""
import argparse
import shutil
import sys
import tempfile

from tslib import ROOT, markdown
from tslib.bench.stages import cases, profile, splice_docs, stream_kernel_file, table
from tslib.binaries import find_binary


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--simulate", help="simulate binary (default: the workspace's)")
    ap.add_argument("--keep", help="keep the callgrind files and summaries in this folder")
    ap.add_argument("--reuse", help="tabulate the files an earlier --keep left (no valgrind)")
    ap.add_argument("--only", help="comma-separated cases (strike, stream100, stream1000)")
    ap.add_argument("--docs", action="store_true", help="splice into docs/bench_islands.md")
    ap.add_argument("--section", default="stage-profile", help="marker pair to splice into")
    args = ap.parse_args()
    if shutil.which("valgrind") is None and not args.reuse:
        raise SystemExit("stage_profile: valgrind is not installed")
    simulate = find_binary("simulate", args.simulate)
    with tempfile.TemporaryDirectory() as gen:
        case_list = cases(lambda n, sparse: stream_kernel_file(gen, n, sparse))
        if args.only:
            case_list = [c for c in case_list if c[0] in args.only.split(",")]
        results = profile(simulate, case_list, keep=args.keep, reuse=args.reuse,
                          say=lambda s: print(s, file=sys.stderr))
    text = table(results)
    print(text)
    if args.docs:
        path = ROOT / "docs/bench_islands.md"
        if args.section == "stage-profile":
            splice_docs(text, path)
        else:
            markdown.splice(args.section, text, path)
        print(f"stage_profile: wrote section {args.section} of {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
