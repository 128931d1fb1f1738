"""Sweep files: parsing, expansion into runs, and validation of every run with the scene loader.

A sweep file (YAML) names a base scene, override files and fixed overrides, a list of axes, a
number of seeds, the outcomes to collect and optional derived columns (docs/sweeps.md has the
reference). Paths in it are relative to the sweep file. Every run is the cartesian product of
one value of each axis (and one seed); `simulate --check-batch` validates them all in one
process and returns each run's resolved scene, whose hash (with the binary's) is the run's key.

Every count, size and magnitude a sweep file sets is bounded (LIMITS below, the table of
docs/sweeps.md "Limits"), and checked before anything is expanded or run: a hostile file is
refused with a SweepError naming the key, never left to hang or to exhaust the memory.
"""
import ast
import hashlib
import itertools
import math
import os
import pathlib
import reprlib
import stat
import subprocess

import yaml

from tslib.numbers import RADPS_PER_RPM  # noqa: E402
UNITS = {None: 1.0, "rad/s": 1.0, "rpm": RADPS_PER_RPM}
TOP_KEYS = {"name", "scene", "set_files", "set", "axes", "seeds", "outcomes", "derived",
            "timeout", "keep", "report", "groups", "stop"}
GROUP_KEYS = {"name", "axes", "set", "keep"}
AXIS_KEYS = {"name", "key", "unit", "values", "range", "files", "cases"}
CASE_KEYS = {"scene", "set_files", "set"}
DEFAULT_OUTCOMES = ["outcomes.peak_normal_force_N", "outcomes.peak_tangential_force_N",
                    "outcomes.detached", "outcomes.damaged", "outcomes.kernels"]
KEEP_FILES = {"events", "forces"}  # extra simulate outputs a sweep may keep per run
REPORT_KINDS = {"findings"}        # report.kind (absent: the generic report)

# ------------------------------------------------------------------------------------------
# Limits. docs/sweeps.md's "Limits" table is generated from LIMITS (limits_markdown();
# test/sweeps/test_sweep_hostile.py checks the page against it).

MAX_FILE_BYTES = 1 << 20        # the sweep file's size
MAX_YAML_NODES = 20_000         # YAML nodes, with every alias counted as the nodes it repeats
MAX_YAML_DEPTH = 32             # nesting of YAML collections (aliases expanded)
MAX_YAML_ALIASES = 1_000        # uses of YAML aliases (*name), merge keys included
MAX_STRING_CHARS = 4_096        # one YAML scalar: path, key path, label, value
MAX_RUNS = 100_000              # runs of the whole sweep (sum over groups); seeds' count
MAX_AXIS_VALUES = 100_000       # values of one axis: list length, range count or steps, cases
MAX_AXES = 32                   # axes of a group (top-level axes included)
MAX_GROUPS = 1_000              # groups
MAX_OVERRIDES = 1_000           # entries of one set or set_files list
MAX_OUTCOMES = 1_000            # outcomes
MAX_DERIVED = 100               # derived columns
MAX_PLOTS = 100                 # report.plots
MAX_SEED = 2**31 - 1            # the last seed (first + count - 1); stream.seed's bound
MAX_TIMEOUT_S = 86_400.0        # timeout per run (s)
MAX_MAGNITUDE = 1e300           # a number's magnitude: range ends, unit values, expressions
MAX_BATCH_BYTES = 64 << 20      # simulate arguments of all runs together (bytes)
MAX_EXPRESSION_CHARS = 1_000    # one derived or keep expression's text
MAX_EXPRESSION_NODES = 200      # its operators, operands and calls (AST nodes)
MAX_EXPRESSION_DEPTH = 100      # its nesting (AST depth; a + b + c + ... nests one a term)

LIMITS = [  # (constant, value, what is bounded, keys)
    ("MAX_FILE_BYTES", MAX_FILE_BYTES, "size of the sweep file (bytes)", "the file"),
    ("MAX_YAML_NODES", MAX_YAML_NODES, "YAML nodes, each alias counted as the nodes it "
     "repeats (YAML bombs)", "the file"),
    ("MAX_YAML_DEPTH", MAX_YAML_DEPTH, "nesting depth of YAML collections, aliases expanded",
     "the file"),
    ("MAX_YAML_ALIASES", MAX_YAML_ALIASES, "uses of aliases (`*name`, `<<: *name`); an alias "
     "to its own collection is refused", "the file"),
    ("MAX_STRING_CHARS", MAX_STRING_CHARS, "characters of one scalar (path, key, label, value)",
     "any"),
    ("MAX_RUNS", MAX_RUNS, "runs of the sweep (product of the axes' lengths and the seeds, "
     "summed over the groups), and the seeds' count", "`axes`, `groups`, `seeds`"),
    ("MAX_AXIS_VALUES", MAX_AXIS_VALUES, "values of one axis (list, range `count` or steps, "
     "files, cases)", "`axes[i]`"),
    ("MAX_AXES", MAX_AXES, "axes of one group, the top-level ones included", "`axes`, "
     "`groups[i].axes`"),
    ("MAX_GROUPS", MAX_GROUPS, "groups", "`groups`"),
    ("MAX_OVERRIDES", MAX_OVERRIDES, "entries of one `set` or `set_files`", "`set`, "
     "`set_files`, `groups[i].set`, `cases.*.set`"),
    ("MAX_OUTCOMES", MAX_OUTCOMES, "outcomes", "`outcomes`"),
    ("MAX_DERIVED", MAX_DERIVED, "derived columns", "`derived`"),
    ("MAX_PLOTS", MAX_PLOTS, "plots of the report", "`report.plots`"),
    ("MAX_SEED", MAX_SEED, "the last seed, `first + count - 1` (the scene's `stream.seed` "
     "bound)", "`seeds`"),
    ("MAX_TIMEOUT_S", MAX_TIMEOUT_S, "wall-time limit per run (s)", "`timeout`"),
    ("MAX_MAGNITUDE", MAX_MAGNITUDE, "magnitude of a number: range ends and steps, values "
     "with a unit, constants of expressions and what they compute", "`range`, `values`, "
     "`derived`, `keep`"),
    ("MAX_BATCH_BYTES", MAX_BATCH_BYTES, "`simulate` arguments of all runs together (bytes), "
     "estimated before the runs are expanded", "`set`, `set_files`, `axes`, `seeds`"),
    ("MAX_EXPRESSION_CHARS", MAX_EXPRESSION_CHARS, "characters of one expression",
     "`derived`, `keep`"),
    ("MAX_EXPRESSION_NODES", MAX_EXPRESSION_NODES, "operators, operands and calls of one "
     "expression", "`derived`, `keep`"),
    ("MAX_EXPRESSION_DEPTH", MAX_EXPRESSION_DEPTH, "nesting depth of one expression",
     "`derived`, `keep`"),
]


def limits_markdown():
    """The Limits table of docs/sweeps.md."""
    lines = ["| limit | value | bounds | keys |", "|---|---|---|---|"]
    for name, value, what, keys in LIMITS:
        shown = f"{value:g}" if isinstance(value, float) and value >= 1e6 else \
            (f"{value:,}".replace(",", " ") if isinstance(value, int) else f"{value:g}")
        lines.append(f"| `{name}` | {shown} | {what} | {keys} |")
    return "\n".join(lines)


class SweepError(Exception):
    """A bad sweep file; the message names the key and the value."""


def _fail(where, what):
    raise SweepError(f"{where}: {what}")


_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlong = 80, 80, 40
_REPR.maxlist = _REPR.maxdict = _REPR.maxtuple = _REPR.maxset = 6
_REPR.maxlevel = 3


def _show(value):
    """A value for an error message: its repr, shortened (bounded work for any value)."""
    return _REPR.repr(value)


def _label(value):
    """A key or label in the place of an error message (`axes[0] (length)`), shortened."""
    text = str(value) if isinstance(value, (str, int, float)) else _show(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _count(where, items, limit, what):
    if len(items) > limit:
        _fail(where, f"{len(items)} {what} exceed the limit of {limit}")
    return items


def _text(where, value):
    """A scalar as text (str of a number), refused if it is a collection."""
    if isinstance(value, (dict, list)) or value is None:
        _fail(where, f"expected a text or number (got {_show(value)})")
    return str(value)


# Characters that would split simulate --check-batch's tab-separated lines (or its answers,
# read with str.splitlines) and so validate something else than what runs.
_BAD_ARGUMENT = {chr(c) for c in range(32)} | {"\x7f", "\x85", "\u2028", "\u2029"}


def _argument(where, text):
    if not _BAD_ARGUMENT.isdisjoint(text):
        _fail(where, f"control characters (tab, line break, NUL, ...) cannot be passed to "
              f"simulate (got {_show(text)})")
    try:
        text.encode("utf-8")  # as simulate --check-batch gets it
    except UnicodeEncodeError:
        _fail(where, f"not valid Unicode (a lone surrogate such as \\udc80) (got {_show(text)})")
    return text


def _number(where, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            (isinstance(value, float) and not math.isfinite(value)):
        _fail(where, f"expected a finite number (got {_show(value)})")
    if abs(value) > MAX_MAGNITUDE:
        _fail(where, f"{_show(value)} exceeds the limit of {MAX_MAGNITUDE:g} in magnitude")
    return value


def _range_values(where, spec, check=lambda n: None):
    """Values of a range axis: {from, to, step} (both ends included) or {from, to, count};
    check(number of values) is called before they are built."""
    if not isinstance(spec, dict) or set(spec) - {"from", "to", "step", "count"} or \
            not {"from", "to"} <= set(spec) or ("step" in spec) == ("count" in spec):
        _fail(where, f"expected {{from, to, step}} or {{from, to, count}} (got {_show(spec)})")
    lo, hi = _number(where + ".from", spec["from"]), _number(where + ".to", spec["to"])
    if "count" in spec:
        n = spec["count"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            _fail(where + ".count", f"expected a whole number >= 1 (got {_show(n)})")
        if n > MAX_AXIS_VALUES:
            _fail(where + ".count", f"{n} exceeds the limit of {MAX_AXIS_VALUES} values")
        check(n)
        if n == 1:
            return [lo]
        return [lo + (hi - lo) * i / (n - 1) for i in range(n)]
    step = _number(where + ".step", spec["step"])
    # In floats: the ends and the step are at most MAX_MAGNITUDE, the quotient may be inf.
    steps = (float(hi) - float(lo)) / float(step) if step else math.nan
    if not steps >= 0:
        _fail(where + ".step", f"does not lead from {_show(lo)} to {_show(hi)} "
              f"(got {_show(step)})")
    if steps > MAX_AXIS_VALUES - 1:
        _fail(where + ".step", f"{_show(step)} from {_show(lo)} to {_show(hi)} gives "
              f"{steps + 1:.3g} values, which exceeds the limit of {MAX_AXIS_VALUES} values")
    n = int(math.floor(steps + 1e-9)) + 1
    check(n)
    values = [lo + i * step for i in range(n)]
    # Whole numbers stay integers (600, 700, ... rpm), others are rounded to 12 digits so that
    # 0.1 + 2 * 0.1 reads 0.3 in the table and the scene.
    return [v if isinstance(v, int) else float(f"{v:.12g}") for v in values]


class _Length(Exception):
    """The number of values of a range, found before they are built."""


def _stop(n):
    raise _Length(n)


def _length(spec):
    """The number of values of an axis' spec, without building them; None for a malformed
    spec (Axis says what is wrong with it)."""
    if not isinstance(spec, dict):
        return None
    for kind in ("values", "files", "cases"):
        if kind in spec:
            return len(spec[kind]) if isinstance(spec[kind], (list, dict)) else None
    try:
        _range_values("", spec.get("range"), _stop)
    except _Length as length:
        return length.args[0]
    except SweepError:
        return None
    return None


def _mapping(where, value, limit, what):
    """A mapping (None: empty) of at most `limit` entries."""
    value = {} if value is None else value
    if not isinstance(value, dict):
        _fail(where, f"expected a mapping of {what} (got {_show(value)})")
    return _count(where, value, limit, what)


def _overrides(where, fixed):
    """`set`: key path -> value, as "key=value" arguments."""
    fixed = _mapping(where, fixed, MAX_OVERRIDES, "key paths to values")
    return [_argument(f"{where}.{_label(k)}", f"{_text(where, k)}={_scene_text(v)}")
            for k, v in fixed.items()]


class Axis:
    """One swept dimension: a scene key over values, or a set of override files."""

    def __init__(self, where, spec, base_dir, check=lambda n: None):
        """check(number of values) is called before the values are built (the run count)."""
        if not isinstance(spec, dict) or set(spec) - AXIS_KEYS or "name" not in spec:
            _fail(where, f"expected a mapping with name and one of values, range, files and "
                  f"keys among {sorted(AXIS_KEYS)} (got {_show(spec)})")
        self.name = _text(where + ".name", spec["name"])
        where = f"{where} ({_label(self.name)})"
        kinds = [k for k in ("values", "range", "files", "cases") if k in spec]
        if len(kinds) != 1:
            _fail(where, f"needs exactly one of values, range, files, cases (got "
                  f"{kinds or 'none'})")
        self.kind = kinds[0]
        self.unit = spec.get("unit")
        if not (self.unit is None or isinstance(self.unit, str)) or self.unit not in UNITS:
            _fail(where + ".unit", f"expected one of {sorted(u for u in UNITS if u)} "
                  f"(got {_show(self.unit)})")
        self.key = spec.get("key")
        if self.kind in ("files", "cases"):
            if self.key is not None or self.unit is not None:
                _fail(where, f"a {self.kind} axis takes no key or unit (its entries hold the "
                      "keys)")
            if self.kind == "files":
                self.labels, self.files = self._files(where + ".files", spec["files"], base_dir,
                                                      check)
            else:
                self.labels, self.cases = self._cases(where + ".cases", spec["cases"], base_dir,
                                                      check)
            self.longest = max(sum(len(a) + 1 for a in self.arguments(i))
                               for i in range(len(self.labels)))
            return
        if not isinstance(self.key, str) or not self.key:
            _fail(where + ".key", f"expected a scene key path such as drum.speed or "
                  f"teeth.*.length (got {_show(self.key)})")
        _argument(where + ".key", self.key)
        if self.kind == "values":
            values = spec["values"]
            if not isinstance(values, list) or not values:
                _fail(where + ".values", f"expected a non-empty list (got {_show(values)})")
            self.labels = _count(where + ".values", values, MAX_AXIS_VALUES, "values")
            check(len(values))
        else:
            self.labels = _range_values(where + ".range", spec["range"], check)
        if self.unit is not None:
            for v in self.labels:
                _number(f"{where}.values", v)
        self.longest = 0  # bytes of the longest arguments of one value
        for i in range(len(self.labels)):
            argument = _argument(f"{where}.values[{i}]", self.arguments(i)[1])
            self.longest = max(self.longest, len(argument) + 6)

    @staticmethod
    def _files(where, spec, base_dir, check):
        if isinstance(spec, list) and spec:
            items = [(pathlib.Path(_text(where, p)).stem, p) for p in spec]
        elif isinstance(spec, dict) and spec:
            items = list(spec.items())
        else:
            _fail(where, f"expected a non-empty list of override files or a mapping of labels "
                  f"to files (got {_show(spec)})")
        _count(where, items, MAX_AXIS_VALUES, "files")
        check(len(items))
        files = [_existing(f"{where}.{_label(label)}", base_dir, path) for label, path in items]
        return [_text(where, label) for label, _ in items], files

    @staticmethod
    def _cases(where, spec, base_dir, check):
        """A case: a scene of its own, with override files and overrides."""
        if not isinstance(spec, dict) or not spec:
            _fail(where, f"expected a mapping of labels to {{scene, set_files, set}} "
                  f"(got {_show(spec)})")
        _count(where, spec, MAX_AXIS_VALUES, "cases")
        check(len(spec))
        cases = []
        for label, case in spec.items():
            here = f"{where}.{_label(label)}"
            if not isinstance(case, dict) or set(case) - CASE_KEYS or "scene" not in case:
                _fail(here, f"expected {{scene, set_files, set}} (got {_show(case)})")
            arguments = [str(_existing(here + ".scene", base_dir, case["scene"]))]
            for path in _list(here + ".set_files", case.get("set_files")):
                arguments += ["--set-file", str(_existing(here + ".set_files", base_dir, path))]
            for argument in _overrides(here + ".set", case.get("set")):
                arguments += ["--set", argument]
            cases.append(arguments)
        return [_text(where, label) for label in spec], cases

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


def _list(where, value, limit=MAX_OVERRIDES, what="entries"):
    """A list (None: empty) of at most `limit` entries."""
    value = [] if value is None else value
    if not isinstance(value, list):
        _fail(where, f"expected a list (got {_show(value)})")
    return _count(where, value, limit, what)


class _Folder:
    """The sweep file's folder; each path in the file is resolved once per load (the groups
    of a sweep name the same files many times)."""

    def __init__(self, path):
        self.path = path
        self.found = {}

    def find(self, text):
        """(resolved path, whether it is a file); OSError, ValueError for a bad path."""
        if text not in self.found:
            full = (self.path / text).resolve()
            self.found[text] = (full, full.is_file())
        return self.found[text]


def _existing(where, base_dir, path):
    """The resolved path of an existing file, relative to base_dir (a _Folder)."""
    text = _text(where, path)
    try:
        full, found = base_dir.find(text)
    except (OSError, ValueError) as e:  # a name too long, a NUL byte, a loop of links
        _fail(where, f"not a usable path ({e}) (got {_show(text)})")
    if not found:
        _fail(where, f"no such file '{text}' (looked at {full})")
    return pathlib.Path(_argument(where, str(full)))


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
# The file: read with a size bound, its YAML events scanned (nodes with aliases expanded,
# depth, aliases, scalar lengths) before anything is built from them.

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _scan(where, text):
    """Refuses YAML past the limits, from the parser's events (no tree is built): bounded work
    for any text, a YAML bomb included (its aliases are counted as the nodes they repeat).
    The message names the place (key path) where the limit was passed."""
    open_ = []      # per open collection: [nodes, height, anchor, is_mapping, index, key]
    anchors = {}    # anchor -> (nodes, height) of its complete node
    nodes = aliases = 0

    def place():
        parts = []
        for _, _, _, mapping, index, key in open_:
            if mapping:  # index counts the keys and values read: odd while in a value
                parts.append(f".{key}" if index % 2 else f".{key}(key)" if index else "")
            else:
                parts.append(f"[{index}]")
        return where + ": " + ("".join(parts).lstrip(".") or "(top)")

    def add(size, height):
        nonlocal nodes
        nodes += size
        if nodes > MAX_YAML_NODES:
            _fail(place(), f"more than {MAX_YAML_NODES} YAML nodes (aliases expanded) exceed "
                  f"the limit of {MAX_YAML_NODES}")
        if len(open_) + height > MAX_YAML_DEPTH:
            _fail(place(), f"nesting deeper than the limit of {MAX_YAML_DEPTH} (aliases "
                  f"expanded)")
        if open_:
            parent = open_[-1]
            parent[0] += size
            parent[1] = max(parent[1], height + 1)
            parent[4] += 1

    def key(text):
        if open_ and open_[-1][3] and open_[-1][4] % 2 == 0:
            open_[-1][5] = text if len(text) <= 40 else text[:37] + "..."

    for event in yaml.parse(text, Loader=_LOADER):
        if isinstance(event, yaml.DocumentStartEvent):
            anchors = {}
        elif isinstance(event, yaml.ScalarEvent):
            key(event.value)
            if len(event.value) > MAX_STRING_CHARS:
                _fail(place(), f"a scalar of {len(event.value)} characters exceeds the limit of "
                      f"{MAX_STRING_CHARS} (starts {_show(event.value[:40])}, line "
                      f"{event.start_mark.line + 1})")
            add(1, 0)
            if event.anchor is not None:
                anchors[event.anchor] = (1, 0)
        elif isinstance(event, yaml.AliasEvent):
            key("*" + event.anchor)
            aliases += 1
            if aliases > MAX_YAML_ALIASES:
                _fail(place(), f"more than {MAX_YAML_ALIASES} aliases exceed the limit of "
                      f"{MAX_YAML_ALIASES}")
            if event.anchor not in anchors:
                _fail(place(), f"alias *{_label(event.anchor)} (line "
                      f"{event.start_mark.line + 1}) refers to no complete node before it "
                      f"(undefined, or its own collection)")
            add(*anchors[event.anchor])
        elif isinstance(event, yaml.CollectionStartEvent):
            key("?")
            open_.append([0, 0, event.anchor, isinstance(event, yaml.MappingStartEvent), 0, ""])
            if len(open_) > MAX_YAML_DEPTH:
                _fail(place(), f"nesting deeper than the limit of {MAX_YAML_DEPTH} (line "
                      f"{event.start_mark.line + 1})")
        elif isinstance(event, yaml.CollectionEndEvent):
            size, height, anchor = open_.pop()[:3]
            size, height = size + 1, max(height, 1)
            add(size, height)
            if anchor is not None:
                anchors[anchor] = (size, height)


def _read(path):
    """The sweep file's parsed YAML, within the limits."""
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise SweepError(f"{path}: not a regular file")
        if info.st_size > MAX_FILE_BYTES:
            raise SweepError(f"{path}: {info.st_size} bytes exceed the limit of "
                             f"{MAX_FILE_BYTES} bytes")
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as e:
        raise SweepError(f"{path}: cannot read ({e.strerror})") from None
    except ValueError as e:  # a NUL in the path
        raise SweepError(f"{path}: cannot read ({e})") from None
    if len(data) > MAX_FILE_BYTES:
        raise SweepError(f"{path}: more than {MAX_FILE_BYTES} bytes exceed the limit of "
                         f"{MAX_FILE_BYTES} bytes")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise SweepError(f"{path}: not UTF-8 text ({e})") from None
    try:
        _scan(str(path), text)
    except yaml.YAMLError as e:
        raise SweepError(f"{path}: not YAML ({e})") from None
    try:
        return yaml.load(text, Loader=_LOADER)
    except yaml.YAMLError as e:
        raise SweepError(f"{path}: not YAML ({e})") from None
    except Exception as e:  # noqa: BLE001
        # PyYAML's constructors fail in their own ways on values that scan fine: a date out of
        # range (2001-02-30: ValueError), `!!timestamp 2001-01-99` (AttributeError), `!!int
        # 1.5` (ValueError), bad `!!binary` (binascii.Error)... The text is within the limits
        # here, so this is bounded; any failure of the library on it is a bad value.
        raise SweepError(f"{path}: not a valid YAML value ({type(e).__name__}: "
                         f"{_show(str(e))})") from None


# ------------------------------------------------------------------------------------------
# Derived columns: arithmetic over a row's columns, parsed once and checked against the names.
# Every number is a float during the evaluation, so each operation takes bounded time and
# memory: no integer of a billion digits (10 ** 10 ** 10) and no repeated string or list
# (column * 1000000000). Constant parts are computed when the file is read and refused
# past MAX_MAGNITUDE.

class _Operands(TypeError):
    """An operation on a value that is not a number (a label): the cell is empty."""


def _arithmetic(op):
    def apply(a, b):
        if not (isinstance(a, float) and isinstance(b, float)):
            raise _Operands()
        return op(a, b)
    return apply


_BINARY = {ast.Add: _arithmetic(lambda a, b: a + b), ast.Sub: _arithmetic(lambda a, b: a - b),
           ast.Mult: _arithmetic(lambda a, b: a * b),
           ast.Div: _arithmetic(lambda a, b: a / b if b else math.nan),
           ast.Pow: _arithmetic(math.pow)}  # OverflowError, not a huge integer or complex
_COMPARE = {ast.Lt: lambda a, b: a < b, ast.LtE: lambda a, b: a <= b,
            ast.Gt: lambda a, b: a > b, ast.GtE: lambda a, b: a >= b,
            ast.Eq: lambda a, b: a == b, ast.NotEq: lambda a, b: a != b}
_FUNCTIONS = {"min": (min, 2, MAX_EXPRESSION_NODES), "max": (max, 2, MAX_EXPRESSION_NODES),
              "abs": (abs, 1, 1), "sqrt": (math.sqrt, 1, 1), "log10": (math.log10, 1, 1)}
_CONSTANTS = {"pi": math.pi}


def _operand(value):
    """A row value in an expression: a float when it is a number (or a number's text), NaN
    when missing, else the value itself (a label: only == and != apply to it)."""
    if value is None or value == "":
        return math.nan
    if isinstance(value, (bool, int, float)):
        return float(value)  # OverflowError for an integer past 1e308: an empty cell
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


class Expression:
    """A derived column, e.g. `damaged / kernels`: numbers, column names, + - * / **,
    comparisons, min, max, abs, sqrt, log10 and pi. A missing or empty value, a division by
    zero or an overflow gives NaN."""

    def __init__(self, where, text, names):
        self.text = _text(where, text)
        if len(self.text) > MAX_EXPRESSION_CHARS:
            _fail(where, f"an expression of {len(self.text)} characters exceeds the limit of "
                  f"{MAX_EXPRESSION_CHARS}")
        try:
            self.tree = ast.parse(self.text, mode="eval").body
        except SyntaxError as e:
            _fail(where, f"not an expression ({e.msg}) (got {_show(self.text)})")
        except (ValueError, RecursionError, MemoryError) as e:  # a NUL; too deep to parse
            _fail(where, f"not an expression ({type(e).__name__}) (got {_show(self.text)})")
        # Size and depth first, without recursion; then the recursive check is bounded.
        stack, count = [(self.tree, 1)], 0
        while stack:
            node, depth = stack.pop()
            count += 1
            if count > MAX_EXPRESSION_NODES:
                _fail(where, f"more than {MAX_EXPRESSION_NODES} operators and operands exceed "
                      f"the limit of {MAX_EXPRESSION_NODES} (got {_show(self.text)})")
            if depth > MAX_EXPRESSION_DEPTH:
                _fail(where, f"nesting deeper than the limit of {MAX_EXPRESSION_DEPTH} "
                      f"(got {_show(self.text)})")
            stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
        self._check(where, self.tree, set(names))

    def _check(self, where, node, names):
        """Refuses what is not allowed; returns the value of a constant node (else None),
        refusing a constant past MAX_MAGNITUDE (10 ** 10 ** 10)."""
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and \
                not isinstance(node.value, bool):
            return self._constant(where, node, lambda: float(node.value))
        if isinstance(node, ast.Name):
            if node.id in _CONSTANTS:
                return _CONSTANTS[node.id]
            if node.id not in names:
                _fail(where, f"unknown column '{node.id}' in {_show(self.text)} (columns: "
                      f"{_show(', '.join(sorted(names)))})")
            return None
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            left = self._check(where, node.left, names)
            right = self._check(where, node.right, names)
            if left is not None and right is not None:
                return self._constant(where, node,
                                      lambda: _BINARY[type(node.op)](left, right))
            return None
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            value = self._check(where, node.operand, names)
            return None if value is None else (-value if isinstance(node.op, ast.USub)
                                                else value)
        if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
            left = self._check(where, node.left, names)
            right = self._check(where, node.comparators[0], names)
            return None if left is None or right is None else \
                float(_COMPARE[type(node.ops[0])](left, right))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                node.func.id in _FUNCTIONS and not node.keywords:
            function, least, most = _FUNCTIONS[node.func.id]
            if not least <= len(node.args) <= most:
                takes = least if least == most else f"{least} or more"
                _fail(where, f"{node.func.id} takes {takes} argument(s) (got {len(node.args)} "
                      f"in {_show(self.text)})")
            values = [self._check(where, arg, names) for arg in node.args]
            if any(v is None for v in values):
                return None
            return self._constant(where, node, lambda: function(*values))
        _fail(where, f"unsupported element {_show(ast.unparse(node))} in {_show(self.text)}")

    def _constant(self, where, node, compute):
        try:
            value = float(compute())
        except OverflowError:
            value = math.inf
        except (ValueError, ArithmeticError, TypeError):  # sqrt(-1), log10(0): NaN as in a row
            return math.nan
        if math.isinf(value) or abs(value) > MAX_MAGNITUDE:
            part = ast.unparse(node)
            _fail(where, f"{_show(part)} exceeds the limit of {MAX_MAGNITUDE:g} in magnitude"
                  + ("" if part == self.text.strip() else f" (in {_show(self.text)})"))
        return value

    def evaluate(self, row):
        try:
            value = self._eval(self.tree, row)
        except (TypeError, ValueError, ArithmeticError):
            return math.nan
        return value if isinstance(value, float) and math.isfinite(value) else math.nan

    def _eval(self, node, row):
        if isinstance(node, ast.Constant):
            return float(node.value)
        if isinstance(node, ast.Name):
            if node.id in row:
                return _operand(row[node.id])
            return _CONSTANTS.get(node.id, math.nan)
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self._eval(node.left, row), self._eval(node.right, row))
        if isinstance(node, ast.UnaryOp):
            value = self._eval(node.operand, row)
            if not isinstance(value, float):
                raise _Operands()
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.Compare):
            return float(_COMPARE[type(node.ops[0])](self._eval(node.left, row),
                                                     self._eval(node.comparators[0], row)))
        values = [self._eval(a, row) for a in node.args]
        if not all(isinstance(v, float) for v in values):
            raise _Operands()
        return float(_FUNCTIONS[node.func.id][0](*values))


# ------------------------------------------------------------------------------------------

class Run:
    """One combination: its place in the sweep, axis labels, simulate arguments and key."""

    def __init__(self, index, labels, arguments):
        self.index = index          # position in the sweep's order (row order of the table)
        self.labels = labels        # column -> axis value (label for a files axis)
        self.arguments = arguments  # simulate arguments: scene, --set-file, --set
        self.keep = []              # extra outputs kept (events, forces)
        self.scene = None           # resolved scene (one line of YAML), after validation
        self.base = None            # its scene with the override files, before the --set ones
        self.key = None             # hash of the resolved scene, the binary and the outputs


class Sweep:
    """A parsed sweep file, within the limits (LIMITS); `run_count` runs."""

    def __init__(self, path):
        spec = _read(path)
        self.path = pathlib.Path(path).resolve()
        where = str(path)
        if not isinstance(spec, dict):
            _fail(where, f"expected a mapping (got {_show(spec)})")
        unknown = set(spec) - TOP_KEYS
        if unknown:
            _fail(where, f"unknown key(s) {_show(sorted(unknown, key=str))} (known: "
                  f"{sorted(TOP_KEYS)})")
        base = _Folder(self.path.parent)
        self.name = self._name(f"{where}: name", spec.get("name", self.path.stem))
        self.scene = (_existing(f"{where}: scene", base, spec["scene"]) if "scene" in spec
                      else None)
        self.set_files = [_existing(f"{where}: set_files", base, p)
                          for p in _list(f"{where}: set_files", spec.get("set_files"))]
        self.fixed = _overrides(f"{where}: set", spec.get("set"))
        self.seeds = self._seeds(f"{where}: seeds", spec.get("seeds"))
        seeds = len(self.seeds[2]) if self.seeds else 1
        shared = self._axes(f"{where}: axes", spec.get("axes", []), base, seeds, 0)
        done = 0  # runs of the groups before
        groups = spec.get("groups")
        if groups is None:
            self.groups = [Group(None, shared, [], spec.get("keep", []))]
        else:
            if not isinstance(groups, list) or not groups:
                _fail(f"{where}: groups", f"expected a non-empty list (got {_show(groups)})")
            _count(f"{where}: groups", groups, MAX_GROUPS, "groups")
            self.groups = []
            for i, g in enumerate(groups):
                here = f"{where}: groups[{i}]"
                if not isinstance(g, dict) or set(g) - GROUP_KEYS or "name" not in g:
                    _fail(here, f"expected {{name, axes, set, keep}} (got {_show(g)})")
                shared_runs = seeds * math.prod(len(a.labels) for a in shared)
                axes = shared + self._axes(here + ".axes", g.get("axes", []), base,
                                           shared_runs, done)
                done += shared_runs * math.prod(len(a.labels) for a in axes[len(shared):])
                self.groups.append(Group(_text(here + ".name", g["name"]), axes, _overrides(
                    here + ".set", g.get("set")), g.get("keep", spec.get("keep", []))))
        for i, group in enumerate(self.groups):
            here = f"{where}: axes" if group.name is None else f"{where}: groups[{i}].axes"
            _count(here, group.axes, MAX_AXES, "axes (the top-level ones included)")
            names = [a.column() for a in group.axes]
            if len(set(names)) != len(names):
                _fail(here, f"two axes share a column name ({_show(names)})")
            if self.scene is None and not any(a.kind == "cases" for a in group.axes):
                _fail(where, "needs a base scene (scene: PATH) or a cases axis")
        self.run_count = self._check_size(where)
        for group in self.groups:
            group.keep = self._keep(f"{where}: keep", group.keep, self.axis_columns())
        self.outcomes = self._outcomes(f"{where}: outcomes",
                                       spec.get("outcomes", DEFAULT_OUTCOMES))
        derived = _mapping(f"{where}: derived", spec.get("derived"), MAX_DERIVED,
                           "derived columns (column: expression)")
        known = self.axis_columns() + list(self.outcomes) + ["wall_s", "cpu_s"]
        self.derived = {}
        for column, text in derived.items():
            name = _text(f"{where}: derived", column)
            self.derived[name] = Expression(f"{where}: derived.{_label(name)}", text, known)
            known.append(name)
        self.timeout_s = _number(f"{where}: timeout", spec.get("timeout", 600))
        if not 0 < self.timeout_s <= MAX_TIMEOUT_S:
            _fail(f"{where}: timeout", f"must be > 0 s and at most the limit of "
                  f"{MAX_TIMEOUT_S:g} s (got {_show(self.timeout_s)})")
        self.report = self._report(f"{where}: report", spec.get("report"))
        self.stop = spec.get("stop")  # seeds in rounds (tslib/sweep/stats.py), or None

    def _check_size(self, where):
        """The number of runs, refused past MAX_RUNS, and the size of their simulate arguments,
        refused past MAX_BATCH_BYTES; both computed from the axes' lengths, before any run is
        expanded."""
        seeds = len(self.seeds[2]) if self.seeds else 1
        seed_bytes = (len(self.seeds[1]) + len(str(self.seeds[2][-1])) + 8) if self.seeds else 0
        total = size = 0
        for i, group in enumerate(self.groups):
            here = f"{where}: axes" if group.name is None else \
                f"{where}: groups[{i}] ({_label(group.name)})"
            runs = seeds
            for axis in group.axes:
                runs *= len(axis.labels)
            total += runs
            if total > MAX_RUNS:
                factors = [f"{len(a.labels)} ({_show(a.name)})" for a in group.axes] + \
                    ([f"{seeds} seeds"] if self.seeds else [])
                earlier = f" after {total - runs} runs of the groups before it" \
                    if total != runs else ""
                _fail(here, f"{' x '.join(factors)} = {runs} runs{earlier} exceeds the limit "
                      f"of {MAX_RUNS} runs")
            # Bytes of one run's arguments: the fixed ones and each axis' longest.
            fixed = len(str(self.scene or "")) + seed_bytes + \
                sum(len(str(f)) + 12 for f in self.set_files) + \
                sum(len(f) + 7 for f in self.fixed + group.fixed)
            longest = sum(axis.longest for axis in group.axes)
            size += runs * (fixed + longest)
            if size > MAX_BATCH_BYTES:
                _fail(here, f"{runs} runs of up to {fixed + longest} bytes of simulate "
                      f"arguments each exceed the limit of {MAX_BATCH_BYTES} bytes in all")
        return total

    @staticmethod
    def _name(where, name):
        """The output folder's name, out/sweeps/NAME: one path component."""
        name = _argument(where, _text(where, name))
        if not name or name in (".", "..") or "/" in name or "\\" in name or len(name) > 255:
            _fail(where, f"expected a folder name (no '/', no control characters, not '.' or "
                  f"'..', at most 255 characters) (got {_show(name)})")
        return name

    @staticmethod
    def _axes(where, specs, base, runs, done):
        """The axes of a list. `runs`: runs of each combination of them (the seeds, and the
        shared axes of a group); `done`: runs of the groups before. Refuses the axis that
        takes the sweep past MAX_RUNS as soon as it is read (so that no more than that is
        built)."""
        specs = [] if specs is None else specs
        if not isinstance(specs, list):
            _fail(where, f"expected a list of axes (got {_show(specs)})")
        _count(where, specs, MAX_AXES, "axes")
        def check(lengths):
            total = runs * math.prod(n for _, n in lengths)
            if done + total > MAX_RUNS:
                factors = " x ".join(f"{n} ({_label(name)})" for name, n in lengths)
                before = f" (and {done} runs before)" if done else ""
                _fail(where, f"{factors} values give {total} runs{before}, which exceeds the "
                      f"limit of {MAX_RUNS} runs (seeds and shared axes included)")

        # First from the lengths alone, nothing built (a malformed axis is left to Axis)...
        check([(s.get("name"), n) for s, n in ((s, _length(s)) for s in specs) if n])
        axes = []
        for i, spec in enumerate(specs):
            # ... then axis by axis, each before its values are built.
            axes.append(Axis(f"{where}[{i}]", spec, base, lambda n: check(
                [(a.name, len(a.labels)) for a in axes] + [(spec.get("name"), n)])))
        return axes

    @staticmethod
    def _seeds(where, spec):
        """(column, key, list of seeds) or None: `seeds: N` sets stream.seed to 1..N."""
        if spec is None:
            return None
        if isinstance(spec, int) and not isinstance(spec, bool):
            spec = {"count": spec}
        if not isinstance(spec, dict) or set(spec) - {"count", "key", "first"}:
            _fail(where, f"expected a count or {{count, key, first}} (got {_show(spec)})")
        count, first = spec.get("count"), spec.get("first", 1)
        for name, v in (("count", count), ("first", first)):
            if isinstance(v, bool) or not isinstance(v, int) or v < (1 if name == "count" else 0):
                _fail(f"{where}.{name}", f"expected a whole number >= "
                      f"{1 if name == 'count' else 0} (got {_show(v)})")
        if count > MAX_RUNS:
            _fail(where, f"{count} exceeds the limit of {MAX_RUNS} runs")
        if first + count - 1 > MAX_SEED:
            _fail(where, f"the last seed {_show(first + count - 1)} (first {_show(first)}, count "
                  f"{count}) exceeds the limit of {MAX_SEED}")
        key = spec.get("key", "stream.seed")
        if not isinstance(key, str) or not key:
            _fail(f"{where}.key", f"expected a scene key path (got {_show(key)})")
        return ("seed", _argument(f"{where}.key", key), list(range(first, first + count)))

    @staticmethod
    def _outcomes(where, spec):
        """Column -> dotted path into the run's JSON summary."""
        if not isinstance(spec, list) or not spec:
            _fail(where, f"expected a non-empty list of summary paths (got {_show(spec)})")
        _count(where, spec, MAX_OUTCOMES, "outcomes")
        columns = {}
        for item in spec:
            if isinstance(item, dict) and len(item) == 1:
                (column, path), = item.items()
                column, path = _text(where, column), _text(where, path)
            elif isinstance(item, str):
                path = item
                column = item[len("outcomes."):] if item.startswith("outcomes.") else item
                column = column.replace(".", "_")
            else:
                _fail(where, f"expected a summary path or {{column: path}} (got {_show(item)})")
            columns[column] = path
        return columns

    @staticmethod
    def _keep(where, spec, names):
        """Extra outputs kept per run: a list (every run) or a mapping of output to true or a
        condition on the axis columns, e.g. {forces: "drum_speed_rpm == 800"}."""
        if isinstance(spec, list):
            for item in spec:
                if not isinstance(item, str):
                    _fail(where, f"expected outputs among {sorted(KEEP_FILES)} "
                          f"(got {_show(item)})")
            spec = {item: True for item in spec}
        if not isinstance(spec, dict):
            _fail(where, f"expected a list or a mapping of outputs (got {_show(spec)})")
        keep = {}
        for item, when in spec.items():
            if item not in KEEP_FILES:
                _fail(where, f"expected outputs among {sorted(KEEP_FILES)} (got {_show(item)})")
            keep[item] = when if isinstance(when, bool) else \
                Expression(f"{where}.{item}", when, names)
        return keep

    @staticmethod
    def _report(where, spec):
        """report: {kind, plots}; each plot {y, x, lines, bands} or {pareto: {x, y}, color}."""
        spec = _mapping(where, spec, MAX_OVERRIDES, "report settings")
        kind = spec.get("kind")
        if kind is not None and (not isinstance(kind, str) or kind not in REPORT_KINDS):
            _fail(where + ".kind", f"expected one of {sorted(REPORT_KINDS)} (got {_show(kind)})")
        plots = _list(where + ".plots", spec.get("plots"), MAX_PLOTS, "plots")
        for i, plot in enumerate(plots):
            here = f"{where}.plots[{i}]"
            if not isinstance(plot, dict):
                _fail(here, f"expected {{y, x, lines}} or {{pareto: {{x, y}}, color}} "
                      f"(got {_show(plot)})")
            columns = plot.get("pareto") if "pareto" in plot else plot
            if not isinstance(columns, dict) or \
                    not all(isinstance(columns.get(k), str) for k in ("x", "y")) or \
                    not all(isinstance(plot.get(k), (str, type(None))) for k in ("lines",
                                                                                  "color")):
                _fail(here, f"expected column names x and y (and lines or color) "
                      f"(got {_show(plot)})")
        return spec

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


def _check_batch(simulate, runs, timeout_s, compile_models=True):
    """Lines of `simulate --check-batch` for the runs (one process; without compile_models,
    --resolve-only)."""
    text = "".join("\t".join(r.arguments) + "\n" for r in runs)
    command = [str(simulate), "--check-batch", "-"] + ([] if compile_models else
                                                       ["--resolve-only"])
    proc = subprocess.run(command, input=text, capture_output=True, text=True,
                          timeout=timeout_s)
    lines = proc.stdout.splitlines()
    if len(lines) != len(runs):
        raise SweepError(f"{simulate} --check-batch answered {len(lines)} lines for "
                         f"{len(runs)} runs: {proc.stderr.strip()}")
    return lines


def validate(sweep, runs, simulate, binary_sha, jobs=1, timeout_s=600, compile_models=True):
    """Resolves every run with `simulate --check-batch` (`jobs` processes, each a share of the
    runs) and sets each run's scene, base scene (the scene with its override files: a batch
    process parses each base once and applies the run's --set values to a copy) and key.
    Raises SweepError naming the first bad run's axis values, its key path and value (the
    loader's message), and how many runs are bad (invalid_error). Without compile_models
    (--resolve-only) the scenes are resolved but not compiled: only a bad key path is refused
    here, and the runner's batch processes validate the rest before any run starts
    (runner.run_sweep)."""
    jobs = max(1, min(jobs, len(runs) // 50 + 1))
    shares = [runs[i::jobs] for i in range(jobs)]
    if jobs == 1:
        answers = [_check_batch(simulate, runs, timeout_s, compile_models)]
    else:
        import concurrent.futures

        with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
            answers = list(pool.map(lambda share: _check_batch(simulate, share, timeout_s,
                                                               compile_models), shares))
    lines = [None] * len(runs)
    for i, answer in enumerate(answers):
        lines[i::jobs] = answer
    bad = []
    bases = {}
    for run, line in zip(runs, lines):
        verdict, _, rest = line.partition("\t")
        if verdict != "ok":
            bad.append((run, rest))
            continue
        run.scene, _, base = rest.partition("\t")
        run.base = bases.setdefault(base, base) if base else None  # one string per base
        outputs = ",".join(run.keep)
        run.key = hashlib.sha256(f"{binary_sha}\n{outputs}\n{run.scene}".encode()).hexdigest()[:32]
    if bad:
        raise invalid_error(sweep, len(runs), bad)


def invalid_error(sweep, n_runs, bad):
    """The SweepError for a sweep with bad runs: bad holds (run, the loader's message) in sweep
    order; the first is named by its axis values."""
    run, message = bad[0]
    axes = ", ".join(f"{k}={v}" for k, v in run.labels.items())
    return SweepError(f"{sweep.path}: {len(bad)} of {n_runs} runs are invalid; the first "
                      f"({axes}): {message}")
