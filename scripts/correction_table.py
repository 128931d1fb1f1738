#!/usr/bin/python3
"""Does the static correction make few modes enough, and is it never worse than without it?

For the default strike (config/bench/single_strike.yaml), the polyurethane knead
(config/bench/knead_polyurethane.yaml) and a soft knead not in the tests (the same scene with an
8 MPa tooth at 900 rpm; and, to separate the friction path, the polyurethane knead without
tooth-kernel friction), runs the built `simulate` at 1, 2, 3, 4, 6, 8, 12, 16 and 24 modes with
teeth.*.static_correction on and off (event-driven, tolerance 1e-9), and a converged reference
(64 modes, correction on, tolerance 1e-10). For each run: the peak normal and tangential tooth
force on the kernel (the core's located peaks) and the tooth-kernel normal and tangential impulse
(the --forces history every 0.1 us near contacts, trapezoidal), and their relative errors against
the reference. A cell is marked `*` where the correction is worse than without it (by more than
0.1 % of the reference).

Writes the table between `<!-- correction-table -->` markers of docs/convergence.md (--docs),
or prints it. Exits non-zero if a run fails.
"""
import sys

from tslib.correction import main  # the study: scripts/tslib/correction.py

if __name__ == "__main__":
    sys.exit(main(__doc__))
