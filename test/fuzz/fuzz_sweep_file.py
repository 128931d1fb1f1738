#!/usr/bin/python3
"""Fuzz target over the sweep-file loader (scripts/tslib/sweep/spec.py; issue 25, item 4).

A seeded, deterministic mutation fuzzer: input i is made by its own random generator
(seed, i) from one of the real sweep files of config/sweeps/, with grammar-aware mutations
(huge numbers, deep nesting, aliases and YAML bombs, wrong types, long strings, hostile
expressions, unknown keys) on the parsed file and byte mutations on its text. Each input is
written to a scratch folder laid out as config/ (so that the corpus' relative paths resolve)
and loaded with spec.Sweep(); a sweep that loads is expanded (runs()) and its derived columns
are evaluated on hostile rows. The loader may refuse an input only with its own SweepError:
any other exception is a defect, and so is an input that takes more than --per-input seconds
of CPU time (SIGPROF in the worker: CPU rather than wall time, so that a loaded machine does
not make slow inputs of fast ones). A hang that no signal interrupts (in C code, or blocked
reading) is caught by the parent, which kills the worker after --hard-limit seconds (wall)
without progress and starts a new one after that input. The workers' address space is capped
(--memory-mb), so a memory bomb is a MemoryError (a defect), not a machine out of memory.
--jobs workers share the inputs (worker j: inputs j, j + jobs, ...). Every loop is bounded:
--inputs inputs or --max-seconds in all, whichever comes first; fewer than --min-inputs inputs
also fails.

  test/fuzz/fuzz_sweep_file.py [--inputs 100000] [--seed 1] [--max-seconds 85] [--jobs 2]
  test/fuzz/fuzz_sweep_file.py --replay 1234 [--seed 1]   (prints input 1234 and its verdict)

Defective inputs are saved as DIR/defect-<i>.yaml (--artifacts, default .build/fuzz_sweep).
Ends with one line: inputs, refused, loaded, defects, hangs, inputs/s; exit 1 on any defect.
"""
import argparse
import copy
import json
import marshal
import mmap
import os
import pathlib
import random
import resource
import signal
import struct
import subprocess
import sys
import tempfile
import time
import traceback

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

import yaml  # noqa: E402

from tslib.sweep import spec  # noqa: E402

CORPUS = sorted((ROOT / "config/sweeps").glob("*.yaml"))

# ------------------------------------------------------------------------------------------
# Hostile values and texts.

HUGE_NUMBERS = [0, -1, 1, 2, 10**9, 10**12, 2**31 - 1, 2**31, 2**63, 10**300, 10**400,
                -10**400, 10**4000, 1e308, -1e308, 1e-308, 5e-324, 1e300, 1e-300, 0.5,
                100000, 100001, 99999, float("inf"), float("-inf"), float("nan")]
EXPRESSIONS = [
    "10 ** 10 ** 10", "9 ** 9 ** 9 ** 9", "2 ** 1000000", "(-8) ** (1 / 3)", "1e308 * 1e308",
    "10 ** 400", "10.0 ** 400", "-(10 ** 10 ** 10)", "max(1, 10 ** 10 ** 10)",
    "sqrt(10 ** 10 ** 10)", "log10(0)", "sqrt(-1)", "1 / 0", "0 ** -1", "min()", "max(1)",
    "abs(1, 2)", "min(*kernels)", "sqrt(x=1)", "damaged * 1000000000", "tooth * 1000000000",
    "case * 10 ** 9", "drum_speed_rpm ** drum_speed_rpm ** drum_speed_rpm",
    "__import__('os').system('true')", "().__class__", "kernels.real", "[1] * 10 ** 9",
    "'a' * 10 ** 9", "lambda: 1", "a if b else c", "1 < 2 < 3", "not 1", "~1", "1 // 0",
    "1 % 0", "1 << 100000", "1j", "True + 1", "None", "...", "f'{1}'", "b'x'",
    "-" * 900 + "1", "+-" * 450 + "1", "(" * 150 + "1" + ")" * 150, "(" * 300 + "1" + ")" * 300,
    "1" * 4301, "1" * 999, "1.0e" + "9" * 400, "a" * 2000, "kernels" + " + kernels" * 120,
    "1 +" * 400 + " 1", "max(" * 40 + "1" + ", 2)" * 40, "min(" + ", ".join(["1"] * 300) + ")",
    "\x00", "1\n+1", "damaged / kernels", "damage_fraction ** 1e6", "pi ** pi ** pi ** pi",
    "drum_speed_rpm == 800", "seed * seed * seed * seed * seed * seed",
]
STRINGS = ["", " ", "x" * 4097, "x" * 100000, "a\tb", "a\nb", "a\x00b", "\u2028", "../" * 2000,
           "/dev/zero", "/dev/stdin", "/proc/self/fd/0", "/", ".", "..", "*", "teeth.*.length",
           "drum.speed", "stream.seed", "outcomes.kernels", "rpm", "rad/s", "findings", "\udcff",
           "../scenes/single_strike.yaml", "../scenes/stream.yaml", "a" * 256 + ".yaml",
           "%s" * 100, "{0}" * 100, "\\", "=", "a=b", "~", "null", "&a", "*a", "!!python/none"]
KEYS = sorted(spec.TOP_KEYS | spec.AXIS_KEYS | spec.GROUP_KEYS | spec.CASE_KEYS |
              {"count", "first", "step", "from", "to", "kind", "plots", "pareto", "x", "y",
               "lines", "color", "events", "forces", "unknown", "<<"})


def hostile_value(rng, depth=0):
    """A value of any kind, hostile more often than not."""
    kind = rng.randrange(12)
    if kind == 0:
        return rng.choice(HUGE_NUMBERS)
    if kind == 1:
        return rng.choice(EXPRESSIONS)
    if kind == 2:
        return rng.choice(STRINGS)
    if kind == 3:  # deep nesting
        value = rng.choice([1, "x", None])
        for _ in range(rng.choice([5, 31, 32, 33, 60, 200])):
            value = [value] if rng.random() < 0.5 else {"k": value}
        return value
    if kind == 4:  # long list (longer ones come from the text snippets)
        return [rng.choice(HUGE_NUMBERS[:6])] * rng.choice([2, 100, 1000])
    if kind == 5:
        return rng.choice([None, True, False, [], {}, [1, 2], {"a": 1}, "2001-02-30", 1.5])
    if kind == 6 and depth < 3:
        return {rng.choice(KEYS): hostile_value(rng, depth + 1) for _ in range(rng.randrange(4))}
    if kind == 7 and depth < 3:
        return [hostile_value(rng, depth + 1) for _ in range(rng.randrange(4))]
    if kind == 8:  # a range
        return {"from": rng.choice(HUGE_NUMBERS), "to": rng.choice(HUGE_NUMBERS),
                rng.choice(["step", "count"]): rng.choice(HUGE_NUMBERS)}
    if kind == 9:  # a seeds spec
        return {"count": rng.choice(HUGE_NUMBERS), "first": rng.choice(HUGE_NUMBERS),
                "key": rng.choice(STRINGS)}
    if kind == 10:  # an axis
        axis = {"name": rng.choice(["a", "b", "tooth", "x" * 100]),
                "key": rng.choice(["drum.speed", "teeth.*.length", "a\tb"])}
        form = rng.randrange(3)
        if form == 0:
            axis["values"] = [rng.choice(HUGE_NUMBERS) for _ in range(rng.randrange(1, 5))]
        elif form == 1:
            axis["range"] = hostile_value(rng, 3) if rng.random() < 0.2 else \
                {"from": 0, "to": rng.choice([1, 10**9, 1e300]), "count":
                 rng.choice([2, 1000, 100000, 100001, 10**9])}
        else:
            axis["unit"] = rng.choice(["rpm", "rad/s", [1], "x"])
            axis["values"] = [rng.choice(HUGE_NUMBERS)]
        return axis
    return rng.choice(HUGE_NUMBERS + STRINGS[:5])


def nodes(tree, path=()):
    """(path, node) of every node of a parsed file."""
    out, stack = [], [(path, tree)]
    while stack and len(out) < 5000:
        path, node = stack.pop()
        out.append((path, node))
        if isinstance(node, dict):
            stack.extend((path + (k,), v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((path + (i,), v) for i, v in enumerate(node))
    return out


def set_at(tree, path, value):
    if not path:
        return value
    parent = tree
    for step in path[:-1]:
        parent = parent[step]
    parent[path[-1]] = value
    return tree


def mutate_tree(rng, tree):
    """Grammar-aware mutations of a parsed sweep file."""
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        places = nodes(tree)
        path, node = rng.choice(places)
        op = rng.randrange(9)
        if op <= 2:      # replace a node by a hostile value
            tree = set_at(tree, path, hostile_value(rng))
        elif op == 3 and isinstance(node, dict):   # add a key
            node[rng.choice(KEYS)] = hostile_value(rng)
        elif op == 4 and isinstance(node, dict) and node:   # drop a key
            node.pop(rng.choice(list(node)))
        elif op == 5 and isinstance(node, list) and node:   # repeat an item
            node.extend([copy.deepcopy(rng.choice(node))] * rng.choice([1, 2, 40, 200]))
        elif op == 6 and isinstance(tree, dict):   # a hostile top-level key
            key = rng.choice(["seeds", "timeout", "derived", "axes", "groups", "set", "keep",
                              "report", "outcomes", "name", "scene", "set_files"])
            if key == "derived":
                tree[key] = {rng.choice(["d", "big", "x" * 50]): rng.choice(EXPRESSIONS)
                             for _ in range(rng.randrange(1, 4))}
            elif key == "keep":
                tree[key] = {rng.choice(["events", "forces"]): rng.choice(EXPRESSIONS)}
            elif key == "axes":
                tree[key] = [hostile_value(rng) if rng.random() < 0.3 else
                             {"name": f"a{j}", "key": "drum.speed",
                              "range": {"from": 1, "to": 2, "count": rng.choice(
                                  [2, 10, 400, 100000])}} for j in range(rng.choice(
                                      [1, 2, 3, 32, 33, 40]))]
            elif key == "seeds":
                tree[key] = rng.choice([10**9, 100000, 100001, -1, 0, 2**31, True, "3",
                                        {"count": 2, "first": 2**31 - 1}, {"count": 10**9}])
            else:
                tree[key] = hostile_value(rng)
        elif op == 7 and path:   # move a node elsewhere (wrong type for that key)
            other, _ = rng.choice(places)
            try:
                tree = set_at(tree, other, copy.deepcopy(node))
            except (KeyError, IndexError, TypeError):
                pass
        else:   # deep copy of a node in itself (size)
            if isinstance(node, (dict, list)):  # (bounded: at most 50 x 5000 nodes)
                tree = set_at(tree, path, [copy.deepcopy(node) for _ in range(
                    rng.choice([2, 10, 50]) if len(places) < 1000 else 2)])
    return tree


BOMB = ("a: &a [x, x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
        "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c]\n"
        "e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]\nf: &f [*e, *e, *e, *e, *e, *e, *e, *e]\n"
        "g: &g [*f, *f, *f, *f, *f, *f, *f, *f, *f, *f]\n")
SNIPPETS = [BOMB, "x: &r [*r]\n", "x: &r {a: *r}\n", "x: *undefined\n", "<<: 1\n",
            "seeds: 2001-02-30\n", "seeds: " + "9" * 5000 + "\n", "seeds: 0x" + "f" * 3000 + "\n",
            "seeds: 1:" + "59:" * 1000 + "1\n", "seeds: !!binary aGVsbG8=\n",
            "name: !!python/object/apply:os.system ['true']\n", "---\na: 1\n---\nb: 2\n",
            "timeout: .inf\n", "timeout: .nan\n", "scene: \"a\\0b\"\n", "set: {\"a\\tb\": 1}\n",
            "set: {x: \"a\\nb\"}\n", "[" * 100 + "]" * 100 + "\n", "{a: " * 50 + "1" + "}" * 50,
            "? [a, b]\n: c\n", "? {a: 1}\n: c\n", "1: 2\n", "null: x\n", "*x\n", "&x a: 1\n",
            "\"\\uDC80\": 1\n", "!!set {a, b}\n", "!!omap [a: 1]\n", "x: !!timestamp 2001-01-99\n",
            "x: !!int 1.5\n", "x: !!float abc\n", "\ufeff", "%YAML 1.1\n---\n",
            "%TAG ! tag:x,2000:\n---\n"]
# Large ones, rarely: past the node, alias, scalar, depth and size limits.
BIG_SNIPPETS = ["seeds: 3\naxes:\n- {name: v, key: drum.speed, values: [" + "1, " * 100001 +
                "1]}\n", "x: &x [1]\n" + "".join(f"y{i}: *x\n" for i in range(1001)),
                "name: " + "n" * 4097 + "\n", "x: " + "[" * 40 + "]" * 40 + "\n",
                "# " + "c" * (1 << 20) + "\n", "derived: {d: '" + "1 + " * 400 + "1'}\n"]


# Inputs are cut at this size: past the loader's file limit, and bounded for the generator.
MAX_INPUT_BYTES = spec.MAX_FILE_BYTES + 4096


def mutate_text(rng, text):
    """Byte-level mutations of a sweep file's text."""
    data = bytearray(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
    for _ in range(rng.choice([1, 1, 2, 4])):
        del data[MAX_INPUT_BYTES:]
        op = rng.randrange(9)
        pos = rng.randrange(len(data) + 1)
        if op == 0 and data:     # flip a byte
            data[min(pos, len(data) - 1)] = rng.randrange(256)
        elif op == 1:            # truncate
            del data[pos:]
        elif op == 2:            # insert a snippet, at a line start or anywhere
            snippet = rng.choice(SNIPPETS).encode("utf-8", "surrogatepass")
            if rng.random() < 0.7:
                pos = data.rfind(b"\n", 0, pos) + 1
            data[pos:pos] = snippet
        elif op == 3:            # insert YAML punctuation
            data[pos:pos] = rng.choice([b"[", b"]", b"{", b"}", b": ", b"- ", b"&a ", b"*a",
                                        b"<<: ", b"!!", b"'", b'"', b"#", b"\t", b"\0", b"\n  ",
                                        b"|\n", b">-\n", b"\xff", b"\xc3", b"? "])
        elif op == 4 and data:   # repeat a line
            start = data.rfind(b"\n", 0, pos) + 1
            end = data.find(b"\n", pos)
            line = bytes(data[start:end + 1 if end >= 0 else len(data)])
            data[start:start] = line[:4096] * rng.choice([2, 10, 1000])
        elif op == 5:            # a long run of one character
            data[pos:pos] = bytes([rng.choice(b"9a[{- \n")]) * rng.choice([100, 5000, 70000])
        elif op == 6:            # a digit run in a number's place
            data[pos:pos] = b"9" * rng.choice([20, 400, 4400])
        elif op == 7 and data:   # swap two chunks
            a, b = sorted(rng.randrange(len(data)) for _ in range(2))
            data[a:b] = data[a:b][::-1]
        else:                    # an expression in a scalar's place
            data[pos:pos] = rng.choice(EXPRESSIONS).encode("utf-8", "surrogatepass")
    return bytes(data[:MAX_INPUT_BYTES])


class Corpus:
    def __init__(self):
        self.texts = [p.read_text() for p in CORPUS]
        self.trees = [marshal.dumps(yaml.safe_load(t)) for t in self.texts]
        # Smaller files more often: more inputs per second, the same keys and forms.
        self.weights = [1 / (1 + len(t) / 2000) for t in self.texts]

    def make(self, seed, i):
        """Input i of the run with this seed: bytes."""
        rng = random.Random(seed * 1_000_003 + i)
        which = rng.choices(range(len(self.texts)), self.weights)[0]
        kind = rng.randrange(100)
        if kind < 60:    # tree mutation, dumped; sometimes text-mutated as well
            tree = mutate_tree(rng, marshal.loads(self.trees[which]))
            try:
                if rng.random() < 0.85:  # JSON is YAML (flow style), and quick to write
                    text = json.dumps(tree, ensure_ascii=rng.random() < 0.5)
                else:
                    text = yaml.dump(tree, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper),
                                     default_flow_style=rng.random() < 0.3, width=rng.choice(
                                         [80, 1 << 20]), allow_unicode=rng.random() < 0.5)
            except (yaml.YAMLError, ValueError, OverflowError, RecursionError):
                text = self.texts[which]
            data = text.encode("utf-8", "surrogatepass")[:MAX_INPUT_BYTES]
            return mutate_text(rng, data) if kind >= 50 else data
        if kind < 95:    # text mutation of the file
            return mutate_text(rng, self.texts[which])
        if kind < 99:
            return rng.choice(SNIPPETS).encode("utf-8", "surrogatepass") + \
                mutate_text(rng, self.texts[which])[:rng.randrange(1, 400)]
        return (mutate_text(rng, self.texts[which]) + b"\n" +
                rng.choice(BIG_SNIPPETS).encode())[:MAX_INPUT_BYTES]


# ------------------------------------------------------------------------------------------
# The worker: loads inputs under SIGALRM, reports each on stdout.

class Hang(Exception):
    pass


def _alarm(*_):
    raise Hang()


HOSTILE_ROWS = [
    {},
    {"damaged": 10**400, "kernels": 3, "detached": "x" * 1000, "tooth": "rigid" * 10,
     "drum_speed_rpm": 1e308, "case": [1, 2] * 10, "seed": 2**31 - 1, "wall_s": -1e308},
    {"damaged": "9" * 4000, "kernels": 0, "detached": float("nan"), "tooth": None,
     "drum_speed_rpm": True, "case": {"a": 1}, "seed": "", "cpu_s": float("inf")},
]


def check_one(path, data, per_input):
    """Loads one input; returns 'refused' or 'loaded'; raises on a defect (Hang included)."""
    path.write_bytes(data)
    signal.setitimer(signal.ITIMER_PROF, per_input)
    try:
        try:
            sweep = spec.Sweep(path)
        except spec.SweepError as e:
            str(e)
            return "refused"
        runs = sweep.runs() if sweep.run_count <= 300 else []
        assert sweep.run_count == len(runs) or not runs, (sweep.run_count, len(runs))
        for row in HOSTILE_ROWS + [dict(r.labels) for r in runs[:3]]:
            for expression in sweep.derived.values():
                value = expression.evaluate(row)
                assert isinstance(value, float), value
        return "loaded"
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)


# Progress of a worker, shared with the parent through a file mapped in both: the input being
# checked (-1: none), the next input, and the counts of each verdict.
SLOTS = ("current", "next", "refused", "loaded", "defects", "hangs")


def _slots(path):
    f = open(path, "r+b")
    return f, mmap.mmap(f.fileno(), 8 * len(SLOTS))


def _get(view, name):
    return struct.unpack_from("q", view, 8 * SLOTS.index(name))[0]


def _set(view, name, value):
    struct.pack_into("q", view, 8 * SLOTS.index(name), value)


def worker(args):
    """Checks inputs start, start + step, ... below stop; progress in the --progress file."""
    resource.setrlimit(resource.RLIMIT_AS, (args.memory_mb << 20, args.memory_mb << 20))
    signal.signal(signal.SIGPROF, _alarm)
    corpus = Corpus()
    artifacts = pathlib.Path(args.artifacts)
    path = pathlib.Path(args.scratch) / "sweeps" / f"fuzz_input_{args.start % args.step}.yaml"
    _, view = _slots(args.progress)
    parent = os.getppid()
    for i in range(args.start, args.stop, args.step):
        if i % 256 < args.step and os.getppid() != parent:
            return  # the driver is gone
        _set(view, "current", i)  # before the input is made: a worker that dies skips it
        data = corpus.make(args.seed, i)
        try:
            verdict = check_one(path, data, args.per_input)
        except Hang:
            verdict = "hang"
        except BaseException as e:  # noqa: B902  any other exception is a defect
            if isinstance(e, KeyboardInterrupt):
                raise
            where = traceback.extract_tb(e.__traceback__)[-1]
            verdict = (f"defect {type(e).__name__}: {str(e)[:200]!r} at "
                       f"{pathlib.Path(where.filename).name}:{where.lineno}")
        if verdict in ("refused", "loaded"):
            _set(view, verdict, _get(view, verdict) + 1)
        else:
            counter = "hangs" if verdict == "hang" else "defects"
            _set(view, counter, _get(view, counter) + 1)
            artifacts.mkdir(parents=True, exist_ok=True)
            (artifacts / f"defect-{i}.yaml").write_bytes(data)
            print(f"fuzz_sweep_file: input {i}: {verdict} "
                  f"(> {args.per_input} s)" if verdict == "hang" else
                  f"fuzz_sweep_file: input {i}: {verdict}", flush=True)
        _set(view, "next", i + args.step)
        _set(view, "current", -1)


def scratch_folder(base):
    """A folder laid out as config/ (sweeps/, scenes/ linked) for the corpus' paths."""
    folder = pathlib.Path(tempfile.mkdtemp(prefix="fuzz_sweep_", dir=base))
    (folder / "sweeps").mkdir()
    (folder / "scenes").symlink_to(ROOT / "config/scenes")
    (folder / "sweeps/materials").symlink_to(ROOT / "config/sweeps/materials")
    return folder


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--inputs", type=int, default=100_000)
    parser.add_argument("--min-inputs", type=int, default=None,
                        help="fail if fewer inputs were checked in --max-seconds "
                        "(default: --inputs)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    parser.add_argument("--max-seconds", type=float, default=85.0)
    parser.add_argument("--per-input", type=float, default=1.0,
                        help="CPU time limit per input (s, SIGPROF)")
    parser.add_argument("--hard-limit", type=float, default=10.0,
                        help="seconds without progress before the worker is killed")
    parser.add_argument("--memory-mb", type=int, default=2048)
    parser.add_argument("--artifacts", default=str(ROOT / ".build/fuzz_sweep"))
    parser.add_argument("--replay", type=int, help="print input N and its verdict")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--scratch", help=argparse.SUPPRESS)
    parser.add_argument("--start", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--stop", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--step", type=int, default=1, help=argparse.SUPPRESS)
    parser.add_argument("--progress", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args)
        return 0
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # cleans up (workers, scratch)
    base = "/dev/shm" if os.path.isdir("/dev/shm") and "TMPDIR" not in os.environ else None
    scratch = scratch_folder(base)
    try:
        if args.replay is not None:
            data = Corpus().make(args.seed, args.replay)
            sys.stdout.write(data.decode("utf-8", "replace")[:4000] + "\n---- verdict:\n")
            signal.signal(signal.SIGPROF, _alarm)
            try:
                print(check_one(scratch / "sweeps/replay.yaml", data, args.per_input))
            except spec.SweepError as e:
                print(f"refused: {e}")
            return 0
        return drive(args, scratch)
    finally:
        for p in sorted(scratch.rglob("*"), reverse=True):
            p.unlink() if p.is_file() or p.is_symlink() else p.rmdir()
        scratch.rmdir()


def drive(args, scratch):
    """Runs --jobs workers over inputs 0..--inputs-1 (worker j: the inputs j mod jobs) within
    --max-seconds; returns the exit code."""
    begin = time.monotonic()
    deadline = begin + args.max_seconds
    jobs = []
    for j in range(args.jobs):
        progress = scratch / f"progress_{j}"
        progress.write_bytes(bytes(8 * len(SLOTS)))
        f, view = _slots(progress)
        _set(view, "current", -1)
        _set(view, "next", j)
        jobs.append({"progress": progress, "file": f, "view": view, "proc": None,
                     "seen": (-1, 0.0), "killed": 0})

    def start(job):
        first = _get(job["view"], "next")
        if first >= args.inputs:
            return None
        return subprocess.Popen(
            [sys.executable, __file__, "--worker", "--scratch", str(scratch), "--progress",
             str(job["progress"]), "--start", str(first), "--stop", str(args.inputs), "--step",
             str(args.jobs), "--seed", str(args.seed), "--per-input", str(args.per_input),
             "--memory-mb", str(args.memory_mb), "--artifacts", args.artifacts])

    try:
        counts = _drive(args, jobs, start, begin, deadline)
    finally:  # the workers end with the driver, whatever ends it (SIGTERM: SystemExit)
        for job in jobs:
            if job["proc"] is not None and job["proc"].poll() is None:
                job["proc"].kill()
            if job["proc"] is not None:
                job["proc"].wait()
            job["view"].close()
            job["file"].close()
    elapsed = time.monotonic() - begin
    done = sum(counts.values())
    minimum = args.inputs if args.min_inputs is None else args.min_inputs
    print(f"fuzz_sweep_file: {done} inputs (seed {args.seed}, {args.jobs} workers), "
          f"{counts['refused']} refused, {counts['loaded']} loaded, {counts['defects']} "
          f"defects, {counts['hangs']} hangs, {elapsed:.1f} s, {done / elapsed:.0f} inputs/s")
    if done < minimum:
        print(f"fuzz_sweep_file: FAILED: {done} inputs in {args.max_seconds:g} s, fewer than "
              f"{minimum}")
        return 1
    if counts["defects"] or counts["hangs"]:
        print(f"fuzz_sweep_file: FAILED: inputs saved in {args.artifacts}; replay one with "
              f"--replay N --seed {args.seed}")
        return 1
    return 0


def _drive(args, jobs, start, begin, deadline):
    """The driver's loop: watches the workers' progress, restarts a worker after a hang or a
    death (the input skipped and counted); returns the counts of each verdict."""
    for job in jobs:
        job["proc"] = start(job)
    shown = begin
    while time.monotonic() < deadline and any(job["proc"] for job in jobs):
        time.sleep(0.1)
        now = time.monotonic()
        if now - shown >= 15:  # progress, for long runs
            shown = now
            done = sum(_get(job["view"], name) for job in jobs for name in SLOTS[2:])
            print(f"fuzz_sweep_file: {done} inputs, {now - begin:.0f} s", flush=True)
        for job in jobs:
            proc, view = job["proc"], job["view"]
            if proc is None:
                continue
            current = _get(view, "current")
            if proc.poll() is not None:  # ended: all its inputs done, or it died
                if current >= 0:  # died in the middle of an input: a defect; go on after it
                    print(f"fuzz_sweep_file: input {current}: worker died (exit "
                          f"{proc.returncode})", flush=True)
                    _set(view, "defects", _get(view, "defects") + 1)
                    _set(view, "next", current + args.jobs)
                    _set(view, "current", -1)
                job["proc"] = start(job)
                continue
            if current != job["seen"][0]:
                job["seen"] = (current, now)
            elif current >= 0 and now - job["seen"][1] > args.hard_limit:
                # No progress on one input: a hang that no signal interrupts (C code).
                proc.kill()
                proc.wait()
                print(f"fuzz_sweep_file: input {current}: hang (no progress for "
                      f"{args.hard_limit:g} s; worker killed)", flush=True)
                pathlib.Path(args.artifacts).mkdir(parents=True, exist_ok=True)
                (pathlib.Path(args.artifacts) / f"defect-{current}.yaml").write_bytes(
                    Corpus().make(args.seed, current))
                _set(view, "hangs", _get(view, "hangs") + 1)
                _set(view, "next", current + args.jobs)
                _set(view, "current", -1)
                job["proc"] = start(job)
    return {name: sum(_get(job["view"], name) for job in jobs) for name in SLOTS[2:]}


if __name__ == "__main__":
    sys.exit(main())
