#!/usr/bin/python3
"""simulate --batch against separate simulate processes, bit for bit (docs/sweeps.md, docs/cli.md).

A sweep file with every axis kind (a files list and a files mapping, values, a range by step
and by count, a unit, cases with their own scene, override files and overrides, seeds, groups
with their own overrides, and keep, conditional too) is expanded and validated. Every run is
then run as its own simulate process (the run's arguments: scene, --set-file, --set) and
compared with:

- simulate --batch with the same arguments as lines (scene trees parsed once, overrides per run);
- simulate --batch with the resolved scenes as text;
- simulate --batch with each run's base scene as text and its --set overrides (the runner's
  lines: one parse per base scene, the overrides applied to a copy of its tree);
- simulate --batch with validation first (hold, barrier, go or run by id), the models kept
  or compiled again;
- scripts/sweep run locally, with validation first (one share per worker) and with --batch (the
  runs handed out in batches), its table and kept files;
- scripts/sweep run on a dask-scheduler with two dask-workers on 127.0.0.1.

Summaries must be equal apart from the wall_time_s line; outcomes, events and forces byte for
byte. A bad line gives an error line naming the bad value and the batch continues. Every wait
has a timeout; the cluster started here is stopped at the end. Writes JUnit XML (--xml).
"""
import csv
import json
import os
import pathlib
import subprocess
import sys
import unittest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from sweep_test_util import ROOT, fresh_folder, load, parser, run_suite  # noqa: E402

sys.path.insert(0, str(ROOT / "scripts"))
from tslib.sweep import runner, spec  # noqa: E402
from tslib.sweep.cluster import LoopbackCluster  # noqa: E402

ARGS = None
SCENES = ROOT / "config/scenes"
OUTPUTS = ("summary", "outcomes", "events", "forces")

SWEEP = f"""
name: every_axis
scene: {SCENES}/stream.yaml
set_files: [{SCENES}/teeth/nylon.yaml]
set: {{stream.count: 2, duration: 0.0015}}
axes:
  - {{name: tooth, files: [{SCENES}/teeth/rigid.yaml, {SCENES}/teeth/polyurethane.yaml]}}
seeds: {{count: 2, key: stream.seed, first: 3}}
keep: [events]
groups:
  - name: speed
    axes:
      - {{name: drum_speed, key: drum.speed, unit: rpm, range: {{from: 800, to: 1100, step: 300}}}}
      - {{name: length, key: teeth.*.length, values: [0.055, 0.062]}}
    keep: {{events: true, forces: "drum_speed_rpm == 800"}}
  - name: restitution
    axes:
      - {{name: e, key: contact.tooth_kernel.restitution, range: {{from: 0.3, to: 0.5, count: 2}}}}
  - name: case
    set: {{duration: 0.0012}}
    axes:
      - name: scene
        cases:
          plain: {{scene: {SCENES}/stream.yaml, set: {{stream.count: 3}}}}
          steel: {{scene: {SCENES}/stream.yaml, set_files: [{SCENES}/teeth/spring_steel.yaml],
                  set: {{stream.count: 1, drum.speed: 120.5}}}}
outcomes: [outcomes.peak_normal_force_N, outcomes.detached, outcomes.kernels, steps, impacts]
timeout: 120
"""


def without_wall_time(summary):
    """The summary without its one line that is a measurement (wall_time_s)."""
    return "\n".join(line for line in summary.splitlines() if '"wall_time_s"' not in line)


def batch(simulate, lines, timeout=300):
    """simulate --batch - on the lines; returns the parsed result lines and the exit code."""
    proc = subprocess.run([simulate, "--batch", "-"], input="".join(json.dumps(x) + "\n"
                          for x in lines), capture_output=True, text=True, timeout=timeout)
    return [json.loads(line) for line in proc.stdout.splitlines()], proc.returncode


class BatchTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.out = fresh_folder(ARGS.out)
        cls.simulate = ARGS.simulate
        cls.sweep_file = cls.out / "every_axis.yaml"
        cls.sweep_file.write_text(SWEEP)
        cls.sweep = spec.Sweep(cls.sweep_file)
        cls.runs = cls.sweep.runs()
        spec.validate(cls.sweep, cls.runs, cls.simulate, runner.binary_sha(cls.simulate), jobs=2)
        cls.separate = [cls.run_separately(run) for run in cls.runs]

    @classmethod
    def run_separately(cls, run):
        """The run as its own simulate process: its outputs' texts by name."""
        folder = cls.out / "separate" / str(run.index)
        folder.mkdir(parents=True)
        command = [cls.simulate, *run.arguments, "--quiet"]
        names = ["summary", "outcomes", *run.keep]
        for name in names:
            command += [f"--{name}", str(folder / name)]
        proc = subprocess.run(command, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, (command, proc.stderr)
        return {name: (folder / name).read_text() for name in names}

    def assert_same_outputs(self, run, outputs, where):
        reference = self.separate[run.index]
        for name in OUTPUTS:
            if name not in reference:
                continue
            mine, theirs = outputs.get(name), reference[name]
            self.assertIsNotNone(mine, f"{where}: run {run.index} has no {name}")
            if name == "summary":
                mine, theirs = without_wall_time(mine), without_wall_time(theirs)
            self.assertEqual(mine, theirs, f"{where}: run {run.index} ({run.labels}): {name}")

    def test_sweep_covers_every_axis_kind(self):
        kinds = {a.kind for g in self.sweep.groups for a in g.axes}
        self.assertEqual(kinds, {"files", "values", "range", "cases"})
        self.assertTrue(any(a.unit for g in self.sweep.groups for a in g.axes))
        self.assertEqual(len(self.runs), 2 * 2 * (4 + 2 + 2))
        self.assertEqual(sum("forces" in r.keep for r in self.runs), 8)
        # Runs differ where their resolved scenes do (seeds, speeds, teeth all reach the
        # scene); the steel case's override file sets the whole tooth, so its two teeth are one
        # run (one key, run once by the sweep).
        keys = {r.key for r in self.runs}
        self.assertEqual(len(keys), len(self.runs) - 2)
        self.assertEqual(len({without_wall_time(s["summary"]) for s in self.separate}),
                         len(keys))

    def test_batch_of_arguments(self):
        lines = [{"id": f"run{r.index}", "args": r.arguments, "return": ["summary", "outcomes",
                                                                         *r.keep]}
                 for r in self.runs]
        results, code = batch(self.simulate, lines)
        self.assertEqual(code, 0)
        self.assertEqual([x["id"] for x in results], [f"run{r.index}" for r in self.runs])
        for run, result in zip(self.runs, results):
            self.assertEqual(result["status"], "ok", result["message"])
            self.assertGreater(result["cpu_s"], 0)
            self.assert_same_outputs(run, result, "batch of arguments")

    def test_batch_of_resolved_scenes(self):
        lines = [{"id": r.key, "scene_yaml": r.scene, "return": ["summary", "outcomes",
                                                                  *r.keep]}
                 for r in reversed(self.runs)]  # another order: no state carried between runs
        results, code = batch(self.simulate, lines)
        self.assertEqual(code, 0)
        for run, result in zip(reversed(self.runs), results):
            self.assertEqual(result["id"], run.key)
            self.assert_same_outputs(run, result, "batch of resolved scenes")

    def test_batch_of_base_scenes_and_overrides(self):
        # The runner's lines: each run's base scene (scene and override files, from
        # --check-batch) and its --set overrides, applied in the batch process to a copy of the
        # base's tree, parsed once per base; in reverse order and then in sweep order.
        scenes = [runner._scene_of(r) for r in self.runs]
        self.assertTrue(all(s["scene"] == r.base for s, r in zip(scenes, self.runs)))
        self.assertTrue(all(s["args"] and s["args"][::2] == ["--set"] * (len(s["args"]) // 2)
                            for s in scenes))
        self.assertLess(len(set(r.base for r in self.runs)), len(self.runs) // 2)
        order = list(reversed(self.runs)) + list(self.runs)
        lines = [{"id": r.key, "scene_yaml": scenes[r.index]["scene"],
                  "args": scenes[r.index]["args"], "return": ["summary", "outcomes", *r.keep]}
                 for r in order]
        results, code = batch(self.simulate, lines)
        self.assertEqual(code, 0)
        self.assertEqual(len(results), len(order))
        for run, result in zip(order, results):
            self.assertEqual(result["id"], run.key)
            self.assertEqual(result["status"], "ok", result["message"])
            self.assert_same_outputs(run, result, "batch of base scenes and overrides")

    def test_bad_lines_are_reported_and_the_batch_goes_on(self):
        # Run 0 keeps its forces: --forces samples near contacts, so the line asks for them.
        good = {"id": "good", "args": self.runs[0].arguments,
                "return": ["summary", "outcomes", *self.runs[0].keep]}
        lines = [{"id": "speed", "args": [*self.runs[0].arguments, "--set", "drum.speed=fast"]},
                 good,
                 {"id": "option", "args": [*self.runs[0].arguments, "--trace-every", "0"]},
                 {"id": "key", "args": self.runs[0].arguments, "retrun": ["summary"]},
                 {"id": "output", "args": self.runs[0].arguments, "return": ["movie"]},
                 {"id": "modes", "args": [*self.runs[0].arguments, "--modes"]},
                 {"id": "yaml", "scene_yaml": "{drum: [1, 2"},
                 {"id": "unié \U0001F600", "args": [0.06]},  # sent as \u escapes
                 good]
        text = "".join(json.dumps(x) + "\n" for x in lines[:3]) + "{not json\n" + \
            "".join(json.dumps(x) + "\n" for x in lines[3:])
        proc = subprocess.run([self.simulate, "--batch", "-"], input=text, capture_output=True,
                              text=True, timeout=120)
        self.assertEqual(proc.returncode, 2)
        results = {x["id"]: x for x in map(json.loads, proc.stdout.splitlines())}
        self.assertEqual(len(results), 9)  # the two good lines share their id
        expected = {"speed": "fast", "option": "'0'", "4": "JSON", "key": "'retrun'",
                    "output": "'movie'", "modes": "--modes", "yaml": "(scene_yaml):1",
                    "unié \U0001F600": "expected a string (got 0.06)"}
        for name, word in expected.items():
            self.assertEqual(results[name]["status"], "error", name)
            self.assertEqual(results[name]["exit"], 2, name)
            self.assertIn(word, results[name]["message"], name)
        self.assertEqual(results["good"]["status"], "ok")
        self.assert_same_outputs(self.runs[0], results["good"], "after bad lines")

    def held_lines(self, runs):
        """The runner's lines for the runs (base scene, --set values, the scene's name)."""
        lines = []
        for run in runs:
            scene = runner._scene_of(run)
            lines.append({"id": run.key, "scene_yaml": scene["scene"],
                          "scene_name": scene["scene_name"], "args": scene["args"],
                          "return": ["summary", "outcomes", *run.keep]})
        return lines

    def distinct_runs(self):
        return list({r.key: r for r in self.runs}.values())

    def test_validation_first(self):
        """{"hold": ...}, the runs' lines, {"barrier": s} and then {"go": true}: the barrier's
        answer comes before any run, then the runs on the models compiled for the answer
        (with {"hold": 0} none is kept: each is compiled again), equal to separate processes;
        a run's cpu_s includes its validation."""
        runs = self.distinct_runs()
        for hold in (True, 0):
            text = "".join(json.dumps(x) + "\n" for x in [{"hold": hold}, *self.held_lines(runs),
                                                          {"barrier": 60}, {"go": True}])
            proc = subprocess.run([self.simulate, "--batch", "-"], input=text,
                                  capture_output=True, text=True, timeout=300)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            answers = [json.loads(line) for line in proc.stdout.splitlines()]
            self.assertEqual(answers[0], {"barrier": True, "lines": len(runs), "invalid": []})
            self.assertEqual([a["id"] for a in answers[1:]], [r.key for r in runs])
            for run, result in zip(runs, answers[1:]):
                self.assertEqual(result["status"], "ok", result["message"])
                self.assertGreater(result["cpu_s"], 0)
                self.assert_same_outputs(run, result, f"held lines (hold {hold})")

    def test_held_lines_run_by_id(self):
        """{"run": [ids]} after the barrier runs those held lines in that order (the runner's
        shares); an id not held, or run already, is an error line; a whole run line runs as
        usual (a run taken from another process's share); the lines not run are dropped at the
        end of the input."""
        runs = self.distinct_runs()
        held, other = runs[:6], runs[6]
        lines = [{"hold": True}, *self.held_lines(held), {"barrier": 60},
                 {"run": [held[3].key, held[1].key]}, {"run": [held[1].key, "nosuch"]},
                 *self.held_lines([other]), {"run": [held[0].key]}]
        proc = subprocess.run([self.simulate, "--batch", "-"], capture_output=True, text=True,
                              input="".join(json.dumps(x) + "\n" for x in lines), timeout=300)
        self.assertEqual(proc.returncode, 2, proc.stderr)  # the two error lines
        answers = [json.loads(line) for line in proc.stdout.splitlines()]
        self.assertEqual(answers[0]["invalid"], [])
        results = answers[1:]
        self.assertEqual([r["id"] for r in results],
                         [held[3].key, held[1].key, held[1].key, "nosuch", other.key,
                          held[0].key])
        for i in (2, 3):
            self.assertEqual(results[i]["status"], "error")
            self.assertIn("no held line", results[i]["message"])
        for run, result in zip([held[3], held[1], other, held[0]],
                               [results[0], results[1], results[4], results[5]]):
            self.assertEqual(result["status"], "ok", result["message"])
            self.assert_same_outputs(run, result, "held lines run by id")

    def test_validation_first_refuses(self):
        """The barrier names every invalid held line with the loader's message (the scene
        named by scene_name, as simulate --check-batch names it); {"go": false} ends the batch
        (exit 2) without a run; no decision within the barrier's timeout ends it too."""
        good = self.held_lines([self.runs[0]])[0]
        speed = dict(good, id="speed", args=[*good["args"], "--set", "drum.speed=fast"])
        length = dict(good, id="length", args=[*good["args"], "--set", "teeth.*.length=-0.01"])
        head = [{"hold": True}, good, speed, length, {"barrier": 60}]
        proc = subprocess.run([self.simulate, "--batch", "-"], capture_output=True, text=True,
                              input="".join(json.dumps(x) + "\n" for x in
                                            head + [{"go": False}]), timeout=120)
        self.assertEqual(proc.returncode, 2)
        answers = [json.loads(line) for line in proc.stdout.splitlines()]
        self.assertEqual(len(answers), 1, "a run before the go")
        invalid = {x["id"]: x["message"] for x in answers[0]["invalid"]}
        self.assertEqual(set(invalid), {"speed", "length"})
        self.assertIn(f"{good['scene_name']}: drum.speed: expected a number (got fast)",
                      invalid["speed"])
        self.assertIn("teeth.0.length: must be in [1e-5, 10] (got -0.01)", invalid["length"])
        self.assertIn("no go after the barrier; 3 held runs not run", proc.stderr)
        # No decision: the input stays open; the process ends by itself after the timeout.
        head[-1] = {"barrier": 1}
        proc = subprocess.Popen([self.simulate, "--batch", "-"], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            proc.stdin.write("".join(json.dumps(x) + "\n" for x in head))
            proc.stdin.flush()
            self.assertEqual(proc.wait(timeout=30), 2)
            self.assertIn("no go within 1 s of the barrier", proc.stderr.read())
        finally:
            proc.kill()
            proc.wait()

    def check_sweep_output(self, out, where):
        """A sweep's table and kept files against the separate processes."""
        with open(out / "runs.csv", newline="") as f:
            table = list(csv.DictReader(f))
        self.assertEqual(len(table), len(self.runs))
        for run, row in zip(self.runs, table):
            self.assertEqual(row["status"], "ok", row["message"])
            self.assertEqual(row["key"], run.key)
            summary = json.loads(self.separate[run.index]["summary"])
            for column, path in self.sweep.outcomes.items():
                value = runner._lookup(summary, path)
                self.assertEqual(row[column], str(value), f"{where}: run {run.index} {column}")
            folder = out / "files" / run.key
            kept = {name: (folder / (name + (".json" if name == "summary" else ".csv")))
                    .read_text() for name in ["summary", "outcomes", *run.keep]}
            self.assert_same_outputs(run, kept, where)
            self.assertGreater(float(row["cpu_s"]), 0)
        stats = json.loads((out / "run_stats.json").read_text())
        self.assertGreaterEqual(stats["processes"], 1)
        self.assertGreater(stats["process_cpu_s"], 0)
        return table

    def test_sweep_locally(self):
        out = self.out / "local"
        proc = subprocess.run([sys.executable, str(ROOT / "scripts/sweep"), "run",
                               str(self.sweep_file), "--simulate", self.simulate, "--out",
                               str(out), "--workers", "2", "--batch", "5"], capture_output=True,
                              text=True, timeout=300)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        table = self.check_sweep_output(out, "local sweep")
        self.assertEqual(len({r["worker"] for r in table}), 2)
        stats = json.loads((out / "run_stats.json").read_text())
        self.assertEqual(stats["batches"], 6)  # 30 distinct runs in batches of 5
        # One simulate --batch process per thread takes its batches one after the other.
        self.assertEqual(stats["processes"], 2)

    def test_sweep_locally_validation_first(self):
        """Without --batch: one share per worker, validated in the process that runs it."""
        out = self.out / "local_held"
        proc = subprocess.run([sys.executable, str(ROOT / "scripts/sweep"), "run",
                               str(self.sweep_file), "--simulate", self.simulate, "--out",
                               str(out), "--workers", "2"], capture_output=True, text=True,
                              timeout=300)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        table = self.check_sweep_output(out, "local sweep, validation first")
        self.assertEqual(len({r["worker"] for r in table}), 2)
        stats = json.loads((out / "run_stats.json").read_text())
        self.assertEqual(stats["batches"], 2)  # two shares
        self.assertEqual(stats["processes"], 2)

    def test_sweep_on_dask_scheduler(self):
        out = self.out / "cluster"
        with LoopbackCluster(self.out / "cluster_processes", workers=2) as cluster:
            proc = subprocess.run([sys.executable, str(ROOT / "scripts/sweep"), "run",
                                   str(self.sweep_file), "--simulate", self.simulate, "--out",
                                   str(out), "--scheduler", cluster.address],
                                  capture_output=True, text=True, timeout=300)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        table = self.check_sweep_output(out, "sweep on the scheduler")
        self.assertEqual(len({r["worker"].rsplit(":", 1)[-1] for r in table}), 2)


def main():
    global ARGS
    ARGS = parser(__doc__, out="batch_test").parse_args()
    os.environ.pop("THRESHING_SIM_SIMULATE", None)
    return run_suite(load(BatchTest), ARGS.xml, "test_batch")[0]


if __name__ == "__main__":
    sys.exit(main())
