"""Kernel statistics of chaotic streams over seeds, and the stop rule that adds seeds in rounds.

A stream (a scene of many kernels meeting several teeth) is chaotic: one run's kernels are a
sample, and what converges is their distribution. The sweep file's `report.stream_statistics`
names the level axis (`modes`) and the kernel quantities; every other axis column but the seed
names a stream. For each stream and level this module gives the kernel mean of each quantity
with its standard error, the relative difference between the chosen level (the smallest value
of the level axis) and the next finer one with its standard error, and whether the stream meets
the targets (every standard error <= stop.relative_se of its mean, every difference <=
report.stream_statistics.difference).

Standard errors are cluster (batch-means) standard errors over the seeds: the kernels of one
run share the teeth (their vibration, which earlier kernels excite) and collide with each other,
and kernel k of every run is met at the same point of the stream, so they are neither
independent nor identically distributed. The runs of different seeds are independent (the
simulation is deterministic given the seed), so each run is one sample of its kernel mean. The
naive standard error (kernels as independent) is given next to it, and their squared ratio is
the design effect. Both levels of a stream run the same seeds, so the difference between levels
is a paired (per-seed) estimate; its standard error comes from the same cluster linearisation.

The stop rule (`stop:` in the sweep file, `scripts/sweep run`): seeds are added in rounds, per
stream (both levels get the same seeds), until every standard error is <= relative_se of its
mean; a round adds the seeds the current standard errors call for (at most `growth` times the
current count), as far as the budget in core-hours (the runs' own CPU time in the table,
predicted per run from the runs so far) allows. It stops on the standard error, the budget or
max_rounds, and writes OUT/stop.json; the report says which ended it.
"""
import csv
import json
import math
import pathlib
import time

from . import runner
from . import spec as spec_module

DEFAULT_QUANTITIES = {"peak_normal_force_N": "peak normal force [N]",
                      "peak_tangential_force_N": "peak tangential force [N]",
                      "total_normal_impulse_Ns": "normal impulse [N s]",
                      "detached": "detachment fraction"}
STOP_KEYS = {"relative_se", "budget_core_hours", "max_rounds", "growth"}
STATS_KEYS = {"level_axis", "difference", "quantities"}


# ------------------------------------------------------------------------------------------
# Estimators

def cluster_mean(clusters):
    """Kernel mean of values grouped in clusters (one list per run), its cluster standard error
    over the runs and the naive one (kernels as independent).

    mean = sum of all values / N (N kernels in S runs). Cluster SE (the ratio estimator's
    linearisation, with the S / (S - 1) small-sample factor):
        SE^2 = S / (S - 1) * sum_s (T_s - mean n_s)^2 / N^2,   T_s = the run's sum, n_s its size;
    with equal run sizes this is the standard deviation of the run means over sqrt(S). Naive:
    the standard deviation of all N values over sqrt(N). Returns a dict (mean, se, se_naive,
    kernels, runs); se is nan with fewer than 2 runs."""
    clusters = [list(c) for c in clusters if len(c)]
    n = sum(len(c) for c in clusters)
    s = len(clusters)
    if n == 0:
        return {"mean": math.nan, "se": math.nan, "se_naive": math.nan, "kernels": 0, "runs": 0}
    mean = sum(sum(c) for c in clusters) / n
    se = math.nan
    if s >= 2:
        se = math.sqrt(s / (s - 1) * sum((sum(c) - mean * len(c)) ** 2 for c in clusters)) / n
    se_naive = math.nan
    if n >= 2:
        se_naive = math.sqrt(sum((x - mean) ** 2 for c in clusters for x in c) / (n - 1) / n)
    return {"mean": mean, "se": se, "se_naive": se_naive, "kernels": n, "runs": s}


def relative_difference(chosen, finer):
    """Relative difference finer / chosen - 1 of two levels' kernel means and its standard error.

    chosen, finer: {seed: [values of the run's kernels]}. A seed present at both levels is one
    cluster, so the covariance of the paired runs enters. With m_c, m_f the kernel means and
    N_c, N_f the kernel counts, the linearisation of the ratio gives per seed
        u_s = (T_fs - m_f n_fs) / (N_f m_c) - m_f (T_cs - m_c n_cs) / (N_c m_c^2)
    and SE^2 = S / (S - 1) * sum_s u_s^2 (S seeds in either level). Returns (d, se)."""
    seeds = sorted(set(chosen) | set(finer), key=str)
    c = cluster_mean(chosen.values())
    f = cluster_mean(finer.values())
    mc, mf, nc, nf = c["mean"], f["mean"], c["kernels"], f["kernels"]
    if not nc or not nf or mc == 0:
        return math.nan, math.nan
    d = mf / mc - 1.0
    if len(seeds) < 2:
        return d, math.nan
    total = 0.0
    for seed in seeds:
        u = 0.0
        if seed in finer and finer[seed]:
            u += (sum(finer[seed]) - mf * len(finer[seed])) / (nf * mc)
        if seed in chosen and chosen[seed]:
            u -= mf * (sum(chosen[seed]) - mc * len(chosen[seed])) / (nc * mc * mc)
        total += u * u
    s = len(seeds)
    return d, math.sqrt(s / (s - 1) * total)


def relative(se, mean):
    """se / |mean|: inf for a zero mean with a spread, 0 for a zero mean without."""
    if math.isnan(se) or math.isnan(mean):
        return math.nan
    if mean == 0:
        return 0.0 if se == 0 else math.inf
    return se / abs(mean)


# ------------------------------------------------------------------------------------------
# Settings and the table

class Settings:
    """report.stream_statistics and stop of a sweep file."""

    def __init__(self, sweep):
        where = f"{sweep.path}"
        block = sweep.report.get("stream_statistics") or {}
        if not isinstance(block, dict) or set(block) - STATS_KEYS:
            spec_module._fail(f"{where}: report.stream_statistics",
                              f"expected a mapping with keys among {sorted(STATS_KEYS)} "
                              f"(got {block!r})")
        stop = sweep.stop or {}
        if not isinstance(stop, dict) or set(stop) - STOP_KEYS:
            spec_module._fail(f"{where}: stop", f"expected a mapping with keys among "
                              f"{sorted(STOP_KEYS)} (got {stop!r})")
        columns = [c for c in sweep.axis_columns() if c not in ("seed", "group")]
        self.level_axis = str(block.get("level_axis", "modes"))
        if self.level_axis not in columns:
            spec_module._fail(f"{where}: report.stream_statistics.level_axis",
                              f"no axis column '{self.level_axis}' (axes: {columns})")
        self.stream_axes = [c for c in columns if c != self.level_axis]
        quantities = block.get("quantities", DEFAULT_QUANTITIES)
        if isinstance(quantities, list):
            quantities = {q: q for q in quantities}
        if not isinstance(quantities, dict) or not quantities:
            spec_module._fail(f"{where}: report.stream_statistics.quantities",
                              f"expected kernel columns (got {quantities!r})")
        self.quantities = {str(k): str(v) for k, v in quantities.items()}
        self.difference = self._positive(where, "report.stream_statistics.difference",
                                         block.get("difference", 0.01))
        self.relative_se = self._positive(where, "stop.relative_se",
                                          stop.get("relative_se", 0.005))
        self.budget_core_hours = self._positive(where, "stop.budget_core_hours",
                                                stop.get("budget_core_hours", math.inf))
        self.max_rounds = stop.get("max_rounds", 8)
        self.growth = self._positive(where, "stop.growth", stop.get("growth", 4))
        if isinstance(self.max_rounds, bool) or not isinstance(self.max_rounds, int) or \
                not 1 <= self.max_rounds <= 1000:
            spec_module._fail(f"{where}: stop.max_rounds",
                              f"expected an integer in [1, 1000] (got {self.max_rounds!r})")
        if self.growth <= 1:
            spec_module._fail(f"{where}: stop.growth", f"must be > 1 (got {self.growth!r})")
        if sweep.seeds is None:
            spec_module._fail(where, "stream statistics need seeds (seeds: N)")

    @staticmethod
    def _positive(where, name, value):
        if value == math.inf:
            return value
        value = spec_module._number(f"{where}: {name}", value)
        if value <= 0:
            spec_module._fail(f"{where}: {name}", f"must be > 0 (got {value!r})")
        return float(value)


def _float(text):
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _read_csv(path):
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _level_key(value):
    number = _float(value)
    return (0, number, "") if number is not None else (1, 0.0, str(value))


class Data:
    """The sweep's table by stream and level: per-seed kernel values of each quantity, run CPU
    time, runs not ok."""

    def __init__(self, out, settings):
        out = pathlib.Path(out)
        self.settings = settings
        runs = _read_csv(out / "runs.csv")
        kernels = _read_csv(out / "kernels.csv")
        self.cpu_s = sum(_float(r.get("cpu_s")) or 0.0 for r in runs)
        self.streams = {}    # stream -> {level: {"runs", "cpu", "seeds": {seed: {q: [..]}}}}
        self.not_ok = {}     # stream -> list of (level, seed, status)
        ok_runs = set()
        for r in runs:
            stream, level = self._stream(r), r[settings.level_axis]
            cell = self.streams.setdefault(stream, {}).setdefault(
                level, {"runs": 0, "cpu": [], "seeds": {}, "tip": []})
            cell["runs"] += 1
            cell["cpu"].append(_float(r.get("cpu_s")) or 0.0)
            if r["status"] == "ok":
                ok_runs.add(r["run"])
                tip = _float(r.get("max_tip_deflection_ratio"))
                if tip is not None:
                    cell["tip"].append(tip)
            else:
                self.not_ok.setdefault(stream, []).append((level, r.get("seed"), r["status"]))
        for k in kernels:
            if k["run"] not in ok_runs:
                continue
            cell = self.streams[self._stream(k)][k[settings.level_axis]]
            values = cell["seeds"].setdefault(k["seed"], {q: [] for q in settings.quantities})
            for q in settings.quantities:
                value = _float(k.get(q))
                if value is None and str(k.get(q)).lower() in ("true", "false"):
                    value = float(str(k.get(q)).lower() == "true")
                if value is not None:
                    values[q].append(value)
        for stream in self.streams:
            self.streams[stream] = dict(sorted(self.streams[stream].items(),
                                               key=lambda item: _level_key(item[0])))

    def _stream(self, row):
        return " / ".join(str(row[c]) for c in self.settings.stream_axes)

    def levels(self, stream):
        return list(self.streams[stream])

    def mean(self, stream, level, q):
        seeds = self.streams[stream][level]["seeds"]
        return cluster_mean(v[q] for v in seeds.values())

    def difference(self, stream, q):
        levels = self.levels(stream)
        if len(levels) < 2:
            return math.nan, math.nan
        a, b = (self.streams[stream][lv]["seeds"] for lv in levels[:2])
        return relative_difference({s: v[q] for s, v in a.items()},
                                   {s: v[q] for s, v in b.items()})

    def worst_relative_se(self, stream):
        """The largest SE / mean over the stream's levels and quantities (nan: too few seeds)."""
        worst = 0.0
        for level in self.levels(stream):
            for q in self.settings.quantities:
                m = self.mean(stream, level, q)
                r = relative(m["se"], m["mean"])
                if math.isnan(r):
                    return math.nan
                worst = max(worst, r)
        return worst

    def cpu_per_seed(self, stream):
        """Mean CPU seconds of one seed of the stream (one run per level)."""
        return sum(sum(c["cpu"]) / len(c["cpu"]) for c in self.streams[stream].values()
                   if c["cpu"])


# ------------------------------------------------------------------------------------------
# The stop rule

def _runs_for(sweep, seeds_of, settings, validated, simulate, sha):
    """The sweep's runs with each stream's seed list; validates the new ones."""
    column, key, _ = sweep.seeds
    top = max(max(s) for s in seeds_of.values())
    first = min(min(s) for s in seeds_of.values())
    sweep.seeds = (column, key, list(range(first, top + 1)))
    runs = []
    for run in sweep.runs():
        stream = " / ".join(str(run.labels[c]) for c in settings.stream_axes)
        if run.labels["seed"] in seeds_of.get(stream, ()):
            run.index = len(runs)
            runs.append(run)
    ident = [tuple(sorted((k, str(v)) for k, v in r.labels.items())) for r in runs]
    new = [r for r, i in zip(runs, ident) if i not in validated]
    if new:
        spec_module.validate(sweep, new, simulate, sha)
        for r, i in zip(runs, ident):
            if i not in validated and r.key is not None:
                validated[i] = (r.scene, r.key, r.base)
    for r, i in zip(runs, ident):
        r.scene, r.key, r.base = validated[i]
    return runs


def plan(data, settings, seeds_of, spent_core_h):
    """New seed counts per stream for the next round, and the reason to stop (or None).
    Returns (additions {stream: n}, predicted core-hours, reason)."""
    want = {}
    for stream, seeds in seeds_of.items():
        if stream not in data.streams:
            continue
        worst = data.worst_relative_se(stream)
        s = len(seeds)
        if math.isnan(worst) or math.isinf(worst):
            need = math.ceil(s * settings.growth)
        elif worst <= settings.relative_se:
            continue
        else:
            need = math.ceil(s * (worst / settings.relative_se) ** 2)
        want[stream] = max(1, min(need, math.floor(s * settings.growth)) - s)
    if not want:
        return {}, 0.0, "relative_se"
    left = settings.budget_core_hours - spent_core_h
    cost = {stream: data.cpu_per_seed(stream) / 3600.0 for stream in want}
    total = sum(want[s] * cost[s] for s in want)
    if total > left:
        # Round robin, the stream furthest from the target first: one seed each while the
        # budget pays for it at the stream's measured cost per seed.
        order = sorted(want, key=lambda s: -_sortable(data.worst_relative_se(s)))
        given = {s: 0 for s in want}
        added = True
        while added:
            added = False
            for s in order:
                if given[s] < want[s] and cost[s] <= left:
                    given[s] += 1
                    left -= cost[s]
                    added = True
        want = {s: n for s, n in given.items() if n > 0}
        if not want:
            return {}, 0.0, "budget"
        total = sum(want[s] * cost[s] for s in want)
    return want, total, None


def _sortable(x):
    return math.inf if math.isnan(x) else x


def run_rounds(sweep, simulate, sha, out, scheduler=None, workers=None, processes=False,
               batch=None, budget_core_hours=None, max_rounds=None, log=print):
    """Runs the sweep in rounds of seeds until the stop rule ends it; writes OUT/stop.json.
    Returns (rows, stats) of the last round, as runner.run_sweep does, with stats["stop"]."""
    import os

    settings = Settings(sweep)
    if budget_core_hours is not None:
        settings.budget_core_hours = float(budget_core_hours)
    if max_rounds is not None:
        settings.max_rounds = int(max_rounds)
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    first = list(sweep.seeds[2])
    streams = []
    for run in sweep.runs():
        stream = " / ".join(str(run.labels[c]) for c in settings.stream_axes)
        if stream not in streams:
            streams.append(stream)
    seeds_of = {s: list(first) for s in streams}
    validated = {}
    cluster = None
    address = scheduler
    if scheduler is None and processes:
        # A local Dask cluster (processes=True): one for every round instead of one per round.
        # Without it each round runs on local threads, which start at no cost.
        client, cluster = runner._connect(None, workers or os.cpu_count() or 1)
        address = cluster.scheduler_address
        client.close()
    rounds = []
    reason = None
    try:
        while True:
            runs = _runs_for(sweep, seeds_of, settings, validated, simulate, sha)
            started = time.monotonic()
            rows, stats = runner.run_sweep(sweep, runs, simulate, sha, out, address, workers,
                                           processes, batch, log=log)
            data = Data(out, settings)
            spent = data.cpu_s / 3600.0
            worst = {s: data.worst_relative_se(s) for s in streams if s in data.streams}
            rounds.append({"round": len(rounds) + 1, "runs": len(runs),
                           "ran": stats["runs"] - stats["cached"],
                           "wall_s": round(time.monotonic() - started, 3),
                           "core_hours": spent,
                           "seeds": {s: len(v) for s, v in seeds_of.items()},
                           "worst_relative_se": worst})
            log(f"stop rule: round {len(rounds)}: {len(runs)} runs, {spent:.4f} of "
                f"{settings.budget_core_hours:g} core-hours; largest SE / mean " +
                ", ".join(f"{s} {100 * w:.2f} %" for s, w in worst.items()))
            additions, predicted, reason = plan(data, settings, seeds_of, spent)
            if reason is None and spent >= settings.budget_core_hours:
                reason = "budget"
            if reason is None and len(rounds) >= settings.max_rounds:
                reason = "max_rounds"
            if reason is not None:
                break
            rounds[-1]["next"] = {"add": additions, "predicted_core_hours": predicted}
            for stream, n in additions.items():
                top = max(seeds_of[stream])
                seeds_of[stream] += list(range(top + 1, top + 1 + n))
    finally:
        if cluster is not None:
            cluster.close()
    record = {"reason": reason, "relative_se": settings.relative_se,
              "budget_core_hours": settings.budget_core_hours,
              "max_rounds": settings.max_rounds, "core_hours": rounds[-1]["core_hours"],
              "rounds": rounds}
    (out / "stop.json").write_text(json.dumps(record, indent=1) + "\n")
    log(f"stop rule: stopped on {reason} after {len(rounds)} round(s), "
        f"{record['core_hours']:.4f} core-hours")
    stats["stop"] = record
    return rows, stats


# ------------------------------------------------------------------------------------------
# Report section

REASONS = {"relative_se": "every standard error reached the target",
           "budget": "the budget ended first",
           "max_rounds": "the rounds ended first (max_rounds)"}


def _g(x, digits=4):
    if x is None or (isinstance(x, float) and (math.isnan(x) or math.isinf(x))):
        return "-" if x is None or math.isnan(x) else "inf"
    return f"{x:.{digits}g}"


def _pct(x, digits=2):
    if x is None or math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf"
    return f"{100 * x:.{digits}f} %"


def analyse_streams(out, sweep):
    """Per stream: levels, means, differences, verdict and cost model (a dict)."""
    settings = Settings(sweep)
    data = Data(out, settings)
    result = {"settings": settings, "data": data, "streams": {}}
    for stream in data.streams:
        levels = data.levels(stream)
        entry = {"levels": levels, "means": {}, "differences": {}, "misses": [], "cost": {}}
        se_misses = []
        for level in levels:
            cell = data.streams[stream][level]
            cpu = sum(cell["cpu"]) / len(cell["cpu"]) if cell["cpu"] else math.nan
            worst_q, worst = None, 0.0
            for q in settings.quantities:
                m = data.mean(stream, level, q)
                m["relative_se"] = relative(m["se"], m["mean"])
                entry["means"][(level, q)] = m
                if not math.isnan(m["relative_se"]) and m["relative_se"] > settings.relative_se:
                    se_misses.append((m["relative_se"], q, level))
                elif math.isnan(m["relative_se"]) and \
                        f"{level}: fewer" not in " ".join(entry["misses"]):
                    entry["misses"].append(f"no standard error at {settings.level_axis} "
                                           f"{level}: fewer than 2 seeds ended ok")
                if not math.isnan(m["relative_se"]) and m["relative_se"] >= worst:
                    worst_q, worst = q, m["relative_se"]
            seeds = max(len(cell["seeds"]), 1)
            kernels_per_run = (sum(len(v[next(iter(settings.quantities))])
                                   for v in cell["seeds"].values()) / seeds)
            need_seeds = (math.ceil(seeds * (worst / settings.relative_se) ** 2)
                          if worst_q is not None and not math.isinf(worst) else math.nan)
            # Per-kernel spread (standard deviation / mean), the largest over the quantities.
            spread, spread_q = math.nan, None
            for q in settings.quantities:
                m = entry["means"][(level, q)]
                if m["mean"] and not math.isnan(m["se_naive"]):
                    cv = m["se_naive"] * math.sqrt(m["kernels"]) / abs(m["mean"])
                    if math.isnan(spread) or cv > spread:
                        spread, spread_q = cv, q
            need_iid = (spread / settings.relative_se) ** 2
            entry["cost"][level] = {
                "runs": cell["runs"], "cpu_s": cpu, "cpu_min": min(cell["cpu"], default=math.nan),
                "cpu_max": max(cell["cpu"], default=math.nan), "kernels_per_run": kernels_per_run,
                "worst": worst_q, "kernel_cv": spread, "spread_q": spread_q,
                "seeds_needed": need_seeds, "kernels_needed": need_seeds * kernels_per_run,
                "kernels_needed_iid": need_iid, "core_hours": need_seeds * cpu / 3600.0,
                "core_hours_iid": (need_iid / kernels_per_run * cpu / 3600.0
                                   if kernels_per_run else math.nan),
                "tip": max(cell["tip"], default=math.nan)}
        if se_misses:
            rse, q, level = max(se_misses, key=lambda item: item[0])
            factor = rse / settings.relative_se
            entry["misses"].insert(0, (
                f"{len(se_misses)} of {len(levels) * len(settings.quantities)} means have a "
                f"standard error above {_pct(settings.relative_se, 1)}, the largest "
                f"{_pct(rse)} ({settings.quantities[q]} at {settings.level_axis} {level}: "
                f"{_g(factor, 3)} x the target, about {_g(factor ** 2, 3)} x the seeds)"))
        if len(levels) >= 2:
            over = []
            for q in settings.quantities:
                d, se = data.difference(stream, q)
                entry["differences"][q] = (d, se)
                if math.isnan(d) or abs(d) > settings.difference:
                    over.append(f"{settings.quantities[q]} {_pct(d)} ± {_pct(se)}")
            if over:
                entry["misses"].append(
                    f"differences between {settings.level_axis} {levels[0]} and {levels[1]} "
                    f"above {_pct(settings.difference, 0)}: " + ", ".join(over))
        else:
            entry["misses"].append(f"only one level ({levels[0]}) ran")
        not_ok = data.not_ok.get(stream, [])
        if not_ok:
            entry["misses"].append(
                f"{len(not_ok)} run(s) did not end ok and are left out of the means ("
                + ", ".join(f"seed {seed} at {level}: {status}" for level, seed, status
                            in not_ok[:6]) + (", ..." if len(not_ok) > 6 else "") + ")")
        result["streams"][stream] = entry
    return result


def stream_section(out, sweep, heading="##", link_report=None):
    """The stream statistics section (markdown lines)."""
    out = pathlib.Path(out)
    a = analyse_streams(out, sweep)
    settings, data = a["settings"], a["data"]
    stop = None
    if (out / "stop.json").is_file():
        stop = json.loads((out / "stop.json").read_text())
    lines = [f"{heading} Stream statistics", ""] if heading else []
    source = link_report or f"`{out}`"
    met = [s for s, e in a["streams"].items() if not e["misses"]]
    missed = [s for s, e in a["streams"].items() if e["misses"]]
    lines.append(
        f"From {source}: per stream and {settings.level_axis} level, the mean over the kernels "
        f"of all seeds ({', '.join(settings.quantities.values())}), with standard errors over "
        f"the seeds (cluster, or batch-means, standard errors: each run's kernels share the "
        f"teeth and hit each other, so the run, not the kernel, is the independent sample; "
        f"the naive standard error, kernels taken as independent, and the design effect "
        f"(SE / naive SE)^2 are listed too). The difference between the chosen level (the "
        f"smallest) and the next finer one is paired by seed. Targets: every standard error "
        f"<= {_pct(settings.relative_se, 1)} of its mean, every difference <= "
        f"{_pct(settings.difference, 0)}. The runs' own CPU time: "
        f"{data.cpu_s / 3600:.4f} core-hours.")
    lines.append("")
    if stop is not None:
        lines.append(
            f"Stop rule: {len(stop['rounds'])} round(s), {stop['core_hours']:.4f} of "
            f"{stop['budget_core_hours']:g} core-hours (at most {stop['max_rounds']} rounds); "
            f"stopped because {REASONS.get(stop['reason'], stop['reason'])}.")
        lines.append("")
    lines.append(f"**Verdict.** {len(met)} of {len(a['streams'])} streams meet both targets"
                 + (f" ({', '.join(met)})" if met else "") + ".")
    for stream in missed:
        lines.append(f"- {stream} misses: " + "; ".join(a["streams"][stream]["misses"]) + ".")
    lines.append("")
    lines += ["| stream | " + settings.level_axis + " | seeds | kernels | quantity | mean | "
              "SE (seeds) | SE / mean | naive SE | design effect |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for stream, e in a["streams"].items():
        for level in e["levels"]:
            for q, label in settings.quantities.items():
                m = e["means"][(level, q)]
                deff = ((m["se"] / m["se_naive"]) ** 2 if m["se_naive"] else math.nan)
                lines.append(f"| {stream} | {level} | {m['runs']} | {m['kernels']} | {label} | "
                             f"{_g(m['mean'])} | {_g(m['se'], 3)} | {_pct(m['relative_se'])} | "
                             f"{_g(m['se_naive'], 3)} | {_g(deff, 3)} |")
    lines += ["", "Relative difference between the levels (finer / chosen - 1) ± its standard "
              "error:", "", "| stream | levels | " + " | ".join(settings.quantities.values()) +
              " |", "|---|---|" + "---|" * len(settings.quantities)]
    for stream, e in a["streams"].items():
        if len(e["levels"]) < 2:
            continue
        cells = [f"{_pct(d)} ± {_pct(se)}" for d, se in
                 (e["differences"][q] for q in settings.quantities)]
        lines.append(f"| {stream} | {e['levels'][0]} -> {e['levels'][1]} | "
                     + " | ".join(cells) + " |")
    per_run = sorted({round(c["kernels_per_run"]) for e in a["streams"].values()
                      for c in e["cost"].values()})
    lines += ["", f"**Cost model.** Measured core-seconds per run (one seed of one level, "
              f"{', '.join(map(str, per_run))} kernels; `cpu_s`, the simulate process's user + "
              f"system time, failed runs included), and what "
              f"{_pct(settings.relative_se, 1)} standard error costs: the seeds needed scale "
              f"with (SE / mean / target)^2 of the quantity with the largest relative SE, "
              f"estimated from the seeds so far (with S seeds the SE itself is uncertain by "
              f"about 1 / sqrt(2 (S - 1)), so with few seeds this is a rough figure). A second "
              f"estimate takes the kernels as independent: the per-kernel spread (standard "
              f"deviation / mean over all kernels, the largest over the quantities) gives "
              f"(spread / target)^2 kernels; it rests on every kernel, not only on the seeds, "
              f"and is off by the design effect.", "",
              "| stream | " + settings.level_axis + " | runs | core-s per run (min-max) | "
              "largest SE / mean | seeds needed | kernels needed | core-hours needed | "
              "per-kernel spread | kernels needed (independent) | core-hours needed "
              "(independent) | max tip deflection / L |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    total, total_iid = 0.0, 0.0
    for stream, e in a["streams"].items():
        for level in e["levels"]:
            c = e["cost"][level]
            rse = e["means"][(level, c["worst"])]["relative_se"] if c["worst"] else math.nan
            label = settings.quantities.get(c["worst"], "-")
            spread_label = settings.quantities.get(c["spread_q"], "-")
            total += c["core_hours"] if not math.isnan(c["core_hours"]) else 0.0
            total_iid += c["core_hours_iid"] if not math.isnan(c["core_hours_iid"]) else 0.0
            lines.append(
                f"| {stream} | {level} | {c['runs']} | {_g(c['cpu_s'], 3)} "
                f"({_g(c['cpu_min'], 3)}-{_g(c['cpu_max'], 3)}) | {_pct(rse)} ({label}) | "
                f"{_g(c['seeds_needed'], 3)} | {_g(c['kernels_needed'], 3)} | "
                f"{_g(c['core_hours'], 3)} | {_g(c['kernel_cv'], 3)} ({spread_label}) | "
                f"{_g(c['kernels_needed_iid'], 3)} | {_g(c['core_hours_iid'], 3)} | "
                f"{_g(c['tip'], 3)} |")
    lines += ["", f"All levels of all streams to {_pct(settings.relative_se, 1)}: about "
              f"{_g(total, 3)} core-hours from the standard errors over the seeds (levels "
              f"without one left out), {_g(total_iid, 3)} core-hours with independent kernels, "
              f"at the measured cost per run.", ""]
    if stop is not None:
        lines += ["Rounds of the stop rule:", "",
                  "| round | runs | ran | core-hours so far | seeds per stream | largest SE / "
                  "mean per stream |", "|---|---|---|---|---|---|"]
        for r in stop["rounds"]:
            lines.append(f"| {r['round']} | {r['runs']} | {r['ran']} | {r['core_hours']:.4f} | "
                         + ", ".join(f"{s} {n}" for s, n in r["seeds"].items()) + " | "
                         + ", ".join(f"{s} {_pct(w)}" for s, w in
                                     r["worst_relative_se"].items()) + " |")
        lines.append("")
    return lines


def splice_stream_docs(out, sweep, page):
    """Writes the section into page between <!-- stream-statistics --> markers."""
    from tslib import markdown

    def short(path):
        path = pathlib.Path(path).resolve()
        return path.relative_to(markdown.ROOT) if path.is_relative_to(markdown.ROOT) else path

    body = stream_section(out, sweep, heading=None, link_report=f"`scripts/sweep report {short(out)}` "
                   f"(sweep file `{short(sweep.path)}`)")
    return markdown.splice("stream-statistics", "\n".join(body), page)
