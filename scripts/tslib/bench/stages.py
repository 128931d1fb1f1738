"""Instructions per stage of the stepping loop, by callgrind (issue 22, item 1): the cases,
the callgrind runs, the stage counts read from the raw call graph and the table
(scripts/stage_profile.py, which describes the method; scripts/bench.py --part islands runs
it with its own kernel files)."""
import json
import pathlib
import re
import subprocess
import sys
import tempfile

from tslib import BENCH_DIR, ROOT, markdown
STREAM = BENCH_DIR / "stream.yaml"
DEFAULT_SCENE = ROOT / "config/default_scene.yaml"
EVENT_DRIVEN = ["--set", "integrator.type=event_driven", "--set", "integrator.tolerance=1e-6"]
ISLANDS = ["--set", "integrator.islands=true"] + EVENT_DRIVEN

# Stage -> regular expression searched in the demangled function name (callgrind's "fn="); a
# function belongs to the first stage that matches. Every libm function but NOT_TRANSCENDENTAL is
# "transcendental".
STAGES = [
    ("wake", r"^threshing_sim::internal::(wakeDueKernels|tryShrink|predictKernel|"
             r"advanceFreeTeeth|advanceFreeTooth)\("),
    ("sweep", r"^threshing_sim::internal::sweepTeeth\("),
    ("island neighbours and proximity",
     r"^threshing_sim::internal::(islandNeighbours|islandProximity)\("),
    ("island formation", r"^threshing_sim::internal::(formIslands|splitIslands|buildIsland|"
                         r"dissolveIsland|mergeIslandResults|storeIslandState)\("),
    ("broad phase", r"^threshing_sim::internal::(broadPhase|prepareBroadPhase|"
                    r"broadPhaseBruteForce)\("),
    ("narrow phase", r"^threshing_sim::internal::(evaluateContact|(\(anonymous namespace\)::)?"
                     r"(toothKernel|kernelKernel|kernelPlane|kernelPlate|kernelBar))\("),
    ("  tooth-kernel", r"^threshing_sim::internal::(\(anonymous namespace\)::)?toothKernel\("),
    ("  kernel-kernel", r"^threshing_sim::internal::(\(anonymous namespace\)::)?kernelKernel\("),
    ("  centreline (centrelinePoint, centrelineMotion)",
     r"^threshing_sim::internal::(centrelinePoint|centrelineMotion)\("),
    ("  mode shapes (evaluateModes, interpolateModes: phi, phi', phi'')",
     r"^threshing_sim::(evaluateModes|evaluateModeCurvatures|interpolateModes|"
     r"interpolateModeCurvatures)\("),
    ("contact forces", r"^threshing_sim::internal::(compliantNormalForce\w*|smoothForces|"
                       r"recordForce|contactVelocityDrift|(\(anonymous namespace\)::)?"
                       r"addGeneralised)\("),
    ("right-hand side", r"^threshing_sim::internal::(event_driven::rhs|freeAcceleration)\("),
    ("Dormand-Prince step", r"^threshing_sim::internal::event_driven::dopriStep\("),
    ("event location", r"^threshing_sim::internal::event_driven::(locateFirstEvent|eventValues|"
                       r"detectEvents|detectGrazes|hermiteMinimum|locateForcePeaks)\("),
    ("LCP", r"^threshing_sim::(solveContactProblem|internal::solveContactIslands)\("),
    ("pedicel clocks", r"^threshing_sim::internal::(\(anonymous namespace\)::)?(pedicelClock|"
                       r"advanceLazyKernel|syncLazyKernels|updatePedicels)\("),
    ("bookkeeping", r"^threshing_sim::(internal::(publishContacts|beginEpisode|endEpisode|"
                    r"emitTransition|energyOf|checkToothDeflection|flushWindowEvents|"
                    r"event_driven::(recordStepForces|acceptStep|finishStep|switchModes|"
                    r"updateModes|compliantForceSnapshot))|mechanicalEnergy)\("),
]
SETUP = r"^threshing_sim::loadScene\("  # model set-up: the scene's parsing and compile
TRANSCENDENTAL = "transcendental (libm: sin, cos, exp, ...)"
STEPPING = r"^threshing_sim::advance(To|Past)\("  # the stepping loop (simulate: advancePast)
CORE = r"^threshing_sim::(?!app::)"  # the core library's functions (the app's are outside)
NOT_TRANSCENDENTAL = r"^(fmax|fmin|fabs|floor|ceil|trunc|round|lround|copysign)"  # libm, cheap


def stream_kernel_file(folder, count, sparse=None):
    """The stream's kernel file for count kernels (sparse: that many in reach), written by
    scripts/bench.py --stream-kernels into folder."""
    path = pathlib.Path(folder) / (f"stream_kernels_{count}"
                                   f"{'' if sparse is None else '_sparse%d' % sparse}.yaml")
    cmd = [sys.executable, str(ROOT / "scripts/bench.py"), "--stream-kernels", str(count)]
    if sparse is not None:
        cmd += ["--sparse", str(sparse)]
    path.write_text(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)
    return path


def cases(kernel_file):
    """(name, label, scene, arguments) of the profiled runs; kernel_file(count, sparse) gives
    the stream's kernel files."""
    return [
        ("strike", "default single strike (10 ms, global scheme)", DEFAULT_SCENE,
         ["--set", "integrator.islands=false"] + EVENT_DRIVEN),
        ("strike_islands", "default single strike (10 ms, islands)", DEFAULT_SCENE,
         ISLANDS),
        ("stream100", "stream, 100 kernels (2 ms, islands)", STREAM,
         ["--set-file", str(kernel_file(100, None))] + ISLANDS),
        ("stream1000", "stream, 1000 kernels, 10 in reach (2 ms, islands)", STREAM,
         ["--set-file", str(kernel_file(1000, 10))] + ISLANDS),
    ]


def run_callgrind(simulate, scene, args, out_prefix, stepping_only):
    """Runs simulate under callgrind; returns (callgrind file, summary dict). stepping_only:
    collect inside advanceTo only (the stepping loop)."""
    out = pathlib.Path(f"{out_prefix}{'.step' if stepping_only else ''}.cg")
    summary = pathlib.Path(f"{out_prefix}.json")
    # simulate's loop calls advancePast only; the island scheme calls advanceTo inside it, so
    # toggling both would switch collection off there.
    toggle = ["--toggle-collect=threshing_sim::advancePast*"] if stepping_only else []
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"] + toggle + [
        str(simulate), str(scene)] + args + ["--quiet", "--summary", str(summary)]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True,
                   timeout=3600)
    return out, json.loads(summary.read_text())


class CallGraph:
    """The functions of a raw callgrind file (one event, Ir): self cost, object, and the
    inclusive cost of every caller -> callee edge."""

    def __init__(self, path):
        self.names, self.objects = {}, {}
        self.self_cost, self.edges = {}, {}  # fn -> Ir; (caller, callee) -> inclusive Ir
        self.total = 0
        self._parse(pathlib.Path(path).read_text(errors="replace").splitlines())

    @staticmethod
    def _define(table, value):
        """Name compression: "(id) name" defines id, "(id)" refers to it."""
        m = re.match(r"\((\d+)\)(?: (.*))?$", value)
        if not m:
            return value
        if m.group(2) is not None:
            table[m.group(1)] = m.group(2)
        return table[m.group(1)]

    def _parse(self, lines):
        objects, files_unused, obj, fn, cob, cfn, pending_call = {}, {}, None, None, None, None, False
        for line in lines:
            if not line or line[0] == "#":
                continue
            if line[0].isdigit() or line[0] in "+-*":
                cost = int(line.split()[1]) if len(line.split()) > 1 else 0
                if pending_call:
                    key = (fn, cfn)
                    self.edges[key] = self.edges.get(key, 0) + cost
                    self.objects.setdefault(cfn, cob or obj)
                    pending_call, cob = False, None  # cob names one call's callee only
                else:
                    self.self_cost[fn] = self.self_cost.get(fn, 0) + cost
                continue
            key, _, value = line.partition("=")
            if key == "ob":
                obj = self._define(objects, value)
            elif key == "fn":
                fn = self._define(self.names, value)
                self.objects.setdefault(fn, obj)
            elif key == "cob":
                cob = self._define(objects, value)
            elif key == "cfn":
                cfn = self._define(self.names, value)
            elif key == "calls":
                pending_call = True
            elif key in ("fl", "fi", "fe", "cfi", "cfl"):
                self._define(files_unused, value)
            elif line.startswith("totals:") or line.startswith("summary:"):
                self.total = int(line.split()[1])

    def inclusive(self, in_stage):
        """Instructions inside the functions for which in_stage(name) holds, counted once:
        the inclusive costs of the calls that enter them from outside."""
        return sum(cost for (caller, callee), cost in self.edges.items()
                   if in_stage(callee) and not in_stage(caller) and not self._recursion(callee))

    def entries(self, pattern, outside):
        """Instructions of the calls into functions matching pattern from functions that do not
        match outside (the stepping loop entered from the program, not the island scheme's own
        advanceTo calls inside it)."""
        return sum(cost for (caller, callee), cost in self.edges.items()
                   if re.search(pattern, callee) and not re.search(outside, caller))

    @staticmethod
    def _recursion(name):
        """A recursive activation (callgrind's name'2, '3, ...) of a function already on the
        stack, so inside its stage (advanceTo -> asyncWindow -> advanceTo'2)."""
        return re.search(r"'\d+$", name) is not None


def stage_counts(whole, stepping):
    """{stage: inclusive instructions}: the whole run and the model set-up from the profile of
    the whole run, the rest from the profile of the stepping loop alone."""
    counts = {"whole run": whole.total, "model set-up": whole.inclusive(
        lambda f: bool(re.search(SETUP, f)))}
    counts["advanceTo (stepping loop)"] = stepping.total
    for name, pattern in STAGES:
        rx = re.compile(pattern)
        counts[name] = stepping.inclusive(lambda f, rx=rx: bool(rx.search(f)))
    counts[TRANSCENDENTAL] = stepping.inclusive(
        lambda f: "libm.so" in (stepping.objects.get(f) or "") and not re.match(NOT_TRANSCENDENTAL, f))
    return counts


def annotate_total(cg_path):
    """PROGRAM TOTALS of callgrind_annotate --inclusive=yes, and the inclusive count of
    advanceTo there (0 when absent)."""
    text = subprocess.run(["callgrind_annotate", "--inclusive=yes", str(cg_path)],
                          capture_output=True, text=True, check=True).stdout
    total = int(re.search(r"([\d,]+) \(100\.0%\)\s+PROGRAM TOTALS", text).group(1)
                .replace(",", ""))
    # simulate's loop calls advancePast only (the island scheme's advanceTo calls are inside it).
    m = re.search(r"^\s*([\d,]+) \([\d. ]+%\)\s+\S*threshing_sim::advancePast\(", text, re.M)
    return total, int(m.group(1).replace(",", "")) if m else 0


def check(whole_cg, step_cg, whole, stepping):
    """The call graphs' totals against callgrind_annotate's, and the stepping loop of both
    profiles against each other (the same run: they must agree to a few instructions)."""
    a_whole, a_step_in_whole = annotate_total(whole_cg)
    a_step, _ = annotate_total(step_cg)
    step_in_whole = whole.entries(STEPPING, outside=CORE)
    problems = []
    if a_whole != whole.total or a_step != stepping.total:
        problems.append(f"totals ({whole.total}, {stepping.total}) differ from "
                        f"callgrind_annotate's ({a_whole}, {a_step})")
    if step_in_whole != a_step_in_whole:
        problems.append(f"advanceTo {step_in_whole} differs from callgrind_annotate's "
                        f"{a_step_in_whole}")
    if abs(step_in_whole - stepping.total) > 1e-3 * stepping.total:
        problems.append(f"advanceTo in the whole run {step_in_whole} differs from the stepping "
                        f"loop's profile {stepping.total}")
    if problems:
        raise SystemExit(f"stage_profile: {whole_cg}: " + "; ".join(problems))


def profile(simulate, case_list, keep=None, reuse=None, say=print):
    """{case name: (label, counts, summary)}; keep: folder to keep the callgrind files in;
    reuse: folder of an earlier run's files (no valgrind). Two runs per case: the whole run,
    and the stepping loop alone (whose call graph holds no set-up code)."""
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(reuse or keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for name, label, scene, args in case_list:
            prefix = folder / name
            if reuse:
                files = [pathlib.Path(f"{prefix}.cg"), pathlib.Path(f"{prefix}.step.cg")]
                summary = json.loads(pathlib.Path(f"{prefix}.json").read_text())
            else:
                say(f"stage_profile: callgrind on {label}")
                files = [run_callgrind(simulate, scene, args, prefix, s)[0] for s in (False, True)]
                summary = json.loads(pathlib.Path(f"{prefix}.json").read_text())
            whole, stepping = CallGraph(files[0]), CallGraph(files[1])
            check(files[0], files[1], whole, stepping)
            results[name] = (label, stage_counts(whole, stepping), summary)
    return results


def steps_of(summary):
    """Integrator steps: island steps on the island scheme, steps on the global one."""
    island = summary.get("scheduler", {}).get("island_steps", 0)
    return island if island > 0 else summary["steps"]


def table(results):
    """The markdown table: one row per stage, per case total / per event / per step."""
    names = list(results)
    head = ["stage"]
    for name in names:
        head += [f"{results[name][0]}: run", "per event", "per step"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    rows = ["whole run", "model set-up", "advanceTo (stepping loop)"] + [s for s, _ in STAGES] + [TRANSCENDENTAL]
    for row in rows:
        cells = [row.replace("  ", "&nbsp;&nbsp;") if row.startswith("  ") else row]
        for name in names:
            _, counts, summary = results[name]
            x = counts[row]
            cells += [f"{x:.3g}", f"{x / max(1, summary['impacts']):.3g}",
                      f"{x / max(1, steps_of(summary)):.3g}"]
        lines.append("| " + " | ".join(cells) + " |")
    foot = ["impacts (events) / steps"] + sum(
        ([f"{results[n][2]['impacts']} / {steps_of(results[n][2])}", "", ""] for n in names), [])
    lines.append("| " + " | ".join(foot) + " |")
    return "\n".join(lines)


BEFORE_PLACEHOLDER = "(not recorded)"
HEADING = "## Instructions per stage"


def section(current, before=None):
    """The "Instructions per stage" section of docs/bench_islands.md: the explanation, the
    table of the code before issue 22's step-cost work (kept as recorded) and the current one,
    each between its marker pair."""
    b0, b1 = markdown.markers("stage-profile-before")
    c0, c1 = markdown.markers("stage-profile")
    return f"""{HEADING}

Regenerated by `python3 scripts/stage_profile.py --docs` (also run by
`scripts/bench.py --part islands`): callgrind on `simulate` for the default single strike
(`config/default_scene.yaml`, event-driven, tolerance 1e-6, 10 ms, global scheme) and the bench
stream (`config/bench/stream.yaml`, island scheme, event-driven, tolerance 1e-6, its full 2 ms)
with 100 kernels and with 1000 kernels of which 10 are in reach. Each case runs twice: once
whole (the whole run and the model set-up, `loadScene`) and once collecting inside `advanceTo`
only (every other row). A stage's count is inclusive: the calls entering its functions
(the table STAGES of `scripts/stage_profile.py`) from outside it, so nested stages (the narrow
phase inside the right-hand side, inside the Dormand-Prince step) are counted in each; indented
rows are parts of the narrow phase (the centreline and mode-shape rows count their calls from
every stage). "per event" divides by the impacts of the simulate summary,
"per step" by the island integrator's steps (island scheme) or the integrator's steps (global
scheme). "transcendental" is every libm function called inside the stepping loop but
min/max/abs/rounding.

### Before (main at aa8e79d, issue 22 not started)

Recorded once by `python3 scripts/stage_profile.py --docs --section stage-profile-before
--simulate <simulate built from main>`; the regeneration keeps it.

{b0}
{(before or BEFORE_PLACEHOLDER).rstrip()}
{b1}

### Now

{c0}
{current.rstrip()}
{c1}
"""


def splice_docs(text, path):
    """Writes the section with the current table (text) into path: in place of its "Instructions
    per stage" section (from the heading to the current table's end marker, keeping the recorded
    "before" table), or appended when the page has none."""
    page = path.read_text()
    before = markdown.section_body(page, "stage-profile-before")
    start, end_marker = page.find(HEADING), markdown.markers("stage-profile")[1]
    end = page.find(end_marker)
    if start < 0 or end < start:
        page = page.rstrip() + "\n\n" + section(text, before)
    else:
        page = page[:start] + section(text, before) + page[end + len(end_marker) + 1:]
    path.write_text(page)
    return path
