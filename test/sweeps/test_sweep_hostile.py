#!/usr/bin/python3
"""Hostile sweep files are refused, never hung (issue 25, item 4; docs/sweeps.md "Limits").

One test per hostile case: each writes a sweep file past one limit of
scripts/tslib/sweep/spec.py and asserts that spec.Sweep refuses it with a SweepError naming the
key (and the limit) in less than 1 s of CPU time (and 3 s of wall time: the machine is shared). Before the limits, `seeds: 1000000000` made
`scripts/sweep check` run out of memory, and a derived `10 ** 10 ** 10` passed `check` and
hung `scripts/sweep run`: the two cases are also run through the command, which must refuse
them (exit 2) before anything runs. The evaluator's own bounds (float arithmetic: no huge
integer, no repeated string) are checked on rows, and the Limits table of docs/sweeps.md
against spec.LIMITS. Every test has a watchdog (SIGALRM) and the process's address space is
capped, so code without the limits fails the tests instead of hanging them or the machine.
Writes a JUnit XML file (--xml) for scripts/test.sh's count.

  test/sweeps/test_sweep_hostile.py [--simulate PATH] [--xml FILE] [--scripts DIR] [TEST...]
  (--scripts: the tslib.sweep to test, e.g. another checkout's scripts/ folder)
"""
import math
import os
import pathlib
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from sweep_test_util import ROOT, parser, run_suite  # noqa: E402

SCENE = ROOT / "config/scenes/single_strike.yaml"
ARGS = None
TIMES = []  # (test, CPU seconds) of each refusal
spec = None  # tslib.sweep.spec, imported in main() from --scripts

REFUSE_S = 1.0     # a hostile file is refused within this CPU time
REFUSE_WALL_S = 3.0  # and this wall time (slack for a loaded machine)
WATCHDOG_S = 10    # a test that takes longer fails (instead of hanging)


class Watchdog(Exception):
    pass


def _alarm(*_):
    raise Watchdog(f"no answer after {WATCHDOG_S} s")


class HostileTest(unittest.TestCase):
    """spec.Sweep on hostile files: refused in < 1 s with the key and the limit named."""

    def setUp(self):
        self.dir = pathlib.Path(tempfile.mkdtemp(prefix="sweep_hostile_"))
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(WATCHDOG_S)

    def tearDown(self):
        signal.alarm(0)
        shutil.rmtree(self.dir)

    def write(self, text, name="hostile.yaml"):
        path = self.dir / name
        path.write_text(text) if isinstance(text, str) else path.write_bytes(text)
        return path

    def refused(self, text, *expected, head=f"scene: {SCENE}\n"):
        """Asserts that the file (head + text) is refused in < 1 s with each expected part
        in the message; returns the message."""
        path = self.write(head + text if isinstance(text, str) else text)
        started, cpu = time.monotonic(), time.process_time()
        with self.assertRaises(spec.SweepError) as caught:
            spec.Sweep(path)
        elapsed, cpu = time.monotonic() - started, time.process_time() - cpu
        message = str(caught.exception)
        self.assertLess(cpu, REFUSE_S, f"refused after {cpu:.2f} s of CPU: {message}")
        self.assertLess(elapsed, REFUSE_WALL_S, f"refused after {elapsed:.2f} s: {message}")
        TIMES.append((self.id().rpartition(".")[2], cpu))
        for part in expected:
            self.assertIn(part, message)
        self.assertLess(len(message), 2000, "the message repeats the hostile value")
        return message

    def accepted(self, text, head=f"scene: {SCENE}\n"):
        path = self.write(head + text)
        cpu = time.process_time()
        sweep = spec.Sweep(path)
        self.assertLess(time.process_time() - cpu, REFUSE_S)
        return sweep

    # -- the issue's two cases -------------------------------------------------------------

    def test_seeds_count(self):
        self.refused("seeds: 1000000000\n",
                     f"seeds: 1000000000 exceeds the limit of {spec.MAX_RUNS} runs")
        self.refused("seeds: {count: 1000000000, first: 3}\n",
                     f"seeds: 1000000000 exceeds the limit of {spec.MAX_RUNS} runs")
        # The limit itself is accepted (and counted without expanding anything).
        self.assertEqual(self.accepted(f"seeds: {spec.MAX_RUNS}\n").run_count, spec.MAX_RUNS)
        self.refused(f"seeds: {spec.MAX_RUNS + 1}\n", f"seeds: {spec.MAX_RUNS + 1} exceeds")

    def test_last_seed(self):
        self.refused(f"seeds: {{count: 2, first: {spec.MAX_SEED}}}\n",
                     f"seeds: the last seed {spec.MAX_SEED + 1}", f"limit of {spec.MAX_SEED}")

    def test_derived_power_tower(self):
        self.refused("derived:\n  big: 10 ** 10 ** 10\n",
                     "derived.big: '10 ** 10 ** 10' exceeds the limit of 1e+300 in magnitude")
        # A constant part of an expression over columns.
        self.refused("derived:\n  d: 'kernels + 9 ** 9 ** 9'\n", "derived.d: '9 ** 9 ** 9' "
                     "exceeds the limit of 1e+300", "(in 'kernels + 9 ** 9 ** 9')")
        self.refused("derived:\n  d: " + "9" * 400 + "\n", "derived.d:", "exceeds the limit")
        self.refused("derived:\n  d: 2 ** 1000000\n", "derived.d: '2 ** 1000000' exceeds")

    def test_keep_condition_power_tower(self):
        self.refused("axes: [{name: s, key: drum.speed, values: [1, 2]}]\n"
                     "keep: {events: 's == 10 ** 10 ** 10'}\n",
                     "keep.events: '10 ** 10 ** 10' exceeds the limit")

    # -- expressions: size, depth, calls ---------------------------------------------------

    def test_expression_length(self):
        text = "kernels" + " + 1" * 300
        self.refused(f"derived:\n  d: '{text}'\n",
                     f"derived.d: an expression of {len(text)} characters exceeds the limit of "
                     f"{spec.MAX_EXPRESSION_CHARS}")

    def test_expression_nodes(self):
        self.refused("derived:\n  d: 'min(" + ", ".join(["a"] * 250) + ")'\n",
                     f"derived.d: more than {spec.MAX_EXPRESSION_NODES} operators and operands "
                     f"exceed the limit of {spec.MAX_EXPRESSION_NODES}")

    def test_expression_depth(self):
        self.refused("derived:\n  d: '" + "-" * 900 + "kernels'\n",
                     f"derived.d: nesting deeper than the limit of {spec.MAX_EXPRESSION_DEPTH}")
        self.refused("derived:\n  d: '" + "(" * 300 + "1" + ")" * 300 + "'\n",
                     "derived.d: not an expression")

    def test_expression_calls(self):
        self.refused("derived:\n  d: 'min()'\n", "derived.d: min takes 2 or more argument(s)")
        self.refused("derived:\n  d: 'sqrt(1, 2)'\n", "derived.d: sqrt takes 1 argument(s)")
        self.refused("derived:\n  d: \"'a' * 1000000000\"\n", "derived.d: unsupported element")

    def test_evaluation_is_bounded(self):
        """Numbers are floats while evaluating: no integer of 10^10 digits, no repeated
        label, whatever the row holds (the runs' outcomes and labels)."""
        def evaluate(text, row, names):
            expression = spec.Expression("derived.d", text, names)
            cpu = time.process_time()
            value = expression.evaluate(row)
            self.assertLess(time.process_time() - cpu, REFUSE_S, text)
            return value

        self.assertTrue(math.isnan(evaluate("damaged ** kernels ** kernels",
                                            {"damaged": 10, "kernels": 10},
                                            ["damaged", "kernels"])))
        self.assertTrue(math.isnan(evaluate("tooth * 1000000000", {"tooth": "rigid"},
                                            ["tooth"])))
        self.assertTrue(math.isnan(evaluate("case * kernels", {"case": [1, 2],
                                                               "kernels": 10**9},
                                            ["case", "kernels"])))
        self.assertTrue(math.isnan(evaluate("kernels * 2", {"kernels": 10**400}, ["kernels"])))
        # Ordinary values are as before.
        self.assertEqual(evaluate("damaged / kernels", {"damaged": 3, "kernels": 4},
                                  ["damaged", "kernels"]), 0.75)
        self.assertEqual(evaluate("tooth == tooth", {"tooth": "rigid"}, ["tooth"]), 1.0)
        self.assertEqual(evaluate("s == 800", {"s": 800}, ["s"]), 1.0)

    # -- runs and axes ---------------------------------------------------------------------

    def test_runs_product(self):
        self.refused("axes:\n"
                     "  - {name: a, key: drum.speed, range: {from: 1, to: 2, count: 100000}}\n"
                     "  - {name: b, key: duration, range: {from: 1, to: 2, count: 100000}}\n",
                     "axes: 100000 (a) x 100000 (b) values give 10000000000 runs",
                     f"exceeds the limit of {spec.MAX_RUNS} runs")
        self.refused("seeds: 1000\naxes:\n"
                     "  - {name: a, key: drum.speed, range: {from: 1, to: 2, count: 1000}}\n",
                     "axes: 1000 (a) values give 1000000 runs")

    def test_runs_over_groups(self):
        groups = "".join(f"  - {{name: g{i}, axes: [{{name: a, key: drum.speed, range: "
                         f"{{from: 1, to: 2, count: 40000}}}}]}}\n" for i in range(3))
        self.refused("groups:\n" + groups, "groups[2].axes: 40000 (a) values give 40000 runs "
                     "(and 80000 runs before)", f"limit of {spec.MAX_RUNS} runs")

    def test_range_count_and_step(self):
        self.refused("axes: [{name: a, key: drum.speed, range: {from: 0, to: 1, "
                     "count: 1000000000}}]\n",
                     f"range.count: 1000000000 exceeds the limit of {spec.MAX_AXIS_VALUES}")
        self.refused("axes: [{name: a, key: drum.speed, range: {from: 0, to: 1, "
                     "step: 1.0e-12}}]\n", "axes[0] (a).range.step: 1e-12 from 0 to 1 gives",
                     f"exceeds the limit of {spec.MAX_AXIS_VALUES} values")
        self.refused("axes: [{name: a, key: drum.speed, range: {from: -1.0e+300, "
                     "to: 1.0e+300, step: 1.0e-300}}]\n", "range.step")
        self.refused("axes: [{name: a, key: drum.speed, unit: rpm, range: {from: 0, "
                     "to: 1.0e+301, count: 2}}]\n", "range.to: 1e+301 exceeds the limit of "
                     "1e+300 in magnitude")

    def test_number_magnitude(self):
        # An integer past a float's range (was OverflowError, not a SweepError).
        self.refused("axes: [{name: a, key: drum.speed, unit: rpm, values: [1" + "0" * 400 +
                     "]}]\n", "axes[0] (a).values:", "exceeds the limit of 1e+300")

    def test_axes_count(self):
        axes = "".join(f"  - {{name: a{i}, key: drum.speed, values: [1]}}\n" for i in range(33))
        self.refused("axes:\n" + axes, f"axes: 33 axes exceed the limit of {spec.MAX_AXES}")

    def test_groups_count(self):
        groups = "".join(f"  - {{name: g{i}}}\n" for i in range(spec.MAX_GROUPS + 1))
        self.refused("groups:\n" + groups, f"groups: {spec.MAX_GROUPS + 1} groups exceed the "
                     f"limit of {spec.MAX_GROUPS}")

    def test_list_lengths(self):
        n = spec.MAX_OVERRIDES + 1
        self.refused("set:\n" + "".join(f"  k{i}: 1\n" for i in range(n)),
                     f"set: {n} key paths to values exceed the limit of {spec.MAX_OVERRIDES}")
        self.refused("set_files: [" + ", ".join([str(SCENE)] * n) + "]\n",
                     f"set_files: {n} entries exceed the limit of {spec.MAX_OVERRIDES}")
        self.refused("outcomes: [" + ", ".join(["steps"] * (spec.MAX_OUTCOMES + 1)) + "]\n",
                     f"outcomes: {spec.MAX_OUTCOMES + 1} outcomes exceed the limit")
        self.refused("derived:\n" + "".join(f"  d{i}: kernels\n"
                                            for i in range(spec.MAX_DERIVED + 1)),
                     f"derived: {spec.MAX_DERIVED + 1} derived columns (column: expression) "
                     f"exceed the limit of {spec.MAX_DERIVED}")
        self.refused("report:\n  plots:\n" + "".join("    - {x: a, y: b}\n" for _ in range(
            spec.MAX_PLOTS + 1)), f"report.plots: {spec.MAX_PLOTS + 1} plots exceed the limit")

    def test_batch_size(self):
        """100000 runs of 1000 overrides of 60 bytes: 6 GB of simulate arguments."""
        sets = "".join(f"  k{i}: '{'v' * 60}'\n" for i in range(1000))
        self.refused("seeds: 100000\nset:\n" + sets, "axes: 100000 runs of up to",
                     f"exceed the limit of {spec.MAX_BATCH_BYTES} bytes in all")

    def test_timeout(self):
        self.refused("timeout: 1000000000\n", "timeout: must be > 0 s and at most the limit "
                     f"of {spec.MAX_TIMEOUT_S:g} s (got 1000000000)")
        self.refused("timeout: .inf\n", "timeout: expected a finite number (got inf)")
        self.refused("timeout: 0\n", "timeout: must be > 0 s")

    # -- the file and its YAML -------------------------------------------------------------

    def test_file_size(self):
        self.refused("# " + "x" * spec.MAX_FILE_BYTES + "\n",
                     f"bytes exceed the limit of {spec.MAX_FILE_BYTES} bytes")

    def test_not_a_regular_file(self):
        fifo = self.dir / "fifo.yaml"
        os.mkfifo(fifo)
        cpu = time.process_time()
        for path in (fifo, pathlib.Path("/dev/zero"), self.dir):
            with self.assertRaises(spec.SweepError) as caught:
                spec.Sweep(path)
            self.assertIn("not a regular file", str(caught.exception))
        self.assertLess(time.process_time() - cpu, REFUSE_S)

    def test_yaml_bomb(self):
        lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
        for prev, name in zip("abcdefgh", "bcdefghi"):
            lines.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 10) + "]")
        self.refused("\n".join(lines) + "\n",
                     f"more than {spec.MAX_YAML_NODES} YAML nodes (aliases expanded) exceed "
                     f"the limit of {spec.MAX_YAML_NODES}", head="")
        # The same bomb in a key that takes any value: set (was a hang in _scene_text).
        self.refused("bomb: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
            f"l{i}: &{'abcdefg'[i]} [" + ", ".join(["*" + ("a" if i == 0 else
                                                           "abcdefg"[i - 1])] * 10) + "]\n"
            for i in range(1, 7)) + "set: {x: *f}\n", "YAML nodes", head="")

    def test_recursive_alias(self):
        self.refused("set: &s {x: *s}\n", "set.x: alias *s (line 2) refers to no complete node")

    def test_alias_count(self):
        self.refused("x: &x 1\n" + "".join(f"y{i}: *x\n" for i in range(spec.MAX_YAML_ALIASES + 1)),
                     f"y{spec.MAX_YAML_ALIASES}: more than {spec.MAX_YAML_ALIASES} aliases "
                     f"exceed the limit", head="")

    def test_nesting_depth(self):
        self.refused("set:\n  x: " + "[" * 40 + "]" * 40 + "\n", "set.x[0][0]",
                     f"nesting deeper than the limit of {spec.MAX_YAML_DEPTH}")
        self.refused("derived: " + "{a: " * 40 + "1" + "}" * 40 + "\n", "derived.a.a.a",
                     f"nesting deeper than the limit of {spec.MAX_YAML_DEPTH}")

    def test_string_length(self):
        self.refused("name: " + "n" * (spec.MAX_STRING_CHARS + 1) + "\n",
                     f"name: a scalar of {spec.MAX_STRING_CHARS + 1} characters exceeds the "
                     f"limit of {spec.MAX_STRING_CHARS}")
        self.refused("seeds: " + "9" * 5000 + "\n", "seeds: a scalar of 5000 characters")

    def test_yaml_values_python_refuses(self):
        """Values PyYAML scans but cannot build (were ValueError, AttributeError)."""
        self.refused("seeds: 2001-02-30\n", "not a valid YAML value (ValueError")
        self.refused("x: !!timestamp 2001-01-99\n", "not a valid YAML value", head="")
        self.refused("x: !!int 1.5\n", "not a valid YAML value", head="")
        self.refused(b"name: \xff\xfe\n", "not UTF-8 text")

    # -- wrong types and characters --------------------------------------------------------

    def test_wrong_types(self):
        self.refused("1: a\nb: c\n", "unknown key(s) [1, 'b']", head="")
        self.refused("axes: [{name: a, key: drum.speed, unit: [rpm], values: [1]}]\n",
                     "axes[0] (a).unit: expected one of ['rad/s', 'rpm'] (got ['rpm'])")
        self.refused("keep: [[events]]\n", "keep: expected outputs among")
        self.refused("report: {kind: [findings]}\n", "report.kind: expected one of")
        self.refused("report: {plots: [{pareto: 1}]}\n", "report.plots[0]: expected column names")
        self.refused("seeds: {count: 2, key: [a]}\n", "seeds.key: expected a scene key path")

    def test_bad_paths(self):
        self.refused("set_files: ['" + "a" * 300 + "']\n", "set_files: not a usable path")
        self.refused('set_files: ["a\\0b"]\n', "set_files: not a usable path")
        self.refused("name: ../../etc\n", "name: expected a folder name")

    def test_control_characters(self):
        """A tab or a line break in an argument would split simulate --check-batch's lines:
        the check would validate another sweep than the one that runs."""
        self.refused('set: {"duration": "0.1\\n"}\n', "set.duration: control characters")
        self.refused('set: {"a\\tb": 1}\n', "control characters")
        self.refused('axes: [{name: a, key: "drum.speed\\n", values: [1]}]\n',
                     "axes[0] (a).key: control characters")
        # A lone surrogate (simulate --check-batch's input could not be encoded): refused by
        # the YAML parser (libyaml), else by the arguments' check.
        self.refused('set: {duration: "\\udc80"}\n', "Unicode")

    def test_corpus_accepted(self):
        """The real sweep files are within the limits, well under 1 s each."""
        for path in sorted((ROOT / "config/sweeps").glob("*.yaml")):
            cpu = time.process_time()
            sweep = spec.Sweep(path)
            self.assertLess(time.process_time() - cpu, REFUSE_S, path)
            self.assertEqual(sweep.run_count, len(sweep.runs()), path)

    def test_limits_table_in_docs(self):
        """docs/sweeps.md's Limits table is spec.limits_markdown() (regenerate with
        test/sweeps/test_sweep_hostile.py --write-doc)."""
        text = (ROOT / "docs/sweeps.md").read_text()
        begin, end = "<!-- sweep-limits -->\n", "\n<!-- sweep-limits-end -->"
        self.assertIn(begin, text)
        self.assertEqual(text.split(begin, 1)[1].split(end, 1)[0], spec.limits_markdown())
        for name, value, _, _ in spec.LIMITS:
            self.assertEqual(getattr(spec, name), value)


class CommandTest(unittest.TestCase):
    """The issue's two cases through scripts/sweep: refused (exit 2) before anything runs."""

    def setUp(self):
        self.dir = pathlib.Path(tempfile.mkdtemp(prefix="sweep_hostile_cmd_"))

    def tearDown(self):
        shutil.rmtree(self.dir)

    def command(self, *args):
        started = time.monotonic()
        command = pathlib.Path(ARGS.scripts) / "sweep"
        proc = subprocess.run([sys.executable, str(command), *map(str, args), "--simulate",
                               ARGS.simulate], capture_output=True, text=True, timeout=60)
        return proc, time.monotonic() - started

    def test_check_seeds(self):
        path = self.dir / "seeds.yaml"
        path.write_text(f"scene: {SCENE}\nseeds: 1000000000\n")
        proc, elapsed = self.command("check", path)
        self.assertEqual(proc.returncode, 2, proc.stderr)
        self.assertIn("seeds: 1000000000 exceeds the limit of", proc.stderr)
        self.assertNotIn("Traceback", proc.stderr)
        print(f"  scripts/sweep check (seeds: 1000000000): refused in {elapsed:.2f} s "
              "(Python start included)", file=sys.stderr)

    def test_run_derived_power_tower(self):
        path = self.dir / "pow.yaml"
        path.write_text(f"scene: {SCENE}\nset: {{duration: 0.0005}}\n"
                        "derived:\n  big: 10 ** 10 ** 10\n")
        out = self.dir / "out"
        proc, elapsed = self.command("run", path, "--out", out, "--workers", 1)
        self.assertEqual(proc.returncode, 2, proc.stderr)
        self.assertIn("derived.big: '10 ** 10 ** 10' exceeds the limit", proc.stderr)
        self.assertFalse(out.exists(), "a run started before the refusal")
        print(f"  scripts/sweep run (derived 10 ** 10 ** 10): refused in {elapsed:.2f} s "
              "(Python start included)", file=sys.stderr)


# ------------------------------------------------------------------------------------------

def main():
    global ARGS, spec
    p = parser(__doc__)
    p.add_argument("--scripts", default=str(ROOT / "scripts"),
                   help="folder holding the tslib package (tslib.sweep) to test")
    p.add_argument("tests", nargs="*", help="only these tests, e.g. "
                   "HostileTest.test_seeds_count")
    p.add_argument("--write-doc", action="store_true",
                   help="write spec.limits_markdown() into docs/sweeps.md and exit")
    ARGS = p.parse_args()
    sys.path.insert(0, ARGS.scripts)
    from tslib.sweep import spec as module
    spec = module
    if ARGS.write_doc:
        path = ROOT / "docs/sweeps.md"
        text = path.read_text()
        begin, end = "<!-- sweep-limits -->\n", "\n<!-- sweep-limits-end -->"
        head, rest = text.split(begin, 1)
        path.write_text(head + begin + spec.limits_markdown() + end + rest.split(end, 1)[1])
        return 0
    # Code without the limits may try to build a billion seeds: a MemoryError, not a machine
    # out of memory.
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    suite = unittest.TestSuite()
    if ARGS.tests:
        suite.addTests(unittest.defaultTestLoader.loadTestsFromNames(
            ARGS.tests, sys.modules[__name__]))
    for case in () if ARGS.tests else (HostileTest, CommandTest):
        suite.addTests(unittest.defaultTestLoader.loadTestsFromTestCase(case))
    status, _ = run_suite(suite, ARGS.xml, "test_sweep_hostile")
    if TIMES:
        slowest = max(TIMES, key=lambda t: t[1])
        print(f"{len(TIMES)} refusals, the slowest {slowest[1] * 1e3:.1f} ms of CPU "
              f"({slowest[0]})", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
