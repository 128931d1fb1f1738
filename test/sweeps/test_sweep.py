#!/usr/bin/python3
"""Sweep runner tests on a real Dask cluster on this machine (scripts/sweep, docs/sweeps.md).

Starts a dask-scheduler and two dask-worker processes (no nanny) on 127.0.0.1 and runs the
small sweep (config/sweeps/small.yaml) against them; checks that its table equals the one of
a local-cluster run apart from wall/CPU times and worker names, that killing one worker in the
middle of the sweep loses no result, that a sweep interrupted in the middle resumes from the
cache, and that failures (crash, timeout) are recorded without stopping the sweep, and that a
bad axis is refused before anything runs. Every wait has a timeout; every process started here
is killed at the end. Writes a JUnit XML file (--xml) for scripts/test.sh's count.
"""
import csv
import json
import math
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import unittest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from sweep_test_util import ROOT, SWEEP, fresh_folder, load, parser, run_suite, sweep  # noqa: E402

sys.path.insert(0, str(ROOT / "scripts"))
from tslib.sweep.cluster import LoopbackCluster, wait_for  # noqa: E402

SMALL = ROOT / "config/sweeps/small.yaml"
ARGS = None  # command line (simulate, out)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


class SweepTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.out = fresh_folder(ARGS.out)
        cls.simulate = ARGS.simulate
        # The reference: the small sweep on a local cluster of two workers.
        cls.local = cls.out / "local"
        proc = sweep("run", SMALL, "--simulate", cls.simulate, "--out", cls.local,
                     "--workers", 2)
        assert proc.returncode == 0, proc.stderr
        cls.cluster = LoopbackCluster(cls.out / "cluster_processes", workers=2)
        try:
            cls.cluster.start()
        except BaseException:
            cls.cluster.stop()
            raise

    @classmethod
    def tearDownClass(cls):
        cls.cluster.stop()

    def test_local_table(self):
        table = rows(self.local / "runs.csv")
        self.assertEqual(len(table), 18)
        self.assertEqual([int(r["run"]) for r in table], list(range(18)))
        self.assertTrue(all(r["status"] == "ok" for r in table), table)
        # Axis columns, in sweep order: tooth slowest, seed fastest.
        self.assertEqual(table[0]["tooth"], "rigid")
        self.assertEqual(table[-1]["tooth"], "polyurethane")
        self.assertEqual([r["drum_speed_rpm"] for r in table[:6]],
                         ["800", "800", "1000", "1000", "1200", "1200"])
        self.assertEqual([r["seed"] for r in table[:2]], ["1", "2"])
        for r in table:
            self.assertGreater(float(r["cpu_s"]), 0)
            self.assertAlmostEqual(float(r["damage_fraction"]),
                                   float(r["damaged"]) / float(r["kernels"]))
        # Seeds give different streams, so different numbers.
        self.assertNotEqual(table[0]["peak_normal_force_N"], table[1]["peak_normal_force_N"])
        kernels = rows(self.local / "kernels.csv")
        self.assertEqual(len(kernels), 18 * 4)

    def test_report(self):
        proc = sweep("report", self.local)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        report = (self.local / "report.md").read_text()
        self.assertIn("18 runs: 18 ok", report)
        images = [line.split("](")[1].rstrip(")") for line in report.splitlines()
                  if line.startswith("![")]
        self.assertEqual(len(images), 4)  # the four plots of small.yaml's report section
        for name in images:
            png = (self.local / name).read_bytes()
            self.assertEqual(png[1:4], b"PNG", name)
            self.assertGreater(len(png), 10000, name)
        self.assertIn("| tooth | drum_speed_rpm | detachment_fraction | damage_fraction |",
                      report)

    def test_findings_sweep_is_compare_teeth(self):
        """config/sweeps/findings.yaml resolves, run for run, to the scenes and outputs of
        compare_teeth.py's sweep (its full one, not --quick)."""
        import compare_teeth as ct
        from tslib.sweep import spec
        sweep_file = spec.Sweep(ROOT / "config/sweeps/findings.yaml")
        runs = sweep_file.runs()
        spec.validate(sweep_file, runs, self.simulate, "sha", jobs=2)
        mine = {}
        for r in runs:
            labels = r.labels
            modes = labels.get("modes", 0 if labels["group"] == "frozen" else None)
            mine[(labels["group"], labels["case"], labels["tooth"], labels["drum_speed_rpm"],
                  modes)] = (r.scene, r.keep)
        out = self.out / "ct"
        theirs = [ct.ToothRun(out, "sweep", c, v, r, forces=r == ct.HISTORY_RPM)
                  for c in ct.CASES for v in ct.VARIANTS for r in ct.RPM_FULL]
        theirs += [ct.ToothRun(out, "frozen", c, v, r, modes=0)
                   for c in ct.FROZEN_CASES for v in ct.FLEXIBLE for r in ct.RPM_FULL]
        theirs += [ct.ToothRun(out, "convergence", "single_strike", v, ct.HISTORY_RPM, modes=m)
                   for v in ct.FLEXIBLE for m in ct.CONVERGENCE_MODES]
        theirs += [ct.ToothRun(out, "euler_bernoulli", c, v, ct.HISTORY_RPM,
                          rotation="euler_bernoulli")
                   for c in ct.FROZEN_CASES for v in ct.FLEXIBLE]
        theirs += [ct.ToothRun(out, "modal", c, v, ct.HISTORY_RPM, model="modal")
                   for c, teeth in ct.LARGE_DEFLECTION.items() for v in teeth]
        self.assertEqual(len(mine), len(theirs))
        commands = [t.command(self.simulate) for t in theirs]
        text = "".join("\t".join(c[1:c.index("--summary")]) + "\n" for c in commands)
        answer = subprocess.run([self.simulate, "--check-batch", "-"], input=text, text=True,
                                capture_output=True, timeout=120).stdout.splitlines()
        self.assertEqual(len(answer), len(theirs))
        for t, line in zip(theirs, answer):
            scene, keep = mine[(t.group, t.case, t.variant, t.rpm, t.modes)]
            self.assertEqual(line.split("\t")[:2], ["ok", scene], t.label())
            self.assertEqual(keep, sorted(["events"] + (["forces"] if t.forces else [])))

    def test_rpm_and_range(self):
        """800 rpm reaches the scene as 800 (pi / 30) rad/s (compare_teeth.py's conversion):
        the same numbers, to the last bit, as simulate run by hand with that drum speed."""
        summary = self.out / "hand.json"
        subprocess.run([self.simulate, str(ROOT / "config/scenes/stream.yaml"), "--set-file",
                        str(ROOT / "config/scenes/teeth/rigid.yaml"), "--set",
                        "stream.count=4", "--set", "duration=0.004", "--set",
                        f"drum.speed={800 * (math.pi / 30)!r}", "--set", "stream.seed=1",
                        "--summary", str(summary), "--quiet"], check=True, timeout=60)
        import json
        hand = json.loads(summary.read_text())["outcomes"]["peak_normal_force_N"]
        self.assertEqual(rows(self.local / "runs.csv")[0]["peak_normal_force_N"], repr(hand))

    def test_cluster_equals_local_despite_killed_worker(self):
        out = self.out / "cluster"
        with open(self.out / "cluster_sweep.log", "w") as log:
            client = subprocess.Popen(
                [sys.executable, str(SWEEP), "run", str(SMALL), "--simulate", self.simulate,
                 "--out", str(out), "--scheduler", self.cluster.address, "--batch", "3"],
                stdout=log, stderr=log, start_new_session=True)
        victim, survivor = self.cluster.workers[0], self.cluster.workers[1]
        try:
            # Kill worker 0 once a third of the runs are in. Both workers stop first, so that
            # the kill falls in the middle of the sweep even if the client lags behind them.
            wait_for(lambda: (out / "runs.csv").exists() and len(rows(out / "runs.csv")) >= 6,
                     90, "six results")
            for w in (victim, survivor):
                os.kill(w.pid, signal.SIGSTOP)
            at_kill = len(rows(out / "runs.csv"))
            os.killpg(victim.pid, signal.SIGKILL)
            victim.wait(timeout=10)
            os.kill(survivor.pid, signal.SIGCONT)
            self.assertEqual(client.wait(timeout=120), 0,
                             (self.out / "cluster_sweep.log").read_text())
        finally:
            if survivor.poll() is None:
                os.kill(survivor.pid, signal.SIGCONT)
            if client.poll() is None:
                os.killpg(client.pid, signal.SIGKILL)
                client.wait(timeout=10)
        self.assertLess(at_kill, 18, "the sweep ended before the worker was killed")
        proc = sweep("compare", self.local / "runs.csv", out / "runs.csv")
        self.assertEqual(proc.returncode, 0, proc.stdout)
        table = rows(out / "runs.csv")
        self.assertTrue(all(r["status"] == "ok" for r in table))
        # Both workers ran some of the runs, and the survivor finished the sweep.
        hosts = {r["worker"] for r in table}
        self.assertEqual(len(hosts), 2, hosts)
        self.assertIn(f":{victim.pid}", " ".join(hosts))

    def test_interrupted_sweep_resumes_from_cache(self):
        out = self.out / "resume"
        log_path = self.out / "resume_sweep.log"
        with open(log_path, "w") as log:
            client = subprocess.Popen(
                [sys.executable, str(SWEEP), "run", str(SMALL), "--simulate", self.simulate,
                 "--out", str(out), "--scheduler", self.cluster.address, "--batch", "1"],
                stdout=log, stderr=log, start_new_session=True)
        workers = [w for w in self.cluster.workers if w.poll() is None]
        try:
            wait_for(lambda: (out / "runs.csv").exists() and len(rows(out / "runs.csv")) >= 4,
                     90, "four results")
            # The workers stop at once, so that the sweep cannot end before the client is
            # killed (on a busy machine the client could otherwise fall behind them).
            for w in workers:
                os.kill(w.pid, signal.SIGSTOP)
            os.killpg(client.pid, signal.SIGKILL)
            client.wait(timeout=10)
        finally:
            if client.poll() is None:
                os.killpg(client.pid, signal.SIGKILL)
                client.wait(timeout=10)
            for w in workers:
                os.kill(w.pid, signal.SIGCONT)
        done = len(rows(out / "runs.csv"))
        self.assertLess(done, 18, "the sweep ended before it was interrupted:\n" +
                        log_path.read_text())
        proc = sweep("run", SMALL, "--simulate", self.simulate, "--out", out, "--scheduler",
                     self.cluster.address)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        cached = int(proc.stderr.split(" runs (")[1].split(" from the cache")[0])
        self.assertGreaterEqual(cached, done)
        self.assertLess(cached, 18)
        self.assertEqual(sweep("compare", self.local / "runs.csv", out / "runs.csv").returncode,
                         0)
        # A third invocation runs nothing.
        proc = sweep("run", SMALL, "--simulate", self.simulate, "--out", out, "--workers", 1)
        self.assertIn("18 runs (18 from the cache)", proc.stderr)

    def test_failures_are_recorded(self):
        """A crashing run (simulate killed by SIGSEGV) and a run past its timeout (one that
        hangs) are recorded with their messages; the others complete, also those after them in
        the same batch (a new simulate --batch process takes them). A wrapper around the real
        binary passes each --batch line to it, but crashes or hangs on chosen scenes."""
        wrapper = self.out / "crashy_simulate"
        wrapper.write_text(
            "#!/usr/bin/python3\n"
            "import os, signal, subprocess, sys, time\n"
            f"REAL = {str(self.simulate)!r}\n"
            "if '--batch' not in sys.argv:\n"
            "    os.execv(REAL, [REAL] + sys.argv[1:])\n"
            "for line in sys.stdin:\n"
            "    # The run's --set values (the runner's lines), or its resolved scene.\n"
            "    if 'restitution=0.3\"' in line or 'restitution: 0.3,' in line:\n"
            "        os.kill(os.getpid(), signal.SIGSEGV)\n"
            "    if 'duration=0.003\"' in line or 'duration: 0.003,' in line:\n"
            "        time.sleep(60)\n"
            "    sys.stdout.write(subprocess.run([REAL, '--batch', '-'], input=line, text=True,\n"
            "                                    stdout=subprocess.PIPE, timeout=60).stdout)\n"
            "    sys.stdout.flush()\n")
        wrapper.chmod(0o755)
        spec = self.out / "failures.yaml"
        spec.write_text(
            f"scene: {ROOT / 'config/scenes/single_strike.yaml'}\n"
            "axes:\n"
            "  - {name: e, key: contact.tooth_kernel.restitution, values: [0.48, 0.3]}\n"
            "  - {name: duration, key: duration, values: [0.002, 0.003]}\n"
            "timeout: 1.5\n")
        out = self.out / "failures"
        # One batch of the four runs: ok, timeout, crash, crash (e, then duration).
        proc = sweep("run", spec, "--simulate", wrapper, "--out", out, "--workers", 2,
                     "--batch", 4)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        table = {(r["e"], r["duration"]): r for r in rows(out / "runs.csv")}
        self.assertEqual(table[("0.48", "0.002")]["status"], "ok")
        self.assertEqual(table[("0.3", "0.002")]["status"], "crash")
        self.assertIn("SIGSEGV", table[("0.3", "0.002")]["message"])
        self.assertEqual(table[("0.48", "0.003")]["status"], "timeout")
        self.assertIn("no result after 1.5 s", table[("0.48", "0.003")]["message"])
        self.assertIn("4 runs (0 from the cache), 3 not ok", proc.stderr)

    def test_failures_are_recorded_with_validation_first(self):
        """As test_failures_are_recorded, without --batch: the shares are held (the wrapper
        answers the barrier for the lines it holds) and run by id; a process that crashes or
        hangs is replaced by one that takes the runs it had left as whole lines."""
        wrapper = self.out / "crashy_held_simulate"
        wrapper.write_text(
            "#!/usr/bin/python3\n"
            "import json, os, signal, subprocess, sys, time\n"
            f"REAL = {str(self.simulate)!r}\n"
            "if '--batch' not in sys.argv:\n"
            "    os.execv(REAL, [REAL] + sys.argv[1:])\n"
            "def run(line):\n"
            "    if 'restitution=0.3\"' in line:\n"
            "        os.kill(os.getpid(), signal.SIGSEGV)\n"
            "    if 'duration=0.003\"' in line:\n"
            "        time.sleep(60)\n"
            "    sys.stdout.write(subprocess.run([REAL, '--batch', '-'], input=line, text=True,\n"
            "                                    stdout=subprocess.PIPE, timeout=60).stdout)\n"
            "    sys.stdout.flush()\n"
            "held, holding = {}, False\n"
            "for line in sys.stdin:\n"
            "    message = json.loads(line)\n"
            "    if 'hold' in message:\n"
            "        holding = True\n"
            "    elif 'barrier' in message:\n"
            "        holding = False\n"
            "        print(json.dumps({'barrier': True, 'lines': len(held), 'invalid': []}),\n"
            "              flush=True)\n"
            "    elif 'run' in message:\n"
            "        for key in message['run']:\n"
            "            run(held.pop(key))\n"
            "    elif holding:\n"
            "        held[message['id']] = line\n"
            "    else:\n"
            "        run(line)\n")
        wrapper.chmod(0o755)
        spec = self.out / "failures_held.yaml"
        spec.write_text(
            f"scene: {ROOT / 'config/scenes/single_strike.yaml'}\n"
            "axes:\n"
            "  - {name: e, key: contact.tooth_kernel.restitution, values: [0.48, 0.3]}\n"
            "  - {name: duration, key: duration, values: [0.002, 0.003, 0.0021]}\n"
            "timeout: 1.5\n")
        out = self.out / "failures_held"
        proc = sweep("run", spec, "--simulate", wrapper, "--out", out, "--workers", 2)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        table = {(r["e"], r["duration"]): r for r in rows(out / "runs.csv")}
        for duration in ("0.002", "0.0021"):
            self.assertEqual(table[("0.48", duration)]["status"], "ok")
            self.assertEqual(table[("0.3", duration)]["status"], "crash")
            self.assertIn("SIGSEGV", table[("0.3", duration)]["message"])
        self.assertEqual(table[("0.48", "0.003")]["status"], "timeout")
        self.assertIn("no result after 1.5 s", table[("0.48", "0.003")]["message"])
        self.assertIn(table[("0.3", "0.003")]["status"], ("crash", "timeout"))
        self.assertIn("6 runs (0 from the cache), 4 not ok", proc.stderr)
        stats = json.loads((out / "run_stats.json").read_text())
        self.assertGreaterEqual(stats["processes"], 4)  # two shares, then their replacements

    def test_bad_axis_refused_before_running(self):
        spec = self.out / "bad.yaml"
        spec.write_text(
            f"scene: {ROOT / 'config/scenes/single_strike.yaml'}\n"
            "axes:\n"
            "  - {name: length, key: teeth.*.length, values: [0.06, -0.01]}\n")
        out = self.out / "bad"
        proc = sweep("run", spec, "--simulate", self.simulate, "--out", out)
        self.assertEqual(proc.returncode, 2)
        self.assertIn("teeth.0.length: must be in [1e-5, 10] (got -0.01)", proc.stderr)
        self.assertIn("length=-0.01", proc.stderr)
        self.assertFalse(out.exists(), "a run started before the validation")
        spec.write_text(
            f"scene: {ROOT / 'config/scenes/single_strike.yaml'}\n"
            "axes:\n  - {name: speed, key: drum.sped, unit: rpm, values: [800]}\n")
        proc = sweep("check", spec, "--simulate", self.simulate)
        self.assertEqual(proc.returncode, 2)
        self.assertIn("drum.sped", proc.stderr)


# ------------------------------------------------------------------------------------------
# JUnit XML for catkin's result count.

class BinaryLookupTest(unittest.TestCase):
    """scripts/sweep finds simulate in a sourced catkin workspace without --simulate (issue 24:
    "simulate not found" unless the checkout's own .build/ws held it)."""

    def setUp(self):
        from tslib import binaries
        self.binaries = binaries
        self.saved = (binaries.BIN_DIR, dict(os.environ))
        self.ws = pathlib.Path(ARGS.out) / "sourced_ws"
        shutil.rmtree(self.ws, ignore_errors=True)
        self.lib = self.ws / "devel/lib/threshing_sim"
        self.lib.mkdir(parents=True)
        (self.lib / "simulate").symlink_to(pathlib.Path(ARGS.simulate).resolve())
        # As in a workspace built elsewhere: nothing in this checkout's .build, no override.
        binaries.BIN_DIR = self.ws / "absent"
        os.environ.pop("THRESHING_SIM_SIMULATE", None)

    def tearDown(self):
        self.binaries.BIN_DIR = self.saved[0]
        os.environ.clear()
        os.environ.update(self.saved[1])

    def test_found_under_cmake_prefix_path(self):
        os.environ["CMAKE_PREFIX_PATH"] = os.pathsep.join(
            [str(self.ws / "other"), str(self.ws / "devel"), "/usr"])
        from tslib.sweep.runner import resolve_simulate
        self.assertEqual(resolve_simulate(None), (self.lib / "simulate").resolve())
        # And the binary found runs.
        proc = subprocess.run([str(resolve_simulate(None)), str(ROOT / "config/default_scene.yaml"),
                               "--check"], capture_output=True, text=True, timeout=60)
        self.assertEqual(proc.returncode, 0, proc.stderr)

    def test_not_found_names_where_it_looked(self):
        os.environ["CMAKE_PREFIX_PATH"] = str(self.ws / "other")
        from tslib.sweep.runner import resolve_simulate
        with self.assertRaises(SystemExit) as caught:
            resolve_simulate(None)
        self.assertIn("CMAKE_PREFIX_PATH", str(caught.exception))


def main():
    global ARGS
    p = parser(__doc__, out="sweep_test")
    p.add_argument("--only-lookup", action="store_true",
                   help="only the binary lookup tests (no cluster)")
    ARGS = p.parse_args()
    cases = (BinaryLookupTest,) if ARGS.only_lookup else (BinaryLookupTest, SweepTest)
    return run_suite(load(*cases), ARGS.xml, "test_sweep")[0]


if __name__ == "__main__":
    sys.exit(main())
