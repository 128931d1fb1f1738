"""The mode convergence study: the scenes, the levels of each (the automatic mode count and
two finer ones), the simulations and their metrics, the knead force before and after the
static correction and the section rotation study."""
import json
import math
import re
import subprocess

from tslib import BENCH_DIR, SCENE_DIR, schema
from tslib.teeth.cases import CASES, LD_FILE, VARIANTS, scene_args, validity_fraction


TARGET = 0.01  # relative change allowed between the chosen level and the next finer one
KNEAD_BENCH = "knead_polyurethane"


def scenes(quick):
    """(name, base command arguments) of every scene of the table."""
    out = []
    bench = sorted(BENCH_DIR.glob("*.yaml"))
    if quick:
        bench = [b for b in bench if b.stem in ("single_strike", KNEAD_BENCH)]
    for path in bench:
        out.append((f"bench/{path.stem}", [str(path)]))
    if quick:
        return out
    for case in CASES:
        for variant in VARIANTS:
            args = scene_args(case, variant)
            out.append((f"{case}/{variant}" + (ROD_SUFFIX if is_rod(args) else ""), args))
    return out


def mode_counts(simulate, args):
    """Mode count of every tooth (simulate --modes)."""
    text = subprocess.run([str(simulate)] + args + ["--modes"], capture_output=True, text=True,
                          check=True).stdout
    return [int(m) for m in re.findall(r", (\d+) modes", text)]


ROD_SUFFIX = " (rod)"  # scene names whose tooth is the large-deflection rod


def rod_reruns(todo, results):
    """The scenes whose modal tooth bent past the core's validity limit
    (validity_fraction() L) again with the
    large-deflection rod (config/scenes/cases/large_deflection.yaml)."""
    again = []
    for (name, args), (_, rows) in zip(todo, results):
        if not is_rod(args) and any(usable(m) and m["tip"] > validity_fraction() for _, m in rows):
            again.append((name + ROD_SUFFIX, args + ["--set-file", str(LD_FILE)]))
    return again


def chosen_modes(simulate, args):
    """The automatic mode count (teeth.*.modes=auto; the largest over the teeth), or 0 for a
    scene of rigid teeth (modes: 0), which stays rigid."""
    if max(mode_counts(simulate, args), default=0) == 0:
        return 0
    return max(mode_counts(simulate, args + ["--set", "teeth.*.modes=auto"]), default=0)


def is_rod(args):
    """Whether the scene's teeth are large-deflection rods (levels count shape functions)."""
    return str(LD_FILE) in args or "teeth.*.model=large_deflection" in args


TIME_LIMIT_S = 600  # per simulation; a level that takes longer is reported as timed out
REUSE = False        # --reuse: keep summaries already in the work folder


def simulate_summary(simulate, args, extra, out_json):
    """Summary of one simulation, or None if it ran past TIME_LIMIT_S (remembered by a
    `.timeout` file next to the summary, which --reuse honours)."""
    marker = out_json.with_suffix(".timeout")
    if REUSE and marker.is_file():
        return None
    if not (REUSE and out_json.is_file() and out_json.stat().st_size > 0):
        cmd = [str(simulate)] + args + extra + ["--summary", str(out_json), "--quiet"]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=TIME_LIMIT_S)
        except subprocess.TimeoutExpired:
            out_json.unlink(missing_ok=True)
            marker.write_text(f"ran past {TIME_LIMIT_S:.0f} s\n")
            return None
        if proc.returncode == 2 or not out_json.is_file():
            raise RuntimeError(" ".join(cmd) + "\n" + proc.stderr)
    with open(out_json) as f:
        summary = json.load(f)
    if summary["status"] != "ok":
        return {"failed": summary["status"].split(" [")[0].split(" at t =")[0]}
    return summary


def level_metrics(summary, kernel=None):
    """Peak forces, exit speed of the hardest-struck kernel (or of `kernel`), impacts, tip
    deflection ratio."""
    per = summary["outcomes"]["per_kernel"]
    if kernel is None:
        kernel = max(range(len(per)), key=lambda i: per[i]["peak_normal_force_N"])
    v = summary["kernels"][kernel]["velocity_mps"]
    speeds = [math.hypot(*k["velocity_mps"]) for k in summary["kernels"]]
    return {"fn": max(k["peak_normal_force_N"] for k in per),
            "ft": max(k["peak_tangential_force_N"] for k in per),
            "v": math.hypot(v[0], v[1]), "impacts": summary["impacts"],
            "tip": summary["max_tip_deflection_ratio"], "kernel": kernel,
            "n_kernels": len(per), "stats": {"fn": mean_se([k["peak_normal_force_N"] for k in per]),
                      "ft": mean_se([k["peak_tangential_force_N"] for k in per]),
                      "v": mean_se(speeds)}}


def mean_se(values):
    """Mean and its standard error over the kernels."""
    n = len(values)
    mean = sum(values) / n
    if n < 2:
        return mean, 0.0
    var = sum((x - mean) ** 2 for x in values) / (n - 1)
    return mean, math.sqrt(var / n)


CHAOTIC_KERNELS = 3  # scenes with more kernels are streams: judged by their kernel statistics


def chaotic(rows):
    return rows[0][1] is not None and "stats" in rows[0][1] and \
        len_kernels(rows[0][1]) > CHAOTIC_KERNELS


def len_kernels(m):
    return m.get("n_kernels", 0)


def stats_agree(a, b):
    """Whether two levels' kernel means of peak normal, peak tangential force and exit speed
    agree within twice their combined standard error; the largest such ratio."""
    worst = 0.0
    for k in ("fn", "ft", "v"):
        (ma, sa), (mb, sb) = a["stats"][k], b["stats"][k]
        worst = max(worst, abs(mb - ma) / max(math.hypot(sa, sb), 1e-12))
    return worst <= 2.0, worst





SHAPE_STEP = 4   # a rod's finer levels: +4 and +8 shape functions (its automatic count is at most
#                  24; its spurious highest Ritz frequencies, and its cost, grow fast with n)


def max_modes():
    """The most bending modes of a modal tooth (teeth.*.modes' range, simulate --print-schema)."""
    return int(schema.bounds("teeth.*.modes")[1])


def max_shapes():
    """The most shape functions of a large-deflection tooth (simulate --print-schema)."""
    return int(schema.said("teeth.*.modes", r"Ritz shape functions, at most (\d+)"))


def levels_of(n, rod=False):
    if n == 0:
        return [0]
    if rod:
        finer = [min(max_shapes(), n + SHAPE_STEP), min(max_shapes(), n + 2 * SHAPE_STEP)]
    else:
        finer = [min(max_modes(), math.ceil(1.5 * n)), min(max_modes(), 2 * n)]
    return [n] + [m for i, m in enumerate(finer) if m > n and m not in finer[:i]]


def study(simulate, name, args, work):
    """All levels of one scene: list of (modes, metrics)."""
    n = chosen_modes(simulate, args)
    rows = []
    kernel = None
    for level in levels_of(n, is_rod(args)):
        s = simulate_summary(simulate, args, ["--set", f"teeth.*.modes={level}"] if level else [],
                work / f"{name.replace('/', '_')}_{level}.json")
        if s is None or "failed" in s:
            rows.append((level, None if s is None else s))
            break
        m = level_metrics(s, kernel)
        kernel = m["kernel"]
        rows.append((level, m))
    return name, rows


def knead_before_after(simulate, work):
    """Peak knead (tangential) force of the polyurethane bench at 6, 8, 10, 12 modes with the
    model of before (no static correction, Euler-Bernoulli sections) at --tolerance 1e-8 (the
    issue's figures), and with today's defaults at the chosen level and the finer ones."""
    path = str(BENCH_DIR / f"{KNEAD_BENCH}.yaml")
    before = []
    for n in (6, 8, 10, 12):
        s = simulate_summary(simulate, [path, "--tolerance", "1e-8"],
                ["--set", f"teeth.*.modes={n}", "--set", "teeth.*.static_correction=off",
                 "--set", "teeth.*.section_rotation=euler_bernoulli"],
                work / f"knead_before_{n}.json")
        before.append((n, level_metrics(s)))
    args = [path, "--tolerance", "1e-8"]
    n = chosen_modes(simulate, args)
    after = []
    for level in levels_of(n, is_rod(args)):
        s = simulate_summary(simulate, args, ["--set", f"teeth.*.modes={level}"], work / f"knead_after_{level}.json")
        after.append((level, level_metrics(s)))
    return before, after


ROTATION_CASE = ("tip_strike/nylon", "single_strike", "tip_strike", "nylon")
ROTATION_LEVELS = (20, 30, 40)


def rotation_study(simulate, work):
    """Peak tangential force of one tip strike at three mode counts with each section rotation
    (--tolerance 1e-11, far below the differences): {word: [(modes, metrics)]}."""
    _, scene, case_file, variant = ROTATION_CASE
    args = [str(SCENE_DIR / f"{scene}.yaml"), "--set-file",
            str(SCENE_DIR / "teeth" / f"{variant}.yaml"), "--set-file",
            str(SCENE_DIR / "cases" / f"{case_file}.yaml"), "--tolerance", "1e-11"]
    out = {}
    for word in ("shear_corrected", "euler_bernoulli"):
        out[word] = []
        for n in ROTATION_LEVELS:
            s = simulate_summary(simulate, args, ["--set", f"teeth.*.modes={n}",
                                     "--set", f"teeth.*.section_rotation={word}"],
                    work / f"rotation_{word}_{n}.json")
            out[word].append((n, level_metrics(s)))
    return out


def usable(m):
    return m is not None and "failed" not in m
