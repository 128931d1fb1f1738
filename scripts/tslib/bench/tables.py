"""The benchmark's tables, targets and pages (docs/bench.md, the sections of
docs/benchmarks.md) and its CSV files."""
import csv

from tslib import DOCS, markdown
from tslib.bench.config import (BENCH_CMD, HEADLINE, INTEGRATOR_STYLE, METRICS, METRIC_LABELS,
                                NODE_RTF_PASS, NODE_SETTINGS)
from tslib.bench.measure import fit_slope
from tslib.numbers import fmt


def orders(rows, names):
    """Fitted slopes: log error against log knob, per scene and integrator (headline, exit v)."""
    out = {}
    for name in names:
        for integrator in INTEGRATOR_STYLE:
            sel = [r for r in rows if r["scene"] == name and r["integrator"] == integrator]
            out[(name, integrator)] = {
                m: fit_slope([r["knob"] for r in sel], [r[m] for r in sel])
                for m in ("headline", "exit_velocity", "pose", "impulse")}
    return out


def scaling_exponents(rows):
    out = {}
    for integrator in INTEGRATOR_STYLE:
        k = sorted((r["n"], r["wall_per_sim_s"]) for r in rows
                   if r["series"] == "kernels" and r["integrator"] == integrator)
        idle = sorted((r["n"], r["wall_per_sim_s"]) for r in rows
                      if r["series"] == "idle kernels" and r["integrator"] == integrator)
        m = sorted((r["n"], r["wall_per_sim_s"]) for r in rows
                   if r["series"] == "modes" and r["integrator"] == integrator and r["n"] > 0)
        out[integrator] = {
            "kernels": fit_slope([p[0] for p in k], [p[1] for p in k]),
            "kernels_10_up": fit_slope([p[0] for p in k if p[0] >= 10],
                                       [p[1] for p in k if p[0] >= 10]),
            "idle": fit_slope([p[0] for p in idle], [p[1] for p in idle]),
            "idle_10_up": fit_slope([p[0] for p in idle if p[0] >= 10],
                                    [p[1] for p in idle if p[0] >= 10]),
            "modes": fit_slope([p[0] for p in m], [p[1] for p in m])}
    return out


def dominant(sel):
    """Which of the four headline metrics is the largest, counted over the points."""
    counts = {}
    for r in sel:
        m = max(HEADLINE, key=lambda k: r[k])
        counts[m] = counts.get(m, 0) + 1
    return ", ".join(f"{METRIC_LABELS[m]} ({c} of {len(sel)})"
                     for m, c in sorted(counts.items(), key=lambda kv: -kv[1]))


def best_at(rows, name, integrator, max_wall_per_sim):
    """Smallest headline error among the points at least as fast as the given cost."""
    sel = [r for r in rows if r["scene"] == name and r["integrator"] == integrator
           and r["wall_per_sim_s"] <= max_wall_per_sim]
    return min(sel, key=lambda r: r["headline"]) if sel else None


def table_all_points(rows):
    """docs/bench.md: every point with every metric."""
    lines = ["| scene | integrator | knob | real-time factor | headline error | exit velocity | "
             "final pose | peak normal | peak tangential | normal impulse | impacts ± | "
             "tip RMS |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['integrator'].replace('_', '-')} | {r['knob']:g} | "
            f"{fmt(r['real_time_factor'], 3)} | **{fmt(r['headline'])}** | " +
            " | ".join(fmt(r[m]) for m in METRICS) + " |")
    return "\n".join(lines)


def table_compact(rows, names, ords):
    """Per scene and integrator: the fastest point and the best error at >= 1x and >= 20x."""
    compact = ["| scene | integrator | fastest point: real-time factor, headline error | "
               "best error at ≥ 1× real time | best error at ≥ 20× real time | "
               "slope of log error on log knob (headline / exit velocity) | headline set by |",
               "|---|---|---|---|---|---|---|"]
    for name in names:
        for integrator in INTEGRATOR_STYLE:
            sel = [r for r in rows if r["scene"] == name and r["integrator"] == integrator]
            if not sel:
                continue
            fastest = min(sel, key=lambda r: r["wall_per_sim_s"])
            cells = []
            for limit in (1.0, 0.05):
                b = best_at(rows, name, integrator, limit)
                cells.append(f"{fmt(b['headline'])} (knob {b['knob']:g}, "
                             f"{fmt(b['real_time_factor'], 3)}×)" if b else "none that fast")
            o = ords[(name, integrator)]
            compact.append(
                f"| {name} | {integrator.replace('_', '-')} | {fmt(fastest['real_time_factor'], 3)}×, "
                f"{fmt(fastest['headline'])} (knob {fastest['knob']:g}) | {cells[0]} | {cells[1]} | "
                f"{fmt(o['headline'])} / {fmt(o['exit_velocity'])} | {dominant(sel)} |")
    return "\n".join(compact)


def table_references(refs, names):
    """Each scene's reference against its cross-check and against more tooth modes."""
    lines = ["| scene | modes | reference | cross-check | agreement: exit velocity | "
             "pose | peak normal | peak tangential | impulse | impacts ± | tip RMS | "
             "change with more modes (headline; exit velocity) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        r = refs[name]
        a = r["agreement"]
        mc = "; ".join(f"{r['modes']}→{r['modes'] + int(k[6:])}: {fmt(e['headline'])}; "
                       f"{fmt(e['exit_velocity'])}" for k, e in r["mode_change"].items()) or "rigid"
        lines.append(
            f"| {name} | {r['modes']} | event-driven {r['ed']['tolerance']:g} | time stepping "
            f"{r['ts']['dt_s']:g} | " + " | ".join(fmt(a[m]) for m in METRICS) + f" | {mc} |")
    return "\n".join(lines)


def _cost_cells(r):
    if r is None:
        return "–", "–"
    cut = "" if r["completed"] else f" (cut short at {r['sim_time_s'] * 1e3:.2g} ms)"
    return fmt(r["wall_per_sim_s"], 3) + cut, fmt(r["real_time_factor"], 3)


def table_scaling(scal):
    """Cost per simulated second against kernels, idle kernels and modes, both integrators."""
    lines = ["| series | n | event-driven 1e-6: wall / sim s | real-time factor | "
             "time stepping 1e-6: wall / sim s | real-time factor | kernels struck (ED; TS) |",
             "|---|---|---|---|---|---|---|"]
    for series in ("kernels", "idle kernels", "modes"):
        for n in sorted({r["n"] for r in scal if r["series"] == series}):
            ed, ts = (next((r for r in scal if r["series"] == series and r["n"] == n
                            and r["integrator"] == i), None)
                      for i in ("event_driven", "time_stepping"))
            struck = ("; ".join(str(r["kernels_with_impacts"]) if r else "–" for r in (ed, ts))
                      if series != "modes" else "–")
            lines.append(f"| {series} | {n} | " + " | ".join(_cost_cells(ed)) + " | " +
                         " | ".join(_cost_cells(ts)) + f" | {struck} |")
    return "\n".join(lines)


def text_exponents(scal):
    ex = scaling_exponents(scal) if scal else {}
    return "; ".join(
        f"{i.replace('_', '-')}: cost ∝ kernels^{fmt(e['kernels'], 3)} "
        f"(10–1000: ^{fmt(e['kernels_10_up'], 3)}), idle kernels^{fmt(e['idle'], 3)} "
        f"(10–1000: ^{fmt(e['idle_10_up'], 3)}), ∝ modes^{fmt(e['modes'], 3)} (1–8 modes)"
        for i, e in ex.items())


def text_node(node, cfg):
    """The node's budget: per setting, the real-time factor at each kernel count tried."""
    if not node:
        return "Node budget: not measured in this run (node not built or --no-node)."
    parts = []
    for label in NODE_SETTINGS:
        tried = [n for n in node if n.get("setting") == label]
        if not tried:
            continue
        passing = [n for n in tried if n["rtf"] >= NODE_RTF_PASS]
        parts.append(f"{label}: real-time factor " +
                     ", ".join(f"{n['rtf']:.3g} with {n['n']} kernel"
                               f"{'s' if n['n'] > 1 else ''}" for n in tried) +
                     f"; largest count kept at ≥ {NODE_RTF_PASS}: "
                     f"**{passing[-1]['n'] if passing else 'none (not even 1 kernel)'}**")
    return ("Node budget (`threshing_sim_node` on the stream scene at real-time factor 1, "
            f"wall clock, {cfg['node_duration']:g} s simulated; measured real-time "
            "factor from its final summary, `node_budget.csv`): " + "; ".join(parts) + ".")


def targets_single_strike(rows, ords):
    """The single strike's accuracy-at-speed targets and the measured orders."""
    ss = [r for r in rows if r["scene"] == "single_strike"]
    if not ss:
        return []
    t = []
    for integrator, goal in (("event_driven", 1e-6), ("time_stepping", 1e-2)):
        b = best_at(rows, "single_strike", integrator, 0.05)
        best = min((r for r in ss if r["integrator"] == integrator),
                   key=lambda r: r["headline"], default=None)
        fast_ok = [r for r in ss if r["integrator"] == integrator and r["headline"] <= goal]
        fastest_ok = max(fast_ok, key=lambda r: r["real_time_factor"]) if fast_ok else None
        t.append(f"- single strike, {integrator.replace('_', '-')}: target error ≤ {goal:g} "
                 f"at ≥ 20× real time. Best error at ≥ 20×: "
                 f"{fmt(b['headline']) if b else 'no point that fast'}; fastest point meeting "
                 f"{goal:g}: " + (f"{fmt(fastest_ok['real_time_factor'], 3)}× (knob "
                                  f"{fastest_ok['knob']:g})" if fastest_ok else "none") +
                 (f"; smallest error overall {fmt(best['headline'])}" if best else "") +
                 (" — **met**" if b and b["headline"] <= goal else " — **not met**"))
    o = ords[("single_strike", "time_stepping")]
    t.append(f"- measured order of time stepping on the single strike: "
             f"{fmt(o['exit_velocity'])} (exit velocity), {fmt(o['headline'])} (headline); "
             f"event-driven error against tolerance: {fmt(ords[('single_strike', 'event_driven')]['exit_velocity'])} "
             "(exit velocity)")
    return t


def targets_references(refs, names):
    """Per scene: the cross-check's agreement and the convergence in tooth modes."""
    t = []
    for name in names:
        r = refs[name]
        a = r["agreement"]
        text = (f"- reference of {name}: time stepping at {r['ts']['dt_s']:g} agrees with it to "
                f"{fmt(a['exit_velocity'])} in exit velocity and {fmt(a['headline'])} in the "
                f"headline metrics ({a['impacts']} impacts apart)")
        for k, e in r["mode_change"].items():
            text += (f"; {r['modes']} → {r['modes'] + int(k[6:])} modes changes the exit velocity "
                     f"by {fmt(e['exit_velocity'])} and the headline metrics by "
                     f"{fmt(e['headline'])}")
        if r["mode_change"]:
            worst = max(e["exit_velocity"] for e in r["mode_change"].values())
            text += (" — exit velocity converged in modes to 1 %" if worst <= 0.01 else
                     " — exit velocity **not converged in modes** at the 1 % level")
        t.append(text)
    return t


def targets_scale(scal, node):
    """The 1000-kernel and the node's 100-kernel targets."""
    t = []
    for r in (r for r in scal if r["series"] == "kernels" and r["n"] == 1000):
        t.append(f"- 1000 kernels in `bench_work_precision` ({r['integrator'].replace('_', '-')}, "
                 f"1e-6): {fmt(r['real_time_factor'], 3)}× real time (target ≥ 0.1×) — "
                 f"**{'met' if r['real_time_factor'] >= 0.1 else 'not met'}**")
    for label in NODE_SETTINGS if node else ():
        n100 = next((n for n in node if n["n"] == 100 and n.get("setting") == label), None)
        t.append(f"- 100-kernel stream in the node ({label}): " +
                 (f"real-time factor {n100['rtf']:.3g} (target ≥ 1) — "
                  f"**{'met' if n100['rtf'] >= NODE_RTF_PASS else 'not met'}**" if n100 else
                  "not tried: a smaller count already fell behind real time — **not met**"))
    return t


def text_took(runner, elapsed_s):
    return (f"the points' processes take {runner.process_wall_s / 60:.1f} min of wall time in all "
            f"(run {runner.jobs} at a time on a shared 2-core machine); this invocation took "
            f"{elapsed_s / 60:.1f} min, running {runner.ran} points and taking {runner.cached} "
            "from the cache")


def section_bench(compact, targets, cfg, took, page):
    """The bench-table section of page (docs/benchmarks.md), links relative to it."""
    doc = markdown.link(DOCS / "bench.md", page)
    figures = markdown.link(DOCS / "bench", page)
    return f"""The sweep covers the event-driven tolerance and the time-stepping step on
every scene; each point is the median of several repetitions in one process pinned to one core
(Release), and its errors are measured against the event-driven reference at tolerance
{cfg['ref_tol']:g} (cross-checked by time stepping at a very small step, and with more tooth modes:
[`{doc}`]({doc}), "References"). The headline error is the largest relative error
of the kernel exit velocity, final pose, peak normal force and peak tangential force; the right
panel shows the exit velocity alone. Generated by `{BENCH_CMD}`: {took}. All points and metrics:
[`{doc}`]({doc}) and `docs/bench/work_precision.csv`.

![work-precision, single strike]({figures}/wp_single_strike.png)

{compact}

Targets:

{targets}
"""


def section_scaling(scal, node, cfg, figures):
    """The scaling-table section; figures: the link to docs/bench/ from its page."""
    return f"""Cost per simulated second against the number of kernels (stream scene,
`--stream-kernels N`) and of tooth modes (single strike), from the same command
(`docs/bench/scaling.csv`):

![scaling]({figures}/scaling.png)

{table_scaling(scal)}

Fitted log-log exponents: {text_exponents(scal)}.

{text_node(node, cfg)}
"""


def page_bench_md(refs, rows, names, cfg, compact, scaling_section, targets, took):
    """docs/bench.md: definitions, references, every point, scaling and targets."""
    return f"""# Work-precision benchmark

Generated by `{BENCH_CMD}`; do not edit by hand. Cost of the run: {took}.

## Definitions

Every error is relative to the event-driven reference of its scene (tolerance {cfg['ref_tol']:g}):

- exit velocity: ‖V − V_ref‖ / ‖V_ref‖ over the final velocities of all kernels stacked;
- final pose: ‖P − P_ref‖ / ‖P_ref − P_0‖ over the final positions of all kernels and their angles
  times the semi-major axis a (so the pose error is relative to how far the kernels moved);
- peak normal / tangential force: relative error of the largest normal / tangential contact force
  of the run (the core's maxima over accepted steps and located events; event-driven, a compliant
  normal force's maximum inside a step is located to the tolerance);
- normal impulse: relative error of the total normal impulse;
- impacts: absolute difference of the completed-impact count;
- tip RMS: RMS over the teeth and {cfg['samples']} fixed sample times of the tip deflection
  difference, relative to the RMS of the reference (from a separate, untimed run that lands on the
  sample times).

The headline error is the largest of the first four. Cost is the median wall time of the bare
run (reset + `advanceTo(duration)`, nothing sampled) over up to {cfg['reps']} repetitions
in one process pinned to one core, divided by the simulated time; the real-time factor is its
inverse. Every repetition must end in the bit-identical state (checked; `deterministic` in the CSV).

## References

The event-driven reference against time stepping at a very small step (the cross-check), and
against the same reference with more tooth modes (docs/model.md §9a):

{table_references(refs, names)}

## Work precision

![single strike](bench/wp_single_strike.png)
![single strike, rigid tooth](bench/wp_single_strike_rigid.png)
![knead](bench/wp_knead_polyurethane.png)
![stream](bench/wp_stream.png)

{compact}

All points:

{table_all_points(rows)}

## Scaling

{scaling_section}

## Targets

{targets}
"""


def write_tables(refs, rows, scal, node, names, cfg, elapsed_s, runner, page=None):
    """Markdown: the bench-table and scaling-table sections of page (default: their page,
    docs/benchmarks.md) and the full docs/bench.md."""
    page = page or markdown.page_of("bench-table")
    ords = orders(rows, names)
    compact = table_compact(rows, names, ords)
    targets = "\n".join(targets_single_strike(rows, ords) + targets_references(refs, names) +
                        targets_scale(scal, node))
    took = text_took(runner, elapsed_s)
    bench_section = section_bench(compact, targets, cfg, took, page)
    scaling_section = section_scaling(scal, node, cfg, markdown.link(DOCS / "bench", page))
    doc = page_bench_md(refs, rows, names, cfg, compact,
                        section_scaling(scal, node, cfg, "bench"), targets, took)
    return bench_section, scaling_section, doc


def write_csv(path, rows):
    if not rows:
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else (f"{v:.6g}" if isinstance(v, float) else v))
                        for k, v in r.items()})
