#!/usr/bin/python3
"""Long versions of the hard cases: the stability table (docs/stability.md).

Runs `simulate` on each scene of config/hard/ for both integrators with the scene's long
duration, checks the properties every hard case must keep (issue 5), and writes the stability
table as markdown: scene, integrator, passed properties, worst energy error, worst
penetration, steps per simulated second, wall time.

The short versions of the same scenes run in CI (test/core/hard_cases/), with the
closed forms, the convergence and agreement checks that need several runs. This script adds
what only a long run shows: progress over a long simulated time, energy that drifts up
slowly, contacts that creep or sink, memory that grows with the run.

Usage:
  scripts/stability_table.py --simulate .build/ws/devel/lib/threshing_sim/simulate \\
      --output docs/stability.md --summary docs/numerical_stability.md   # both pages
  scripts/stability_table.py --scenes 01 03 --integrators time_stepping   # a subset, to stdout
  scripts/stability_table.py --scale 0.01                                 # 1 % of each run
  scripts/stability_table.py --full ...     # scene 10 over 10 000 revolutions (hours)
  scripts/stability_table.py ... --save results.json    # also keep the results
  scripts/stability_table.py --render results.json --output docs/stability.md  # re-render only

Exit status: 0 when every property of every run held, 1 when one failed, 2 on a usage error.
"""
import sys

from tslib.stability.cli import main  # scenes, runs and pages: scripts/tslib/stability/

if __name__ == "__main__":
    sys.exit(main())
