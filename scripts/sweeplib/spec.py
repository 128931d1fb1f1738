"""Sweep files: parsing, expansion into runs, and validation of every run with the scene loader.

A sweep file (YAML) names a base scene, override files and fixed overrides, a list of axes, a
number of seeds, the outcomes to collect and optional derived columns (docs/sweeps.md has the
reference). Paths in it are relative to the sweep file. Every run is the cartesian product of
one value of each axis (and one seed); `simulate --check-batch` validates them all in one
process and returns each run's resolved scene, whose hash (with the binary's) is the run's key.
"""
import ast
import hashlib
import itertools
import math
import pathlib
import subprocess

import yaml

RADPS_PER_RPM = math.pi / 30.0
UNITS = {None: 1.0, "rad/s": 1.0, "rpm": RADPS_PER_RPM}
TOP_KEYS = {"name", "scene", "set_files", "set", "axes", "seeds", "outcomes", "derived",
            "timeout", "keep", "report", "groups"}
GROUP_KEYS = {"name", "axes", "set", "keep"}
AXIS_KEYS = {"name", "key", "unit", "values", "range", "files", "cases"}
CASE_KEYS = {"scene", "set_files", "set"}
DEFAULT_OUTCOMES = ["outcomes.peak_normal_force_N", "outcomes.peak_tangential_force_N",
                    "outcomes.detached", "outcomes.damaged", "outcomes.kernels"]
KEEP_FILES = {"events", "forces"}  # extra simulate outputs a sweep may keep per run


class SweepError(Exception):
    """A bad sweep file; the message names the key and the value."""


def _fail(where, what):
    raise SweepError(f"{where}: {what}")


def _number(where, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(where, f"expected a finite number (got {value!r})")
    return value


def _range_values(where, spec):
    """Values of a range axis: {from, to, step} (both ends included) or {from, to, count}."""
    if not isinstance(spec, dict) or set(spec) - {"from", "to", "step", "count"} or \
            not {"from", "to"} <= set(spec) or ("step" in spec) == ("count" in spec):
        _fail(where, f"expected {{from, to, step}} or {{from, to, count}} (got {spec!r})")
    lo, hi = _number(where + ".from", spec["from"]), _number(where + ".to", spec["to"])
    if "count" in spec:
        n = spec["count"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 1 or n > 100000:
            _fail(where + ".count", f"expected an integer in [1, 100000] (got {n!r})")
        if n == 1:
            return [lo]
        return [lo + (hi - lo) * i / (n - 1) for i in range(n)]
    step = _number(where + ".step", spec["step"])
    if step == 0 or (hi - lo) / step < 0 or (hi - lo) / step > 100000:
        _fail(where + ".step", f"does not lead from {lo!r} to {hi!r} in at most 100000 steps "
              f"(got {step!r})")
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    values = [lo + i * step for i in range(n)]
    # Whole numbers stay integers (600, 700, ... rpm), others are rounded to 12 digits so that
    # 0.1 + 2 * 0.1 reads 0.3 in the table and the scene.
    return [v if isinstance(v, int) else float(f"{v:.12g}") for v in values]


class Axis:
    """One swept dimension: a scene key over values, or a set of override files."""

    def __init__(self, where, spec, base_dir):
        if not isinstance(spec, dict) or set(spec) - AXIS_KEYS or "name" not in spec:
            _fail(where, f"expected a mapping with name and one of values, range, files and "
                  f"keys among {sorted(AXIS_KEYS)} (got {spec!r})")
        self.name = str(spec["name"])
        where = f"{where} ({self.name})"
        kinds = [k for k in ("values", "range", "files", "cases") if k in spec]
        if len(kinds) != 1:
            _fail(where, f"needs exactly one of values, range, files, cases (got "
                  f"{kinds or 'none'})")
        self.kind = kinds[0]
        self.unit = spec.get("unit")
        if self.unit not in UNITS:
            _fail(where + ".unit", f"expected one of {sorted(u for u in UNITS if u)} "
                  f"(got {self.unit!r})")
        self.key = spec.get("key")
        if self.kind in ("files", "cases"):
            if self.key is not None or self.unit is not None:
                _fail(where, f"a {self.kind} axis takes no key or unit (its entries hold the "
                      "keys)")
            if self.kind == "files":
                self.labels, self.files = self._files(where + ".files", spec["files"], base_dir)
            else:
                self.labels, self.cases = self._cases(where + ".cases", spec["cases"], base_dir)
            return
        if not isinstance(self.key, str) or not self.key:
            _fail(where + ".key", f"expected a scene key path such as drum.speed or "
                  f"teeth.*.length (got {self.key!r})")
        if self.kind == "values":
            values = spec["values"]
            if not isinstance(values, list) or not values:
                _fail(where + ".values", f"expected a non-empty list (got {values!r})")
            self.labels = values
        else:
            self.labels = _range_values(where + ".range", spec["range"])
        if self.unit is not None:
            for v in self.labels:
                _number(f"{where}.values", v)

    @staticmethod
    def _files(where, spec, base_dir):
        if isinstance(spec, list) and spec:
            items = [(pathlib.Path(str(p)).stem, p) for p in spec]
        elif isinstance(spec, dict) and spec:
            items = list(spec.items())
        else:
            _fail(where, f"expected a non-empty list of override files or a mapping of labels "
                  f"to files (got {spec!r})")
        files = []
        for label, path in items:
            full = (base_dir / str(path)).resolve()
            if not full.is_file():
                _fail(f"{where}.{label}", f"no such override file '{path}' (looked at {full})")
            files.append(full)
        return [str(label) for label, _ in items], files

    @staticmethod
    def _cases(where, spec, base_dir):
        """A case: a scene of its own, with override files and overrides."""
        if not isinstance(spec, dict) or not spec:
            _fail(where, f"expected a mapping of labels to {{scene, set_files, set}} "
                  f"(got {spec!r})")
        cases = []
        for label, case in spec.items():
            here = f"{where}.{label}"
            if not isinstance(case, dict) or set(case) - CASE_KEYS or "scene" not in case:
                _fail(here, f"expected {{scene, set_files, set}} (got {case!r})")
            arguments = [str(_existing(here + ".scene", base_dir, case["scene"]))]
            for path in case.get("set_files", []) or []:
                arguments += ["--set-file", str(_existing(here + ".set_files", base_dir, path))]
            fixed = case.get("set", {}) or {}
            if not isinstance(fixed, dict):
                _fail(here + ".set", f"expected a mapping of key paths to values (got {fixed!r})")
            for key, value in fixed.items():
                arguments += ["--set", f"{key}={_scene_text(value)}"]
            cases.append(arguments)
        return [str(label) for label in spec], cases

    def arguments(self, i):
        """simulate arguments of the axis' i-th value (a cases axis: scene first)."""
        if self.kind == "cases":
            return list(self.cases[i])
        if self.kind == "files":
            return ["--set-file", str(self.files[i])]
        value = self.labels[i]
        if self.unit is not None:
            value = value * UNITS[self.unit]
        return ["--set", f"{self.key}={_scene_text(value)}"]

    def column(self):
        """Table column of the axis: its name, with the unit when it has one."""
        return f"{self.name}_{self.unit.replace('/', 'p')}" if self.unit else self.name


def _existing(where, base_dir, path):
    full = (base_dir / str(path)).resolve()
    if not full.is_file():
        _fail(where, f"no such file '{path}' (looked at {full})")
    return full


def _scene_text(value):
    """A value as scene YAML text (flow style for lists; repr of floats round-trips)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, dict)):
        return yaml.safe_dump(value, default_flow_style=True, width=1 << 30).strip()
    return str(value)


# ------------------------------------------------------------------------------------------
# Derived columns: arithmetic over a row's columns, parsed once and checked against the names.

_BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
           ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b if b else math.nan,
           ast.Pow: lambda a, b: a ** b}
_COMPARE = {ast.Lt: lambda a, b: a < b, ast.LtE: lambda a, b: a <= b,
            ast.Gt: lambda a, b: a > b, ast.GtE: lambda a, b: a >= b,
            ast.Eq: lambda a, b: a == b, ast.NotEq: lambda a, b: a != b}
_FUNCTIONS = {"min": min, "max": max, "abs": abs, "sqrt": math.sqrt, "log10": math.log10}
_CONSTANTS = {"pi": math.pi}


class Expression:
    """A derived column, e.g. `damaged / kernels`: numbers, column names, + - * / **,
    comparisons, min, max, abs, sqrt, log10 and pi. A missing or empty value gives NaN."""

    def __init__(self, where, text, names):
        self.text = str(text)
        try:
            self.tree = ast.parse(self.text, mode="eval").body
        except SyntaxError as e:
            _fail(where, f"not an expression ({e.msg}) (got {self.text!r})")
        self._check(where, self.tree, set(names))

    def _check(self, where, node, names):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return
        if isinstance(node, ast.Name):
            if node.id not in names and node.id not in _CONSTANTS:
                _fail(where, f"unknown column '{node.id}' in {self.text!r} (columns: "
                      f"{', '.join(sorted(names))})")
            return
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return self._check(where, node.left, names) or self._check(where, node.right, names)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            return self._check(where, node.operand, names)
        if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
            return self._check(where, node.left, names) or \
                self._check(where, node.comparators[0], names)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                node.func.id in _FUNCTIONS and not node.keywords:
            for arg in node.args:
                self._check(where, arg, names)
            return
        _fail(where, f"unsupported element '{ast.unparse(node)}' in {self.text!r}")

    def evaluate(self, row):
        try:
            return float(self._eval(self.tree, row))
        except (TypeError, ValueError, ArithmeticError):
            return math.nan

    def _eval(self, node, row):
        if isinstance(node, ast.Constant):
            return node.value
        if isinstance(node, ast.Name):
            value = row.get(node.id, _CONSTANTS.get(node.id))
            return math.nan if value is None or value == "" else value
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self._eval(node.left, row), self._eval(node.right, row))
        if isinstance(node, ast.UnaryOp):
            value = self._eval(node.operand, row)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.Compare):
            return float(_COMPARE[type(node.ops[0])](self._eval(node.left, row),
                                                     self._eval(node.comparators[0], row)))
        return _FUNCTIONS[node.func.id](*[self._eval(a, row) for a in node.args])


# ------------------------------------------------------------------------------------------

class Run:
    """One combination: its place in the sweep, axis labels, simulate arguments and key."""

    def __init__(self, index, labels, arguments):
        self.index = index          # position in the sweep's order (row order of the table)
        self.labels = labels        # column -> axis value (label for a files axis)
        self.arguments = arguments  # simulate arguments: scene, --set-file, --set
        self.keep = []              # extra outputs kept (events, forces)
        self.scene = None           # resolved scene (one line of YAML), after validation
        self.key = None             # hash of the resolved scene, the binary and the outputs


class Sweep:
    """A parsed sweep file."""

    def __init__(self, path):
        self.path = pathlib.Path(path).resolve()
        try:
            spec = yaml.safe_load(self.path.read_text())
        except OSError as e:
            raise SweepError(f"{path}: cannot read ({e.strerror})") from None
        except yaml.YAMLError as e:
            raise SweepError(f"{path}: not YAML ({e})") from None
        where = str(path)
        if not isinstance(spec, dict):
            _fail(where, f"expected a mapping (got {spec!r})")
        unknown = set(spec) - TOP_KEYS
        if unknown:
            _fail(where, f"unknown key(s) {sorted(unknown)} (known: {sorted(TOP_KEYS)})")
        base = self.path.parent
        self.name = str(spec.get("name", self.path.stem))
        self.scene = (_existing(f"{where}: scene", base, spec["scene"]) if "scene" in spec
                      else None)
        self.set_files = [_existing(f"{where}: set_files", base, p)
                          for p in self._list(f"{where}: set_files", spec.get("set_files", []))]
        self.fixed = self._fixed(f"{where}: set", spec.get("set"))
        self.seeds = self._seeds(f"{where}: seeds", spec.get("seeds"))
        shared = self._axes(f"{where}: axes", spec.get("axes", []), base)
        groups = spec.get("groups")
        if groups is None:
            self.groups = [Group(None, shared, [], spec.get("keep", []))]
        else:
            if not isinstance(groups, list) or not groups:
                _fail(f"{where}: groups", f"expected a non-empty list (got {groups!r})")
            self.groups = []
            for i, g in enumerate(groups):
                here = f"{where}: groups[{i}]"
                if not isinstance(g, dict) or set(g) - GROUP_KEYS or "name" not in g:
                    _fail(here, f"expected {{name, axes, set, keep}} (got {g!r})")
                self.groups.append(Group(str(g["name"]), shared + self._axes(
                    here + ".axes", g.get("axes", []), base), self._fixed(here + ".set",
                    g.get("set")), g.get("keep", spec.get("keep", []))))
        for group in self.groups:
            names = [a.column() for a in group.axes]
            if len(set(names)) != len(names):
                _fail(f"{where}: axes", f"two axes share a column name ({names})")
            if self.scene is None and not any(a.kind == "cases" for a in group.axes):
                _fail(where, "needs a base scene (scene: PATH) or a cases axis")
            group.keep = self._keep(f"{where}: keep", group.keep, self.axis_columns())
        self.outcomes = self._outcomes(f"{where}: outcomes",
                                       spec.get("outcomes", DEFAULT_OUTCOMES))
        derived = spec.get("derived", {}) or {}
        if not isinstance(derived, dict):
            _fail(f"{where}: derived", f"expected a mapping of column: expression "
                  f"(got {derived!r})")
        known = self.axis_columns() + list(self.outcomes) + ["wall_s", "cpu_s"]
        self.derived = {}
        for column, text in derived.items():
            self.derived[str(column)] = Expression(f"{where}: derived.{column}", text, known)
            known.append(str(column))
        self.timeout_s = _number(f"{where}: timeout", spec.get("timeout", 600))
        if self.timeout_s <= 0:
            _fail(f"{where}: timeout", f"must be > 0 s (got {self.timeout_s!r})")
        self.report = spec.get("report", {}) or {}

    @staticmethod
    def _axes(where, axes, base):
        if not isinstance(axes, list):
            _fail(where, f"expected a list of axes (got {axes!r})")
        return [Axis(f"{where}[{i}]", a, base) for i, a in enumerate(axes)]

    @staticmethod
    def _fixed(where, fixed):
        fixed = fixed or {}
        if not isinstance(fixed, dict):
            _fail(where, f"expected a mapping of key paths to values (got {fixed!r})")
        return [f"{k}={_scene_text(v)}" for k, v in fixed.items()]

    @staticmethod
    def _list(where, value):
        if not isinstance(value, list):
            _fail(where, f"expected a list (got {value!r})")
        return value

    @staticmethod
    def _seeds(where, spec):
        """(column, key, list of seeds) or None: `seeds: N` sets stream.seed to 1..N."""
        if spec is None:
            return None
        if isinstance(spec, int) and not isinstance(spec, bool):
            spec = {"count": spec}
        if not isinstance(spec, dict) or set(spec) - {"count", "key", "first"}:
            _fail(where, f"expected a count or {{count, key, first}} (got {spec!r})")
        count, first = spec.get("count"), spec.get("first", 1)
        for name, v in (("count", count), ("first", first)):
            if isinstance(v, bool) or not isinstance(v, int) or v < (1 if name == "count" else 0):
                _fail(f"{where}.{name}", f"expected a whole number >= "
                      f"{1 if name == 'count' else 0} (got {v!r})")
        return ("seed", str(spec.get("key", "stream.seed")), list(range(first, first + count)))

    @staticmethod
    def _outcomes(where, spec):
        """Column -> dotted path into the run's JSON summary."""
        if not isinstance(spec, list) or not spec:
            _fail(where, f"expected a non-empty list of summary paths (got {spec!r})")
        columns = {}
        for item in spec:
            if isinstance(item, dict) and len(item) == 1:
                (column, path), = item.items()
            elif isinstance(item, str):
                path = item
                column = item[len("outcomes."):] if item.startswith("outcomes.") else item
                column = column.replace(".", "_")
            else:
                _fail(where, f"expected a summary path or {{column: path}} (got {item!r})")
            columns[str(column)] = str(path)
        return columns

    @staticmethod
    def _keep(where, spec, names):
        """Extra outputs kept per run: a list (every run) or a mapping of output to true or a
        condition on the axis columns, e.g. {forces: "drum_speed_rpm == 800"}."""
        if isinstance(spec, list):
            spec = {item: True for item in spec}
        if not isinstance(spec, dict):
            _fail(where, f"expected a list or a mapping of outputs (got {spec!r})")
        keep = {}
        for item, when in spec.items():
            if item not in KEEP_FILES:
                _fail(where, f"expected outputs among {sorted(KEEP_FILES)} (got {item!r})")
            keep[item] = when if isinstance(when, bool) else \
                Expression(f"{where}.{item}", when, names)
        return keep

    def all_axes(self):
        """The axes of every group, one per column (the first group's where shared)."""
        axes = {}
        for group in self.groups:
            for axis in group.axes:
                axes.setdefault(axis.column(), axis)
        return list(axes.values())

    def axis_columns(self):
        columns = ["group"] if self.groups[0].name is not None else []
        for group in self.groups:
            columns += [a.column() for a in group.axes if a.column() not in columns]
        return columns + ([self.seeds[0]] if self.seeds else [])

    def runs(self):
        """Every combination, group by group, in order (the last axis varies fastest, seeds
        fastest of all)."""
        runs = []
        seeds = self.seeds[2] if self.seeds else [None]
        for group in self.groups:
            dims = [range(len(a.labels)) for a in group.axes]
            cases = [a for a in group.axes if a.kind == "cases"]
            for choice in itertools.product(*dims):
                for seed in seeds:
                    labels = {} if group.name is None else {"group": group.name}
                    scene = [] if cases else [str(self.scene)]
                    files, sets = [], []
                    for axis, i in zip(group.axes, choice):
                        labels[axis.column()] = axis.labels[i]
                        args = axis.arguments(i)
                        if axis.kind == "cases":
                            scene = args[:1]
                            args = args[1:]
                        # Override files before any --set, as simulate applies them.
                        for flag, value in zip(args[::2], args[1::2]):
                            (files if flag == "--set-file" else sets).extend([flag, value])
                    fixed = [a for f in self.fixed + group.fixed for a in ("--set", f)]
                    if seed is not None:
                        labels["seed"] = seed
                        sets += ["--set", f"{self.seeds[1]}={seed}"]
                    base = [a for f in self.set_files for a in ("--set-file", str(f))]
                    run = Run(len(runs), labels, scene + base + files + fixed + sets)
                    run.keep = sorted(k for k, when in group.keep.items()
                                      if when is True or (when is not False and
                                                          when.evaluate(labels) == 1.0))
                    runs.append(run)
        return runs


class Group:
    """Axes and overrides of a part of the sweep (a sweep without groups has one)."""

    def __init__(self, name, axes, fixed, keep):
        self.name = name    # table column `group`, or None
        self.axes = axes
        self.fixed = fixed  # "key=value" overrides of this group, after the sweep's
        self.keep = keep


def _check_batch(simulate, runs, timeout_s):
    """Lines of `simulate --check-batch` for the runs (one process)."""
    text = "".join("\t".join(r.arguments) + "\n" for r in runs)
    proc = subprocess.run([str(simulate), "--check-batch", "-"], input=text, capture_output=True,
                          text=True, timeout=timeout_s)
    lines = proc.stdout.splitlines()
    if len(lines) != len(runs):
        raise SweepError(f"{simulate} --check-batch answered {len(lines)} lines for "
                         f"{len(runs)} runs: {proc.stderr.strip()}")
    return lines


def validate(sweep, runs, simulate, binary_sha, jobs=1, timeout_s=600):
    """Resolves every run with `simulate --check-batch` (`jobs` processes, each a share of the
    runs) and sets each run's scene and key. Raises SweepError naming the first bad run's axis
    values, its key path and value (the loader's message), and how many runs are bad."""
    import concurrent.futures

    jobs = max(1, min(jobs, len(runs) // 50 + 1))
    shares = [runs[i::jobs] for i in range(jobs)]
    with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        answers = list(pool.map(lambda share: _check_batch(simulate, share, timeout_s), shares))
    lines = [None] * len(runs)
    for i, answer in enumerate(answers):
        lines[i::jobs] = answer
    bad = []
    for run, line in zip(runs, lines):
        verdict, _, rest = line.partition("\t")
        if verdict != "ok":
            bad.append((run, rest))
            continue
        run.scene = rest
        outputs = ",".join(run.keep)
        run.key = hashlib.sha256(f"{binary_sha}\n{outputs}\n{rest}".encode()).hexdigest()[:32]
    if bad:
        run, message = bad[0]
        axes = ", ".join(f"{k}={v}" for k, v in run.labels.items())
        raise SweepError(f"{sweep.path}: {len(bad)} of {len(runs)} runs are invalid; the first "
                         f"({axes}): {message}")
