#!/usr/bin/python3
"""Work-precision benchmark: references, error against cost, scaling, the node's budget.

One command regenerates every benchmark figure and table (docs/benchmarks.md, docs/bench.md):

    /usr/bin/python3 scripts/bench.py            # full run (after scripts/setup.sh)

Stages (each run point is cached under .build/bench/cache, keyed by the binary, the scene files
and the arguments, so an interrupted run resumes and a rebuilt binary is measured afresh):

1. References, per benchmark scene of config/bench/: the event-driven integrator at a tight
   tolerance and time stepping at a very small step. Their agreement is printed and tabled. On
   a flexible tooth the reference is also run with more tooth modes, and the change is tabled.
2. Work-precision sweeps: event-driven over tolerances, time stepping over steps. Each point is
   one process of bench/bench_work_precision (pinned to one CPU) that times R repetitions and
   keeps the median wall time per simulated second. Errors against the event-driven reference:
   kernel exit velocity, final pose, peak normal and tangential force, total normal impulse,
   impact count, tip deflection history (RMS); the headline error is the largest of the first
   four. Writes docs/bench/work_precision.csv and docs/bench/wp_<scene>.png.
3. Scaling: cost per simulated second against the kernel count of the stream scene and against
   the tooth's mode count on the single strike, with fitted log-log exponents
   (docs/bench/scaling.csv, docs/bench/scaling.png).
4. The node's budget: threshing_sim_node on the stream scene at real time and its default step
   with growing kernel counts; the largest count whose measured real-time factor stays >= 0.99.
5. docs/bench.md (all tables) and the sections of docs/benchmarks.md between the bench markers.

--quick runs a tiny version into a temporary folder (CI): two knob values per integrator on the
single strike, and asserts that the pipeline works and that the errors fall with the knob.
--stream-kernels N prints the stream scene's kernel override file for N kernels and exits.
"""
import sys

from tslib.bench.cli import main  # the stages and their modules: scripts/tslib/bench/

if __name__ == "__main__":
    sys.exit(main(__doc__))
