#!/usr/bin/python3
"""Byte-identical outputs of two `simulate` builds on every scene of config/ (a refactoring's
check: the loader split of issue 35 changes no output).

For each scene (config/default_scene.yaml and config/scenes/*.yaml; --all adds config/bench/
and config/hard/) and each override file of config/scenes/teeth/ and cases/ on the scenes it
is written for (every tooth on the single strike, the knead and the stream; the tip strike
with every tooth on the single strike; the large-deflection rod with the nylon and
polyurethane teeth on the knead), each binary writes, into a folder of its own: the summary
JSON, trace, events, outcomes and forces (a feed scene: outcomes and the feed series), its
stdout and stderr and exit status, the `--check` resolved scene and the `--modes` table, and
once the `--print-schema` table. The wall times (the JSON's "wall_time_s" and the readable
summary's "in ... of wall time") are masked and the progress lines on stderr (paced by the
wall clock) dropped; every other byte must agree.

  scripts/compare_scene_outputs.py --before OLD/simulate --after NEW/simulate [--all]
  scripts/compare_scene_outputs.py --simulate BIN --out DIR    (one binary's outputs)
  scripts/compare_scene_outputs.py --compare DIR_A DIR_B       (two folders of outputs)

Exits 1 and names every differing file when any output differs.
"""
import argparse
import filecmp
import pathlib
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # tslib
from tslib import CONFIG, ROOT, SCENE_DIR  # noqa: E402

WALL_JSON = re.compile(rb'"wall_time_s": [-+0-9.eE]+')
WALL_TEXT = re.compile(rb" in [-+0-9.eE]+ ?[mun]?s of wall time")
PROGRESS = re.compile(rb"^t=\S+ s  impacts=.*\n", re.M)  # paced by the wall clock


def compared_runs(everything):
    """The runs compared: (name, scene, override files), paths relative to the repository."""
    found = [CONFIG / "default_scene.yaml"] + sorted(SCENE_DIR.glob("*.yaml"))
    if everything:
        found += sorted((CONFIG / "bench").glob("*.yaml")) + sorted((CONFIG / "hard").glob("*.yaml"))
    runs = [(p, []) for p in found]
    teeth = sorted((SCENE_DIR / "teeth").glob("*.yaml"))
    cases = SCENE_DIR / "cases"
    for scene in ("single_strike", "knead", "stream"):
        runs += [(SCENE_DIR / (scene + ".yaml"), [t]) for t in teeth]
    runs += [(SCENE_DIR / "single_strike.yaml", [t, cases / "tip_strike.yaml"]) for t in teeth]
    runs += [(SCENE_DIR / "knead.yaml", [SCENE_DIR / "teeth" / (t + ".yaml"),
                                         cases / "large_deflection.yaml"])
             for t in ("nylon", "polyurethane")]
    rel = lambda p: p.relative_to(ROOT)  # noqa: E731
    return [("__".join(rel(p).with_suffix("").as_posix().replace("/", "_") for p in [scene] + files),
             rel(scene), [rel(f) for f in files]) for scene, files in runs]


def is_feed(scene):
    return re.search(r"^feed:", (ROOT / scene).read_text(), re.M) is not None


def run(binary, args, out, name):
    """Runs simulate with args in the repository; keeps stdout, stderr and the exit status."""
    done = subprocess.run([str(binary)] + args, cwd=ROOT, capture_output=True, timeout=3600)
    (out / (name + ".stdout")).write_bytes(WALL_TEXT.sub(b" in WALL of wall time", done.stdout))
    (out / (name + ".stderr")).write_bytes(PROGRESS.sub(b"", done.stderr))
    (out / (name + ".status")).write_text(str(done.returncode) + "\n")


def write_outputs(binary, out, everything):
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    run(binary, ["--print-schema"], out, "print_schema")
    for name, scene, set_files in compared_runs(everything):
        files = {"summary": out / (name + ".summary.json"), "outcomes": out / (name + ".outcomes.csv")}
        if is_feed(scene):
            files["feed-series"] = out / (name + ".feed_series.csv")
        else:
            files.update({"trace": out / (name + ".trace.csv"), "events": out / (name + ".events.csv"),
                          "forces": out / (name + ".forces.csv")})
        base = [str(scene)] + [a for f in set_files for a in ("--set-file", str(f))]
        args = list(base)
        for option, path in files.items():
            args += ["--" + option, str(path)]
        run(binary, args, out, name + ".run")
        summary = files["summary"]
        if summary.exists():
            summary.write_bytes(WALL_JSON.sub(b'"wall_time_s": WALL', summary.read_bytes()))
        run(binary, base + ["--check"], out, name + ".check")
        run(binary, base + ["--modes"], out, name + ".modes")
        print(f"{binary}: {' '.join(base)}", flush=True)


def compare(a, b):
    """The names of the files that differ or exist in one folder only."""
    a, b = pathlib.Path(a), pathlib.Path(b)
    names = sorted({p.name for p in a.iterdir()} | {p.name for p in b.iterdir()})
    differ = [n for n in names if not ((a / n).exists() and (b / n).exists()
                                       and filecmp.cmp(a / n, b / n, shallow=False))]
    print(f"{len(names) - len(differ)} of {len(names)} output files identical")
    for n in differ:
        print(f"differs: {n}")
    return differ


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", help="the simulate binary before the change")
    p.add_argument("--after", help="the simulate binary after the change")
    p.add_argument("--simulate", help="write one binary's outputs (with --out)")
    p.add_argument("--out", help="the folder --simulate writes")
    p.add_argument("--compare", nargs=2, metavar="DIR", help="compare two folders of outputs")
    p.add_argument("--all", action="store_true", help="config/bench/ and config/hard/ too")
    args = p.parse_args()
    if args.compare:
        return 1 if compare(*args.compare) else 0
    if args.simulate and args.out:
        write_outputs(args.simulate, args.out, args.all)
        return 0
    if not (args.before and args.after):
        p.error("give --before and --after, or --simulate with --out, or --compare")
    with tempfile.TemporaryDirectory() as tmp:
        write_outputs(args.before, pathlib.Path(tmp) / "before", args.all)
        write_outputs(args.after, pathlib.Path(tmp) / "after", args.all)
        return 1 if compare(pathlib.Path(tmp) / "before", pathlib.Path(tmp) / "after") else 0


if __name__ == "__main__":
    sys.exit(main())
