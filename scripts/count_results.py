#!/usr/bin/env python3
"""Counts test cases in the JUnit XML files catkin writes and prints 'N passed, N failed'.

A result file that is missing or unreadable (a test binary that crashed) counts as a failure.
Exit code 1 if anything failed or no test ran.
"""
import pathlib
import sys
import xml.etree.ElementTree as ET


def main(results_dir):
    passed = failed = skipped = 0
    failures = []
    for path in sorted(pathlib.Path(results_dir).rglob("*.xml")):
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError:
            failed += 1
            failures.append(f"{path.name}: unreadable result file")
            continue
        for case in root.iter("testcase"):
            name = f"{case.get('classname', '')}.{case.get('name', '')}"
            if case.find("failure") is not None or case.find("error") is not None:
                failed += 1
                failures.append(f"{path.name}: {name}")
            elif case.find("skipped") is not None or case.get("status") == "notrun":
                skipped += 1
            else:
                passed += 1
    for f in failures:
        print(f"FAILED: {f}")
    line = f"{passed} passed, {failed} failed"
    if skipped:
        line += f", {skipped} skipped"
    print(line)
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
