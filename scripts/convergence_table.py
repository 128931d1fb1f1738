#!/usr/bin/python3
"""Mode convergence of the tooth forces: every scene of config/bench/ and every threshing case x
tooth variant of config/scenes/ (combined as scripts/compare_teeth.py does), run by the built
`simulate` at the automatically chosen mode count (teeth.*.modes: auto) and at two finer levels
(ceil(1.5 n) and 2 n, at most 64 modes).

For each: peak normal and tangential tooth force on a kernel, the exit velocity of the kernel
the tooth struck hardest (its speed at the end of the run), the impact count, their relative
changes from each level to the next finer one, and the largest tip deflection over L.

Writes docs/convergence.md (full table, with the knead force before and after the static
correction) and the README's short table between `<!-- convergence -->` and
`<!-- convergence-end -->`. --quick runs two bench scenes only and writes to --out (for the CI
test). Exits non-zero if a run fails; the 1 % target is reported, not enforced.
"""
import argparse
import concurrent.futures
import json
import math
import os
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
from compare_teeth import CASES, SCENE_DIR, VARIANTS  # noqa: E402

BENCH_DIR = ROOT / "config/bench"
MAX_MODES = 64
TARGET = 0.01  # relative change allowed between the chosen level and the next finer one
KNEAD_BENCH = "knead_polyurethane"


def default_simulate():
    for cand in [ROOT / ".build/ws/devel/lib/threshing_sim/simulate"]:
        if cand.is_file():
            return cand
    raise SystemExit("no built simulate found; run scripts/setup.sh or pass --simulate")


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
    for case, (scene, case_file) in CASES.items():
        for variant in VARIANTS:
            args = [str(SCENE_DIR / f"{scene}.yaml"), "--set-file",
                    str(SCENE_DIR / "teeth" / f"{variant}.yaml")]
            if case_file:
                args += ["--set-file", str(SCENE_DIR / "cases" / f"{case_file}.yaml")]
            out.append((f"{case}/{variant}", args))
    return out


def mode_counts(simulate, args):
    """Mode count of every tooth (simulate --modes)."""
    text = subprocess.run([str(simulate)] + args + ["--modes"], capture_output=True, text=True,
                          check=True).stdout
    return [int(m) for m in re.findall(r", (\d+) modes", text)]


def chosen_modes(simulate, args):
    """The automatic mode count (teeth.*.modes=auto; the largest over the teeth), or 0 for a
    scene of rigid teeth (modes: 0), which stays rigid."""
    if max(mode_counts(simulate, args), default=0) == 0:
        return 0
    return max(mode_counts(simulate, args + ["--set", "teeth.*.modes=auto"]), default=0)


TIME_LIMIT_S = 600  # per simulation; a level that takes longer is reported as timed out
REUSE = False        # --reuse: keep summaries already in the work folder


def run(simulate, args, extra, out_json):
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
        if proc.returncode != 0:
            raise RuntimeError(" ".join(cmd) + "\n" + proc.stderr)
    with open(out_json) as f:
        return json.load(f)


def metrics(summary, kernel=None):
    """Peak forces, exit speed of the hardest-struck kernel (or of `kernel`), impacts, tip
    deflection ratio."""
    per = summary["outcomes"]["per_kernel"]
    if kernel is None:
        kernel = max(range(len(per)), key=lambda i: per[i]["peak_normal_force_N"])
    v = summary["kernels"][kernel]["velocity_mps"]
    return {"fn": max(k["peak_normal_force_N"] for k in per),
            "ft": max(k["peak_tangential_force_N"] for k in per),
            "v": math.hypot(v[0], v[1]), "impacts": summary["impacts"],
            "tip": summary["max_tip_deflection_ratio"], "kernel": kernel}


def rel(a, b):
    return abs(b - a) / max(abs(a), 1e-12)


def levels_of(n):
    if n == 0:
        return [0]
    finer = [min(MAX_MODES, math.ceil(1.5 * n)), min(MAX_MODES, 2 * n)]
    return [n] + [m for i, m in enumerate(finer) if m > n and m not in finer[:i]]


def study(simulate, name, args, work):
    """All levels of one scene: list of (modes, metrics)."""
    n = chosen_modes(simulate, args)
    rows = []
    kernel = None
    for level in levels_of(n):
        s = run(simulate, args, ["--set", f"teeth.*.modes={level}"] if level else [],
                work / f"{name.replace('/', '_')}_{level}.json")
        if s is None:
            rows.append((level, None))
            break
        m = metrics(s, kernel)
        kernel = m["kernel"]
        rows.append((level, m))
    return name, rows


def knead_before_after(simulate, work):
    """Peak knead (tangential) force of the polyurethane bench at 6, 8, 10, 12 modes without
    the static correction at --tolerance 1e-8 (the issue's figures), and with it at the chosen
    level and the finer ones."""
    path = str(BENCH_DIR / f"{KNEAD_BENCH}.yaml")
    before = []
    for n in (6, 8, 10, 12):
        s = run(simulate, [path, "--tolerance", "1e-8"],
                ["--set", f"teeth.*.modes={n}", "--set", "teeth.*.static_correction=off"],
                work / f"knead_before_{n}.json")
        before.append((n, metrics(s)))
    args = [path, "--tolerance", "1e-8"]
    n = chosen_modes(simulate, args)
    after = []
    for level in levels_of(n):
        s = run(simulate, args, ["--set", f"teeth.*.modes={level}"], work / f"knead_after_{level}.json")
        after.append((level, metrics(s)))
    return before, after


def change_cells(rows, i):
    if i + 1 >= len(rows) or rows[i + 1][1] is None:
        return ["-", "-", "-"]
    a, b = rows[i][1], rows[i + 1][1]
    return [f"{100 * rel(a[k], b[k]):.2f} %" for k in ("fn", "ft", "v")]


def verdict(rows):
    if len(rows) >= 2 and rows[1][1] is None:
        return f"timed out (> {TIME_LIMIT_S:.0f} s at {rows[1][0]} modes)"
    if len(rows) < 2:
        return "rigid" if rows[0][0] == 0 else "at cap"
    a, b = rows[0][1], rows[1][1]
    worst = max(rel(a[k], b[k]) for k in ("fn", "ft", "v"))
    return ("yes" if worst <= TARGET else "no") + f" ({100 * worst:.2f} %)"


def full_table(results):
    lines = ["| scene | modes | peak normal [N] | peak tangential [N] | exit speed [m/s] | "
             "impacts | tip deflection / L | change to next level (N, T, v) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, rows in results:
        for i, (level, m) in enumerate(rows):
            if m is None:
                lines.append(f"| | {level} | timed out (> {TIME_LIMIT_S:.0f} s) | | | | | |")
                continue
            cells = change_cells(rows, i)
            lines.append(f"| {name if i == 0 else ''} | {level}{' (auto)' if i == 0 else ''} | "
                         f"{m['fn']:.4g} | {m['ft']:.4g} | {m['v']:.4g} | {m['impacts']} | "
                         f"{m['tip']:.3f} | {', '.join(cells)} |")
    return "\n".join(lines)


def short_table(results):
    lines = ["| scene | auto modes | peak N / T [N] | exit speed [m/s] | largest change to "
             "next level | within 1 % | tip / L |", "|---|---|---|---|---|---|---|"]
    for name, rows in results:
        level, m = rows[0]
        if len(rows) > 1 and rows[1][1] is not None:
            b = rows[1][1]
            worst = f"{100 * max(rel(m[k], b[k]) for k in ('fn', 'ft', 'v')):.2f} %"
        else:
            worst = "-"
        ok = verdict(rows).split(" (")[0]
        lines.append(f"| {name} | {level} | {m['fn']:.3g} / {m['ft']:.3g} | {m['v']:.3g} | "
                     f"{worst} | {ok} | {m['tip']:.3f} |")
    return "\n".join(lines)


def knead_text(before, after):
    b = ", ".join(f"{m['ft']:.1f} N ({n})" for n, m in before)
    a = ", ".join(f"{m['ft']:.2f} N ({n})" for n, m in after)
    change = (f"{100 * rel(after[0][1]['ft'], after[1][1]['ft']):.2f} %" if len(after) > 1
              else "-")
    return (f"Knead force of `config/bench/{KNEAD_BENCH}.yaml` at `--tolerance 1e-8` (peak "
            f"tangential tooth force, modes in brackets). Before (modal tooth only, "
            f"`static_correction: off`): {b}. After (static correction, automatic count and "
            f"finer levels): {a}; change from the chosen level to the next: {change}.")


def write_docs(results, before, after, out_md, readme):
    flexible = [rows for _, rows in results if rows[0][0] > 0]
    n_ok = sum(1 for rows in flexible if verdict(rows).startswith("yes"))
    summary = (f"{n_ok} of {len(flexible)} scenes with flexible teeth meet it (rigid teeth have "
               "no modes to converge).")
    limit = (f" A level whose run took longer than {TIME_LIMIT_S:.0f} s is reported as timed out "
             "(`--time-limit`).")
    body = [
        "# Mode convergence of the tooth forces",
        "",
        "Regenerated by `/usr/bin/python3 scripts/convergence_table.py` (README \"Converged tooth "
        "forces\"). Every scene of `config/bench/` and every case x tooth variant of "
        "`config/scenes/` (as `scripts/compare_teeth.py` combines them, at the scene's drum "
        "speed) runs at the automatic mode count (`teeth.*.modes: auto`, the first row of each "
        "scene) and at ceil(1.5 n) and 2 n modes (at most 64). Peak forces are the largest "
        "tooth force peaks on any kernel; the exit speed is the end speed of the kernel the "
        "tooth struck hardest; the change columns compare a row with the next finer one. "
        f"Target: every force and exit speed within {100 * TARGET:.0f} % between the chosen "
        "level and the next finer one." + limit,
        "",
        summary,
        "",
        "Where it is missed: the tangential peaks of the nylon and polyurethane strikes, which "
        "fall at a stick-slip transition and depend on the tooth's slope compliance; the static "
        "correction covers only the normal direction (README \"Converged tooth forces\"), so "
        "the slope part converges like 1/n through the modes alone. The streams (many kernels "
        "meeting several teeth) are chaotic: a small change early on (a kernel caught a little "
        "earlier) leads to different later collisions, so their peaks need not converge "
        "run by run; their statistics do not enter this table.",
        "",
        knead_text(before, after),
        "",
        full_table(results),
        "",
    ]
    out_md.write_text("\n".join(body))
    if readme is None:
        return
    text = readme.read_text()
    start, end = "<!-- convergence -->", "<!-- convergence-end -->"
    if start not in text or end not in text:
        raise SystemExit(f"README has no {start} ... {end} section")
    section = "\n".join([start, "", summary + " Details, all levels and why the others miss "
                         "it: [docs/convergence.md](docs/convergence.md). " +
                         knead_text(before, after), "", short_table(results), "", end])
    head, rest = text.split(start, 1)
    readme.write_text(head + section + rest.split(end, 1)[1])


def main():
    global TIME_LIMIT_S, REUSE
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--simulate", type=pathlib.Path, default=None)
    p.add_argument("--quick", action="store_true", help="two bench scenes, no README")
    p.add_argument("--out", type=pathlib.Path, default=ROOT / "docs/convergence.md")
    p.add_argument("--work", type=pathlib.Path, default=ROOT / ".build/convergence")
    p.add_argument("--jobs", type=int, default=max(1, min(2, os.cpu_count() or 1)))
    p.add_argument("--time-limit", type=float, default=TIME_LIMIT_S,
                   help="seconds per simulation before its level counts as timed out")
    p.add_argument("--reuse", action="store_true",
                   help="keep the summaries already in --work (to redo the tables)")
    a = p.parse_args()
    TIME_LIMIT_S, REUSE = a.time_limit, a.reuse
    simulate = a.simulate or default_simulate()
    a.work.mkdir(parents=True, exist_ok=True)
    todo = scenes(a.quick)
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = [pool.submit(study, simulate, name, args, a.work) for name, args in todo]
        knead = pool.submit(knead_before_after, simulate, a.work)
        results = [f.result() for f in futures]
        before, after = knead.result()
    for name, rows in results:
        print(f"{name}: {verdict(rows)}  " +
              "  ".join(f"{n}: N {m['fn']:.4g} T {m['ft']:.4g} v {m['v']:.4g}" for n, m in rows
                        if m is not None))
    print(knead_text(before, after))
    write_docs(results, before, after, a.out, None if a.quick else ROOT / "README.md")


if __name__ == "__main__":
    main()
