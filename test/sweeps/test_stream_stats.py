#!/usr/bin/python3
"""Stream statistics and the stop rule of sweeps (scripts/tslib/sweep/stats.py, docs/sweeps.md).

The estimators against closed forms on synthetic data: the cluster (batch-means) standard error
of a kernel mean over the runs, the naive one, and the paired relative difference between two
levels with its standard error. Then the stop rule on a tiny sweep
(test/sweeps/stream_stats_tiny.yaml: two streams of four kernels over 4 ms, two levels, seeds
in rounds) on a local cluster of one worker: it stops on the standard error (a loose target),
on the budget (a budget of a few core-seconds) and on max_rounds, and `scripts/sweep run
--report` writes the report's stream statistics section. Writes a JUnit XML file (--xml).
"""
import copy
import json
import math
import pathlib
import statistics
import sys
import unittest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from sweep_test_util import ROOT, fresh_folder, load, parser, run_suite, sweep  # noqa: E402

sys.path.insert(0, str(ROOT / "scripts"))
from tslib.sweep import runner, spec, stats  # noqa: E402

TINY = ROOT / "test/sweeps/stream_stats_tiny.yaml"
ARGS = None  # command line (simulate, out)


class EstimatorTest(unittest.TestCase):
    def test_equal_runs_is_batch_means(self):
        """Equal run sizes: the cluster SE is the standard deviation of the run means over
        sqrt(S), the naive SE that of all kernels over sqrt(N)."""
        runs = [[1.0, 4.0, 2.5], [0.5, 7.0, 3.0], [2.0, 2.0, 9.0], [1.5, 0.0, 4.0]]
        m = stats.cluster_mean(runs)
        means = [sum(r) / len(r) for r in runs]
        flat = [x for r in runs for x in r]
        self.assertAlmostEqual(m["mean"], statistics.fmean(flat), places=14)
        self.assertAlmostEqual(m["se"], statistics.stdev(means) / math.sqrt(4), places=14)
        self.assertAlmostEqual(m["se_naive"], statistics.stdev(flat) / math.sqrt(12), places=14)
        self.assertEqual((m["kernels"], m["runs"]), (12, 4))

    def test_constant_runs_closed_form(self):
        """Run s (1..S) of n kernels all equal to s: mean (S + 1) / 2, cluster SE
        sqrt((S + 1) / 12) (the SE of the mean of 1..S), naive SE
        sqrt(n S (S^2 - 1) / 12 / (N - 1) / N) with N = n S: smaller by about sqrt(n)."""
        for s_count, n in ((5, 10), (12, 4), (2, 3)):
            m = stats.cluster_mean([[float(s)] * n for s in range(1, s_count + 1)])
            N = n * s_count
            self.assertAlmostEqual(m["mean"], (s_count + 1) / 2, places=12)
            self.assertAlmostEqual(m["se"], math.sqrt((s_count + 1) / 12), places=12)
            self.assertAlmostEqual(m["se_naive"], math.sqrt(
                n * s_count * (s_count ** 2 - 1) / 12 / (N - 1) / N), places=12)

    def test_unequal_runs_ratio_estimator(self):
        """Unequal run sizes: SE^2 = S / (S - 1) sum_s (T_s - m n_s)^2 / N^2, by hand."""
        runs = [[1.0, 2.0], [3.0, 5.0, 4.0, 0.0], [6.0]]
        m = stats.cluster_mean(runs)
        self.assertAlmostEqual(m["mean"], 21.0 / 7.0, places=14)
        residuals = [3.0 - 3.0 * 2, 12.0 - 3.0 * 4, 6.0 - 3.0 * 1]
        self.assertAlmostEqual(m["se"], math.sqrt(3 / 2 * sum(r * r for r in residuals)) / 7,
                               places=14)
        self.assertTrue(math.isnan(stats.cluster_mean([[1.0, 2.0]])["se"]))

    def test_difference_of_scaled_level_has_no_error(self):
        """The finer level = (1 + c) x the chosen one, kernel by kernel, seed by seed: the
        paired difference is c with standard error 0 (the per-seed spread cancels)."""
        chosen = {1: [1.0, 3.0], 2: [5.0, 2.0], 3: [0.5, 9.0], 4: [4.0, 4.0]}
        finer = {s: [1.03 * x for x in v] for s, v in chosen.items()}
        d, se = stats.relative_difference(chosen, finer)
        self.assertAlmostEqual(d, 0.03, places=12)
        self.assertLess(se, 1e-12)

    def test_difference_of_uncorrelated_levels(self):
        """Per-seed deviations of the two levels orthogonal (sum_s a_s c_s = 0): the paired SE
        equals the unpaired (m_f / m_c) sqrt((SE_f / m_f)^2 + (SE_c / m_c)^2)."""
        a = [1.0, -1.0, 1.0, -1.0]   # finer level's run means - its mean (x alpha)
        c = [1.0, 1.0, -1.0, -1.0]   # chosen level's (x beta)
        chosen = {s + 1: [10.0 + 2.0 * c[s]] * 3 for s in range(4)}
        finer = {s + 1: [12.0 + 0.5 * a[s]] * 3 for s in range(4)}
        d, se = stats.relative_difference(chosen, finer)
        mc, mf = stats.cluster_mean(chosen.values()), stats.cluster_mean(finer.values())
        self.assertAlmostEqual(d, 12.0 / 10.0 - 1, places=12)
        expected = (mf["mean"] / mc["mean"]) * math.hypot(mf["se"] / mf["mean"],
                                                          mc["se"] / mc["mean"])
        self.assertAlmostEqual(se, expected, places=12)

    def test_relative(self):
        self.assertEqual(stats.relative(0.0, 0.0), 0.0)
        self.assertEqual(stats.relative(1.0, 0.0), math.inf)
        self.assertAlmostEqual(stats.relative(0.5, -10.0), 0.05)


class StopRuleTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.out = fresh_folder(ARGS.out)
        cls.simulate = ARGS.simulate

    def test_stops_on_standard_error(self):
        """A loose target (50 %): met within the rounds, by adding seeds where needed."""
        tiny = spec.Sweep(TINY)
        tiny.stop = dict(tiny.stop, relative_se=0.5, max_rounds=6)
        simulate = runner.resolve_simulate(self.simulate)
        sha = runner.binary_sha(simulate)
        out = self.out / "se"
        _, result = stats.run_rounds(tiny, simulate, sha, out, workers=1, log=lambda *_: None)
        record = json.loads((out / "stop.json").read_text())
        self.assertEqual(record["reason"], "relative_se", record)
        self.assertEqual(result["stop"]["reason"], "relative_se")
        last = record["rounds"][-1]
        self.assertTrue(all(w <= 0.5 for w in last["worst_relative_se"].values()), last)
        # The verdict recomputed from the table agrees.
        data = stats.Data(out, stats.Settings(tiny))
        for stream in ("spring_steel", "nylon"):
            self.assertLessEqual(data.worst_relative_se(stream), 0.5)

    def test_stops_on_budget_and_reports(self):
        """A budget of about 1.4 core-seconds and a tight target: the budget ends the sweep; no
        round starts once the budget is spent; the report's section says so."""
        out = self.out / "budget"
        budget = 0.0004
        proc = sweep("run", TINY, "--simulate", self.simulate, "--out", out, "--workers", 1,
                     "--budget-core-hours", budget, "--max-rounds", 20, "--report")
        self.assertEqual(proc.returncode, 0, proc.stderr)
        record = json.loads((out / "stop.json").read_text())
        self.assertEqual(record["reason"], "budget", record)
        self.assertGreaterEqual(len(record["rounds"]), 2, record)
        for r in record["rounds"][:-1]:
            self.assertLess(r["core_hours"], budget, record)
        report = (out / "report.md").read_text()
        self.assertIn("## Stream statistics", report)
        self.assertIn("stopped because the budget ended first", report)
        self.assertIn("**Verdict.** 0 of 2 streams meet both targets", report)
        self.assertIn("- spring_steel misses:", report)
        self.assertIn("**Cost model.**", report)
        for stream in ("spring_steel", "nylon"):
            for level in ("2", "3"):
                self.assertIn(f"| {stream} | {level} | ", report)
            self.assertIn(f"| {stream} | 2 -> 3 | ", report)

    def test_stops_on_rounds(self):
        """max_rounds ends a sweep whose budget would go on; seeds grow at most x growth."""
        out = self.out / "rounds"
        proc = sweep("run", TINY, "--simulate", self.simulate, "--out", out, "--workers", 1,
                     "--max-rounds", 2)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        record = json.loads((out / "stop.json").read_text())
        self.assertEqual(record["reason"], "max_rounds", record)
        self.assertEqual([r["seeds"]["nylon"] for r in record["rounds"]], [2, 4])
        # A second invocation takes the first round's runs from the cache.
        proc = sweep("run", TINY, "--simulate", self.simulate, "--out", out, "--workers", 1,
                     "--max-rounds", 1)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        self.assertIn("8 runs, 8 from the cache, 0 to run", proc.stdout + proc.stderr)

    def test_bad_stop_refused(self):
        tiny = spec.Sweep(TINY)
        for bad in ({"relative_se": -1}, {"max_rounds": 0}, {"growth": 1},
                    {"budget": 1}):
            broken = copy.copy(tiny)
            broken.stop = bad
            with self.assertRaises(spec.SweepError):
                stats.Settings(broken)


def main():
    global ARGS
    p = parser(__doc__, out="stream_stats_test")
    p.add_argument("--only-estimators", action="store_true",
                   help="only the estimator tests (no simulate)")
    ARGS = p.parse_args()
    cases = (EstimatorTest,) if ARGS.only_estimators else (EstimatorTest, StopRuleTest)
    return run_suite(load(*cases), ARGS.xml, "test_stream_stats")[0]


if __name__ == "__main__":
    sys.exit(main())
