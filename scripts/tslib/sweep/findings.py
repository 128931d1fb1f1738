"""The findings report (compare_teeth.py's) from a sweep of config/sweeps/findings.yaml.

The runs are the same simulate invocations as compare_teeth.py's (same resolved scenes and
outputs); each run's kept files (summary, outcomes, events, forces at 800 rpm) are in
OUT/files/KEY/. compare_teeth.py's own analysis, plots, report and findings page are applied to
them, so the verdicts and figures are those of `compare_teeth.py --findings`.
"""
import json
import pathlib
import shutil
import sys

from tslib import ROOT

from . import spec as spec_module


def _compare_teeth():
    sys.path.insert(0, str(ROOT / "scripts"))
    import compare_teeth
    return compare_teeth


def sweep_runs(out, rows, ct):
    """compare_teeth.Run objects whose folders are the sweep's kept files."""
    runs = []
    for row in rows:
        if row["status"] != "ok":
            raise spec_module.SweepError(f"{out}: run {row['run']} ({row['group']} "
                                         f"{row['case']} {row['tooth']}) did not end ok: "
                                         f"{row['status']} {row['message']}")
        group = row["group"]
        modes = int(row["modes"]) if row.get("modes") else (0 if group == "frozen" else None)
        rotation = "euler_bernoulli" if group == "euler_bernoulli" else None
        model = "modal" if group == "modal" else None
        run = ct.Run(out, group, row["case"], row["tooth"], int(float(row["drum_speed_rpm"])),
                     modes=modes, rotation=rotation, model=model)
        run.dir = out / "files" / row["key"]
        if not (run.dir / "summary.json").is_file():
            raise spec_module.SweepError(f"{run.dir}: no kept files for run {row['run']}")
        run.forces = (run.dir / "forces.csv").is_file()
        runs.append(run)
    return runs


def write(out, sweep, rows, simulate, findings=False, docs=None, readme=None):
    """OUT/report.md and its plots; with findings, also docs/findings.md, docs/findings/*.png
    and the findings section of docs/threshing_findings.md (as compare_teeth.py --findings)."""
    ct = _compare_teeth()
    runs = sweep_runs(out, rows, ct)
    rpms = sorted({r.rpm for r in runs if r.group == "sweep"})
    history_rpm = ct.HISTORY_RPM if ct.HISTORY_RPM in rpms else rpms[0]
    variants = [v for v in ct.VARIANTS if any(r.variant == v for r in runs)]
    freqs = {v: ct.tooth_frequencies(simulate, v, rpms) for v in variants if v != "rigid"}
    sample_us = 1e6 * runs[0].summary()["outcomes"]["sample_interval_s"]
    a = ct.analyse(runs, sample_us)
    plots = ct.make_plots(out, runs, a, freqs, rpms, history_rpm)
    ct.write_comparison(out, a, len(runs), rpms, plots)
    if findings:
        docs = pathlib.Path(docs or ROOT / "docs")
        figures = docs / "findings"
        figures.mkdir(parents=True, exist_ok=True)
        for name, _ in plots:
            shutil.copy(out / name, figures / name)
        ct.write_findings(docs / "findings.md", a, plots, rpms, history_rpm)
        # The last `scripts/sweep run`'s workers and wall time (run_stats.json).
        stats = json.loads((out / "run_stats.json").read_text()) \
            if (out / "run_stats.json").is_file() else {}
        workers = stats.get("workers") or len({r["worker"] for r in rows})
        wall_s = stats.get("wall_s", sum(float(r["wall_s"]) for r in rows) / workers)
        ct.write_summary(readme, docs, a, rpms, len(runs), workers, wall_s)
    return out / "report.md"

