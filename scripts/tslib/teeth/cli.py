"""scripts/compare_teeth.py's command line: the sweep, the controls, the report and findings."""
from tslib import schema
import argparse
import os
import pathlib
import shutil
import time

from tslib import ROOT
from tslib.binaries import find_binary
from tslib.teeth.analysis import analyse
from tslib.teeth.cases import (CASES, CONVERGENCE_MODES, FLEXIBLE, FROZEN_CASES, HISTORY_RPM,
                               LARGE_DEFLECTION, RPM_FULL, RPM_QUICK, ToothRun, VARIANTS, run_all,
                               tooth_frequencies)
from tslib.teeth.findings import write_findings
from tslib.teeth.plots import make_plots
from tslib.teeth.report import write_comparison
from tslib.teeth.summary import write_summary


def main(doc=None):
    """scripts/compare_teeth.py; doc: its --help text (the entry point's docstring)."""
    parser = argparse.ArgumentParser(description=doc,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--simulate", help="path of the built simulate binary "
                        "(default: .build/ws/devel/lib/threshing_sim/simulate)")
    parser.add_argument("--out", default=str(ROOT / "out/compare"),
                        help="output folder (default: out/compare)")
    parser.add_argument("--rpm", type=int, nargs="+", help="drum speeds [rpm] "
                        f"(default {RPM_FULL[0]}-{RPM_FULL[-1]} by 100; --quick: {RPM_QUICK})")
    parser.add_argument("--jobs", type=int, default=os.cpu_count(),
                        help="parallel simulations (default: the number of cores)")
    parser.add_argument("--quick", action="store_true",
                        help="tiny sweep: rigid and polyurethane teeth, two speeds, a "
                        "two-kernel stream, no convergence check")
    parser.add_argument("--findings", action="store_true",
                        help="also write docs/findings.md, docs/findings/*.png and the "
                        "findings section of docs/threshing_findings.md")
    parser.add_argument("--docs", default=str(ROOT / "docs"),
                        help="folder of findings.md and findings/ (default: docs)")
    parser.add_argument("--summary", "--readme", dest="summary",
                        help="page whose findings section --findings rewrites "
                        "(default: docs/threshing_findings.md)")
    parser.add_argument("--reuse", action="store_true",
                        help="keep the runs already in OUT/runs and run only the missing ones "
                        "(to redo the report; the default reruns everything)")
    args = parser.parse_args()

    simulate = find_binary("simulate", args.simulate)
    schema.use(simulate)
    out = pathlib.Path(args.out)
    rpms = sorted(args.rpm or (RPM_QUICK if args.quick else RPM_FULL))
    variants = ["rigid", "polyurethane"] if args.quick else VARIANTS
    history_rpm = HISTORY_RPM if HISTORY_RPM in rpms else rpms[0]
    if not args.reuse:
        shutil.rmtree(out / "runs", ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)

    # The sweep, the frozen-tooth controls and the modal convergence check.
    runs = [ToothRun(out, "sweep", c, v, r, forces=r == history_rpm, quick=args.quick)
            for c in CASES for v in variants for r in rpms]
    runs += [ToothRun(out, "frozen", c, v, r, modes=0)
             for c in FROZEN_CASES for v in variants if v != "rigid" for r in rpms]
    if not args.quick:
        runs += [ToothRun(out, "convergence", "single_strike", v, history_rpm, modes=m)
                 for v in FLEXIBLE for m in CONVERGENCE_MODES]
        runs += [ToothRun(out, "euler_bernoulli", c, v, history_rpm, rotation="euler_bernoulli")
                 for c in FROZEN_CASES for v in FLEXIBLE]
        runs += [ToothRun(out, "modal", c, v, history_rpm, model="modal")
                 for c, teeth in LARGE_DEFLECTION.items() for v in teeth]
    print(f"compare_teeth: {len(runs)} simulations on {args.jobs} workers -> {out}", flush=True)
    started = time.monotonic()
    run_all(runs, simulate, args.jobs, args.reuse)
    wall_s = time.monotonic() - started
    freqs = {v: tooth_frequencies(simulate, v, rpms) for v in variants if v != "rigid"}

    # Numbers, plots, report, findings.
    sample_us = 1e6 * runs[0].summary()["outcomes"]["sample_interval_s"]
    a = analyse(runs, sample_us)
    plots = make_plots(out, runs, a, freqs, rpms, history_rpm)
    write_comparison(out, a, len(runs), rpms, plots)
    print(f"compare_teeth: wrote {out / 'report.md'} and {len(plots)} plots")
    if args.findings:
        docs = pathlib.Path(args.docs)
        figures = docs / "findings"
        figures.mkdir(parents=True, exist_ok=True)
        for name, _ in plots:
            shutil.copy(out / name, figures / name)
        write_findings(docs / "findings.md", a, plots, rpms, history_rpm)
        page = write_summary(args.summary, docs, a, rpms, len(runs), args.jobs, wall_s)
        print(f"compare_teeth: wrote {docs / 'findings.md'}, {figures}/ and the findings "
              f"section of {page}")
    return 0
