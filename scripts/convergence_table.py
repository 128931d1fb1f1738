#!/usr/bin/python3
"""Mode convergence of the tooth forces: every scene of config/bench/ and every threshing case x
tooth variant of config/scenes/ (combined as scripts/compare_teeth.py does), run by the built
`simulate` at the automatically chosen mode count (teeth.*.modes: auto) and at two finer levels
(ceil(1.5 n) and 2 n, at most 64 modes).

For each: peak normal and tangential tooth force on a kernel, the exit velocity of the kernel
the tooth struck hardest (its speed at the end of the run), the impact count, their relative
changes from each level to the next finer one, and the largest tip deflection over L.

Writes docs/convergence.md (full table, with the knead force before and after the static
correction) and the README's short table between `<!-- convergence -->` and
`<!-- convergence-end -->`. --quick runs two bench scenes only and writes to --out (for the CI
test). Exits non-zero if a run fails; the 1 % target is reported, not enforced.
"""
import sys

from tslib.convergence.cli import main  # the study and its pages: scripts/tslib/convergence/

if __name__ == "__main__":
    sys.exit(main(__doc__))
