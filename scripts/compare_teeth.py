#!/usr/bin/python3
"""Runs the threshing scenes across tooth variants and drum speeds and reports what they show.

Cases: the scenes config/scenes/{single_strike,knead,stream}.yaml, and the single strike with
the kernel at the tooth's tip (config/scenes/cases/tip_strike.yaml). Each case runs with every
tooth variant (config/scenes/teeth/*.yaml) at every drum speed, by invoking the built
`simulate` binary in parallel over the cores; summaries, per-kernel outcomes, events and (at
one speed) contact force samples land in OUT/runs/. Controls: every flexible tooth frozen (no
bending modes, same material and contact) on every case but the stream, which separates the
effect of bending from that of the contact material; a modal convergence check of the single
strike. Then OUT/report.md is written with plots (PNG): force histories, peak forces, knead
force, damage, detachment and sub-collisions against drum speed, and a Campbell diagram of the
teeth's frequencies (simulate --modes).

With --findings, docs/findings.md (the full report: the paper's three claims judged from these
numbers) and its plots in docs/findings/ are regenerated too, and so is the findings section of docs/threshing_findings.md
(between its findings markers): the three
verdicts with their key numbers, the key plots, and the agreement with the measured threshing
force and the Hertz contact time. --quick runs a tiny sweep (for the CI test).

Force peaks and their times come from the core (RunStats::kernel_tooth_peaks: every accepted
step, the located maxima of compliant normal forces, and both sides of every located event),
not from the force samples, which only feed the force history plots.
"""
import sys

# The modules of the comparison (scripts/tslib/teeth/); the names scripts/tslib/sweep/findings.py
# and test/sweeps/test_sweep.py use as compare_teeth.* are re-exported here.
from tslib.teeth.analysis import analyse
from tslib.teeth.cases import (CASES, CONVERGENCE_MODES, FLEXIBLE, FROZEN_CASES,
                               HISTORY_RPM, LARGE_DEFLECTION, RPM_FULL, VARIANTS, ToothRun,
                               tooth_frequencies)
from tslib.teeth.cli import main
from tslib.teeth.findings import write_findings
from tslib.teeth.plots import make_plots
from tslib.teeth.report import write_comparison
from tslib.teeth.summary import write_summary

__all__ = ["CASES", "CONVERGENCE_MODES", "FLEXIBLE", "FROZEN_CASES", "HISTORY_RPM",
           "LARGE_DEFLECTION", "RPM_FULL", "VARIANTS", "ToothRun", "analyse", "make_plots", "main",
           "tooth_frequencies", "write_findings", "write_comparison", "write_summary"]

if __name__ == "__main__":
    sys.exit(main(__doc__))
