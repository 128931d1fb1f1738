"""Plots (PNG) and a markdown report from a sweep's table (OUT/runs.csv).

Plots come from the sweep file's `report.plots` list, or by default one per outcome against
the first numeric axis. A line plot {y, x, lines, bands} draws the mean of y against x, one line
per value of `lines`, with a band from the smallest to the largest value over everything else
(the seeds, and the axes named in `bands` or not named at all). A Pareto plot
{pareto: {x, y}, color} shows every configuration (mean over the seeds) and marks those that no
other beats on both (x larger, y smaller: more threshing, less damage).
"""
import csv
import math
import pathlib

from tslib import plots
from tslib.numbers import fmt4

from . import spec as spec_module

pyplt = plots.pyplot()  # matplotlib.pyplot, Agg backend

CYCLE_COLORS = pyplt.rcParams["axes.prop_cycle"].by_key()["color"]
MARKERS = "osv^D<>phX*"


def _parse_number(text):
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def load_table(out):
    with open(out / "runs.csv", newline="") as f:
        return list(csv.DictReader(f))


def _numeric(rows, column):
    return all(_parse_number(r.get(column)) is not None for r in rows if r.get(column, "") != "")


def _order(rows, column):
    """Values of a column in first-seen order (the sweep's order)."""
    seen = []
    for r in rows:
        if r[column] not in seen:
            seen.append(r[column])
    return seen


def _key(value):
    number = _parse_number(value)
    return (0, number, "") if number is not None else (1, 0.0, value)


def line_plot(rows, plot, path, axes):
    """Mean of y against x per line value, band over the rest; returns a summary table."""
    x, y, lines = plot["x"], plot["y"], plot.get("lines")
    fig, ax = pyplt.subplots(figsize=(7.5, 4.5))
    summary = []
    groups = _order(rows, lines) if lines else [None]
    for i, group in enumerate(groups):
        chosen = [r for r in rows if lines is None or r[lines] == group]
        by_x = {}
        for r in chosen:
            value = _parse_number(r.get(y))
            if value is not None and _parse_number(r[x]) is not None:
                by_x.setdefault(_parse_number(r[x]), []).append(value)
        if not by_x:
            continue
        xs = sorted(by_x)
        mean = [sum(by_x[v]) / len(by_x[v]) for v in xs]
        lo = [min(by_x[v]) for v in xs]
        hi = [max(by_x[v]) for v in xs]
        color = CYCLE_COLORS[i % len(CYCLE_COLORS)]
        ax.plot(xs, mean, marker=MARKERS[i % len(MARKERS)], color=color, markersize=4,
                label=str(group) if lines else y)
        if any(h > l for l, h in zip(lo, hi)):
            ax.fill_between(xs, lo, hi, color=color, alpha=0.15 if len(groups) <= 4 else 0.06,
                            linewidth=0)
        summary.append((group, min(lo), max(hi), sum(len(v) for v in by_x.values())))
    spread = [a for a in axes if a not in (x, lines)]
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(f"{y} against {x}" + (f", per {lines}" if lines else ""), fontsize=10)
    if spread:
        ax.text(0.01, 0.01, f"line: mean; band: min-max over {', '.join(spread)}",
                transform=ax.transAxes, fontsize=7, color="0.35")
    ax.grid(alpha=0.3)
    if lines:
        ax.legend(fontsize=7, ncol=2 if len(groups) > 5 else 1)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    pyplt.close(fig)
    return summary


def pareto_front(points):
    """Indices of the points no other point beats: x at least as large and y at least as
    small, one of them strictly."""
    front = []
    for i, (xi, yi) in enumerate(points):
        if not any((xj >= xi and yj <= yi) and (xj > xi or yj < yi)
                   for j, (xj, yj) in enumerate(points) if j != i):
            front.append(i)
    return front


def pareto_plot(rows, plot, path, axes):
    """Every configuration (mean over the seeds); returns the front's configurations."""
    x, y = plot["pareto"]["x"], plot["pareto"]["y"]
    color = plot.get("color")
    config_axes = [a for a in axes if a != "seed"]
    configs = {}
    for r in rows:
        vx, vy = _parse_number(r.get(x)), _parse_number(r.get(y))
        if vx is None or vy is None:
            continue
        configs.setdefault(tuple(r[a] for a in config_axes), []).append((vx, vy))
    names = list(configs)
    points = [(sum(p[0] for p in configs[n]) / len(configs[n]),
               sum(p[1] for p in configs[n]) / len(configs[n])) for n in names]
    front = pareto_front(points)
    fig, ax = pyplt.subplots(figsize=(7.5, 4.5))
    groups = _order(rows, color) if color else [None]
    for i, group in enumerate(groups):
        chosen = [k for k, n in enumerate(names)
                  if color is None or n[config_axes.index(color)] == group]
        ax.scatter([points[k][0] for k in chosen], [points[k][1] for k in chosen], s=14,
                   color=CYCLE_COLORS[i % len(CYCLE_COLORS)], marker=MARKERS[i % len(MARKERS)],
                   alpha=0.7, label=str(group) if color else None)
    ordered = sorted(front, key=lambda k: points[k][0])
    ax.plot([points[k][0] for k in ordered], [points[k][1] for k in ordered], "k--", lw=1)
    ax.scatter([points[k][0] for k in ordered], [points[k][1] for k in ordered], s=60,
               facecolors="none", edgecolors="k", linewidths=1, label="Pareto front")
    ax.set_xlabel(f"{x} (more is better)")
    ax.set_ylabel(f"{y} (less is better)")
    ax.set_title(f"{y} against {x}: {len(names)} configurations, {len(front)} on the front",
                 fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    pyplt.close(fig)
    return [(dict(zip(config_axes, names[k])), points[k]) for k in ordered]


def default_plots(rows, axes, outcomes):
    numeric_axes = [a for a in axes if a != "seed" and _numeric(rows, a)]
    other = [a for a in axes if a != "seed" and a not in numeric_axes[:1]]
    if not numeric_axes:
        return []
    lines = other[0] if other else None
    return [{"y": y, "x": numeric_axes[0], "lines": lines} for y in outcomes
            if _numeric(rows, y)]


def write_report(out, sweep_path=None, simulate=None, **findings_options):
    """Writes OUT/report.md and its plots OUT/plot_*.png; returns the report's path. A sweep
    whose report kind is `findings` gets compare_teeth.py's report (tslib.sweep.findings)."""
    out = pathlib.Path(out)
    if sweep_path is None:
        recorded = out / "sweep_file.txt"
        if not recorded.is_file():
            raise spec_module.SweepError(f"{out}: no sweep_file.txt; pass --sweep FILE")
        sweep_path = recorded.read_text().strip()
    sweep = spec_module.Sweep(sweep_path)
    rows = load_table(out)
    if not rows:
        raise spec_module.SweepError(f"{out / 'runs.csv'}: no runs")
    if sweep.report.get("kind") == "findings":
        from . import findings
        return findings.write(out, sweep, rows, simulate, **findings_options)
    axes = sweep.axis_columns()
    columns = list(sweep.outcomes) + list(sweep.derived)
    plots = sweep.report.get("plots") or default_plots(rows, axes, columns)
    for i, plot in enumerate(plots):
        names = ([plot["pareto"]["x"], plot["pareto"]["y"], plot.get("color")]
                 if "pareto" in plot else [plot.get("x"), plot.get("y"), plot.get("lines")])
        for name in names:
            if name is not None and name not in rows[0]:
                raise spec_module.SweepError(f"{sweep.path}: report.plots[{i}]: no column "
                                             f"'{name}' in the table ({', '.join(rows[0])})")
    ok = [r for r in rows if r["status"] == "ok"]
    statuses = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    cpu = sum(_parse_number(r["cpu_s"]) or 0.0 for r in rows)
    lines = [f"# Sweep report: {sweep.name}", "",
             f"Generated by `scripts/sweep report {out}` from `{out / 'runs.csv'}` (sweep file "
             f"`{sweep.path}`). {len(rows)} runs: "
             + ", ".join(f"{n} {s}" for s, n in sorted(statuses.items())) +
             f"; the runs' own CPU time {cpu:.1f} s.", "",
             "Axes: " + "; ".join(f"{a.column()} ({len(a.labels)} values: "
                                  f"{', '.join(map(str, a.labels[:12]))}"
                                  f"{', ...' if len(a.labels) > 12 else ''})"
                                  for a in sweep.all_axes())
             + (f"; seeds {sweep.seeds[2][0]}-{sweep.seeds[2][-1]} ({sweep.seeds[1]})"
                if sweep.seeds else "") + ".", ""]
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        lines += ["## Runs that did not end ok", "", "| run | " + " | ".join(axes) +
                  " | status | message |", "|---" * (len(axes) + 3) + "|"]
        lines += [f"| {r['run']} | " + " | ".join(r[a] for a in axes) +
                  f" | {r['status']} | {r['message'][:200].replace('|', '/')} |"
                  for r in failed[:30]]
        if len(failed) > 30:
            lines.append(f"\n... and {len(failed) - 30} more (runs.csv).")
        lines.append("")
    lines += ["## Plots", ""]
    for i, plot in enumerate(plots):
        if "pareto" in plot:
            name = f"plot_{i}_pareto_{plot['pareto']['y']}_{plot['pareto']['x']}.png"
            front = pareto_plot(ok, plot, out / name, axes)
            lines += [f"### Pareto: {plot['pareto']['y']} against {plot['pareto']['x']}", "",
                      f"![pareto]({name})", "",
                      "Configurations on the front (mean over the seeds):", "",
                      "| " + " | ".join(list(front[0][0]) if front else ["-"]) +
                      f" | {plot['pareto']['x']} | {plot['pareto']['y']} |",
                      "|---" * ((len(front[0][0]) if front else 1) + 2) + "|"]
            lines += ["| " + " | ".join(c.values()) + f" | {fmt4(p[0])} | {fmt4(p[1])} |"
                      for c, p in front[:20]]
        else:
            name = f"plot_{i}_{plot['y']}_vs_{plot['x']}.png"
            summary = line_plot(ok, plot, out / name, axes)
            lines += [f"### {plot['y']} against {plot['x']}", "", f"![{plot['y']}]({name})",
                      "", f"| {plot.get('lines') or 'all'} | min | max | runs |",
                      "|---|---|---|---|"]
            lines += [f"| {g if g is not None else 'all'} | {fmt4(lo)} | {fmt4(hi)} | {n} |"
                      for g, lo, hi, n in summary]
        lines.append("")
    if sweep.report.get("stream_statistics") is not None:
        from . import stats
        lines += stats.stream_section(out, sweep)
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
