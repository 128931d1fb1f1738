"""What the sweep tests share: the repository paths, the command line, scripts/sweep as a
process, and the JUnit XML file scripts/test.sh counts (one testcase per test, with its time)."""
import argparse
import pathlib
import shutil
import signal
import subprocess
import sys
import time
import unittest
import xml.etree.ElementTree as ET

ROOT = pathlib.Path(__file__).resolve().parents[2]
SWEEP = ROOT / "scripts/sweep"
SIMULATE = ROOT / ".build/ws/devel/lib/threshing_sim/simulate"  # scripts/setup.sh's build


def sweep(*args, timeout=120):
    """Runs scripts/sweep; returns the completed process (output captured)."""
    return subprocess.run([sys.executable, str(SWEEP), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def fresh_folder(path):
    """path emptied (or made): a test class's output folder at its set-up."""
    folder = pathlib.Path(path)
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    return folder


def parser(description, out=None):
    """The options every sweep test takes: --simulate, --xml and, given a default, --out."""
    p = argparse.ArgumentParser(description=description,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--simulate", default=str(SIMULATE), help="the simulate binary to test")
    if out is not None:
        p.add_argument("--out", default=str(ROOT / ".build" / out),
                       help="folder for the runs' files")
    p.add_argument("--xml", help="JUnit XML result file")
    return p


class TimedResult(unittest.TextTestResult):
    """Records each test's id and wall time when it stops (passed, failed, errored or skipped)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.cases, self.started = [], {}

    def startTest(self, test):
        self.started[test.id()] = time.monotonic()
        super().startTest(test)

    def stopTest(self, test):
        elapsed = time.monotonic() - self.started.get(test.id(), time.monotonic())
        self.cases.append((test.id(), elapsed))
        super().stopTest(test)


def write_junit(path, result, name):
    """Writes result (a TimedResult) as a JUnit testsuite named name; a failed setUpClass, which
    runs no test, becomes one failing case."""
    suite = ET.Element("testsuite", name=name, tests=str(len(result.cases)),
                       failures=str(len(result.failures)), errors=str(len(result.errors)))
    bad = {t.id(): (kind, text) for kind, items in (("failure", result.failures),
                                                    ("error", result.errors))
           for t, text in items}
    for test_id, elapsed in result.cases:
        classname, _, method = test_id.rpartition(".")
        case = ET.SubElement(suite, "testcase", classname=classname, name=method,
                             time=f"{elapsed:.3f}")
        if test_id in bad:
            kind, text = bad[test_id]
            ET.SubElement(case, kind, message=text.splitlines()[-1] if text else "").text = text
    ran = {test_id for test_id, _ in result.cases}
    for test_id, (kind, text) in bad.items():
        if test_id not in ran:  # a class or module fixture failed: no test of it ran
            case = ET.SubElement(suite, "testcase", classname=test_id, name="setUpClass")
            ET.SubElement(case, kind, message="set-up failed").text = text
            suite.set("tests", str(int(suite.get("tests")) + 1))
    pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(suite).write(path, encoding="utf-8", xml_declaration=True)


def run_suite(suite, xml, name):
    """Runs suite verbosely, writes the JUnit file if asked; returns the exit status. SIGTERM ends
    like Ctrl-C, so that the clusters and processes the tests started are stopped."""
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    result = unittest.TextTestRunner(resultclass=TimedResult, verbosity=2).run(suite)
    if xml:
        write_junit(xml, result, name)
    return (0 if result.wasSuccessful() else 1), result


def load(*cases):
    """A suite of every test of the given TestCase classes."""
    suite = unittest.TestSuite()
    for case in cases:
        suite.addTests(unittest.defaultTestLoader.loadTestsFromTestCase(case))
    return suite
