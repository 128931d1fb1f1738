#!/usr/bin/python3
"""Instructions to load and check a 1000-kernel scene (docs/scene_loading.md), under valgrind's
callgrind, as a user runs it: `simulate SCENE --check` (read, override, validate, compile with
the restitution fit set aside, print the resolved scene), Release build.

Two ways in, the bench stream's 1000 kernels (tslib.bench.islands.kernel_file, as
scripts/bench.py passes them):
  - from a file: config/bench/stream.yaml with the kernels written into it (one scene file);
  - through --set-file: config/bench/stream.yaml --set-file stream_kernels_1000.yaml.
For each binary given (default: this checkout's build), the whole process's instructions and,
inclusive, where they go: reading the YAML (the loader's reader, or yaml-cpp), the overrides,
the model (the sections, the start-overlap test, compileModel) and the resolved scene's text.

  scripts/loading_profile.py [--simulate BIN [BIN ...] [--labels NAME ...]] [--kernels N]
                             [--docs]

--docs writes the table into docs/scene_loading.md (its scene-loading markers); give the
binary before a change first, so the table reads before -> after.
"""
import argparse
import pathlib
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # tslib
from tslib import ROOT, markdown  # noqa: E402
from tslib.bench.islands import kernel_file  # noqa: E402
from tslib.bench.stages import STREAM  # noqa: E402
from tslib.binaries import find_binary  # noqa: E402
from tslib.callgrind import total_instructions  # noqa: E402


# (label, regular expression of callgrind_annotate's inclusive function names)
LOADING_PARTS = [
    ("read YAML", r"threshing_sim::(loader::)?readSceneFile\(|YAML::LoadFile\("),
    ("override files", r"threshing_sim::loader::applyOverrideEntries\(|"
                       r"threshing_sim::overridesFromFile\("),
    ("model (all below)", r"threshing_sim::modelFrom(Tree|Yaml)\("),
    ("model: start overlaps", r"threshing_sim::findInitialOverlap\("),
    ("model: compileModel", r"threshing_sim::compileModel\("),
    ("resolved scene text", r"threshing_sim::(app::\(anonymous namespace\)::)?writeFlow\("),
]


def scene_file(count, folder):
    """config/bench/stream.yaml with the count kernels of its override file in place of its
    placeholder kernel: one scene file."""
    kernels = pathlib.Path(kernel_file(count, False, folder)).read_text()
    text = STREAM.read_text()
    start, end = text.index("\nkernels:") + 1, text.index("\nobstacles:") + 1
    path = pathlib.Path(folder) / f"stream_scene_{count}.yaml"
    path.write_text(text[:start] + kernels[kernels.index("kernels:"):] + text[end:])
    return path


def profile_loading(binary, args, out):
    """(total, {part: inclusive instructions}) of one simulate run under callgrind."""
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", str(binary)]
                   + [str(a) for a in args], cwd=ROOT, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=True, timeout=3600)
    text = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(out)],
                          capture_output=True, text=True, check=True).stdout
    parts = {}
    for label, pattern in LOADING_PARTS:
        found = [int(m.group(1).replace(",", "")) for m in  # not a recursive call's ('2)
                 re.finditer(r"^\s*([\d,]+) \([^)]*\)\s+\S*?(?:" + pattern + r")(?!.*\)'\d)",
                             text, re.M)]
        parts[label] = max(found) if found else 0
    return total_instructions(out), parts


def loading_table(rows):
    names = [p for p, _ in LOADING_PARTS]
    lines = ["| binary | way in | whole process | " + " | ".join(names) + " |",
             "|" + "---|" * (3 + len(names))]
    for binary, way, total, parts in rows:
        cells = [f"{parts[p]:.3g}" if parts[p] else "-" for p in names]
        lines.append(f"| {binary} | {way} | {total:.3g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--simulate", nargs="+", help="simulate binaries (default: this build's)")
    p.add_argument("--labels", nargs="+", help="a name for each binary (default: 1, 2, ...)")
    p.add_argument("--kernels", type=int, default=1000, help="kernels of the stream (1000)")
    p.add_argument("--docs", action="store_true", help="write docs/scene_loading.md's table")
    args = p.parse_args()
    binaries = args.simulate or [find_binary("simulate")]
    labels = args.labels or [str(i + 1) for i in range(len(binaries))]
    if len(labels) != len(binaries):
        p.error("give one label per binary")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        kernels = kernel_file(args.kernels, False, tmp)
        ways = [("file", [scene_file(args.kernels, tmp), "--check"]),
                ("--set-file", [STREAM.relative_to(ROOT), "--set-file", kernels, "--check"])]
        for i, binary in enumerate(binaries):
            for way, run_args in ways:
                total, parts = profile_loading(binary, run_args, pathlib.Path(tmp) / f"cg.{i}.out")
                rows.append((labels[i], way, total, parts))
                print(f"{binary} ({way}): {total:.3g} instructions", file=sys.stderr, flush=True)
    text = loading_table(rows)
    legend = "\n".join(f"{label}: `{b}`" for label, b in zip(labels, binaries))
    print(text + "\n\n" + legend)
    if args.docs:
        body = (f"{args.kernels} kernels, `simulate ... --check`, callgrind instructions "
                "(inclusive for the parts; `scripts/loading_profile.py --docs`)\n\n" + text)
        print("wrote", markdown.splice("scene-loading", body))


if __name__ == "__main__":
    main()
