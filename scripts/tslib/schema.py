"""The scene schema of the core (`simulate --print-schema`): every key with its type, unit,
default, range and meaning. Scripts read the core's defaults and limits from here instead of
copying them from the C++ sources.

The table comes from the built simulate (the one given, else the workspace's or a sourced
one's) or, with none built, from its generated copy in docs/scene_reference.md (the
scene-reference section; scripts/scene_reference.sh writes it, test_hostile_inputs checks that
it is current)."""
import functools
import json
import re
import subprocess

from tslib import markdown
from tslib.binaries import find_binary


_chosen = [None]  # the simulate of use(), the default of every look-up


def use(simulate):
    """Reads the schema of this simulate from now on (the one a script was given)."""
    _chosen[0] = str(simulate) if simulate else None


@functools.lru_cache(maxsize=None)
def _rows(simulate=None):
    text = None
    try:
        binary = find_binary("simulate", simulate)
        text = subprocess.run([str(binary), "--print-schema"], capture_output=True, text=True,
                              check=True, timeout=60).stdout
    except (SystemExit, OSError, subprocess.SubprocessError):
        if simulate:
            raise
    if not text:
        text = markdown.section_body(markdown.page_of("scene-reference").read_text(),
                                     "scene-reference") or ""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if len(cells) >= 6 and cells[0].startswith("`"):
            rows[cells[0].strip("`")] = {"type": cells[1], "unit": cells[2],
                                         "default": cells[3], "range": cells[4],
                                         "meaning": " | ".join(cells[5:])}
    if not rows:
        raise SystemExit("schema: no key table in simulate --print-schema nor in "
                         "docs/scene_reference.md")
    return rows


def row(key, simulate=None):
    """The schema's row of key (e.g. "teeth.*.modes"): type, unit, default, range, meaning."""
    rows = _rows(str(simulate) if simulate else _chosen[0])
    if key not in rows:
        raise SystemExit(f"schema: no key {key} in the scene schema")
    return rows[key]


def value(key, simulate=None):
    """The default of a key: a number, a list of numbers, or a word ("compliant", "auto")."""
    cell = row(key, simulate)["default"]
    try:
        return json.loads(cell)
    except ValueError:
        return cell


def default(key, simulate=None):
    """The default of a numeric key, as a float."""
    return float(row(key, simulate)["default"])


def bounds(key, simulate=None):
    """(lower, upper) of a numeric key's range "in [lo, hi]" (or open bounds), as floats."""
    m = re.fullmatch(r"in [\[(]([^,]+), ([^\])]+)[\])]", row(key, simulate)["range"])
    if not m:
        raise SystemExit(f"schema: {key} has no numeric range")
    return float(m.group(1)), float(m.group(2))


def said(key, pattern, simulate=None):
    """The number that `pattern` (a regular expression with one group) finds in a key's
    meaning, e.g. the large-deflection tooth's most shape functions in that of teeth.*.modes."""
    m = re.search(pattern, row(key, simulate)["meaning"])
    if not m:
        raise SystemExit(f"schema: the meaning of {key} does not say /{pattern}/")
    return float(m.group(1))
