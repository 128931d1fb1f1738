#!/usr/bin/python3
"""The contact phase's work-precision and cost tables (issue 33; docs/contact_phase.md).

Runs `simulate` on the bench scenes adaptive and under the contact phase at 10, 20, 40 and 80
steps per contact against the adaptive reference at tolerance 1e-10 (the accuracy table), and
under callgrind, adaptive and at 40 steps, on the default strike and the bench streams (the
cost table). scripts/tslib/contact_phase.py says what each column is.

Usage: scripts/contact_phase_table.py [--docs] [--quick] [--part accuracy|cost|all]
       [--simulate PATH]
  --docs   splice the tables into docs/contact_phase.md (sections contact-phase-accuracy,
           contact-phase-cost)
  --quick  the cost table's 100-kernel stream only (the 1000-kernel ones take minutes under
           callgrind)
"""
import argparse
import shutil
import sys

from tslib import contact_phase, markdown
from tslib.binaries import find_binary


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--docs", action="store_true")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--part", choices=("accuracy", "cost", "all"), default="all")
    ap.add_argument("--simulate")
    args = ap.parse_args()
    simulate = find_binary("simulate", args.simulate)

    def say(text):
        print(text, file=sys.stderr, flush=True)

    if args.part in ("accuracy", "all"):
        table = contact_phase.accuracy_table(contact_phase.accuracy(simulate, say))
        print(table)
        if args.docs:
            print("wrote", markdown.splice("contact-phase-accuracy", table))
    if args.part in ("cost", "all"):
        if shutil.which("valgrind") is None:
            raise SystemExit("valgrind is needed for the cost table (apt-get install valgrind)")
        table = contact_phase.cost_table(contact_phase.cost(simulate, say, args.quick))
        print(table)
        if args.docs:
            print("wrote", markdown.splice("contact-phase-cost", table))


if __name__ == "__main__":
    main()
