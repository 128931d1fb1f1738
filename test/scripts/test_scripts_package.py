#!/usr/bin/python3
"""Guards the structure of scripts/ (issue 25, item 5): the scripts are one package, tslib, with
thin entry points.

- no import cycle among the modules of scripts/ (the entry points and tslib, tslib.sweep included), lazy
  imports inside functions included; the graph is built with `ast`, nothing is imported;
- no top-level name (function, class, constant) defined in two modules of the package: a helper
  such as fmt, rel or ROOT lives in one module and the others import it;
- every entry point with options still answers --help (exit 0, a usage line).

Run: /usr/bin/python3 test/scripts/test_scripts_package.py [-v] (scripts/test.sh runs it).
"""
import ast
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import unittest

ROOT = pathlib.Path(__file__).resolve().parents[2]
# The scripts folder checked; $SCRIPTS_DIR checks another (e.g. an older checkout's).
SCRIPTS = pathlib.Path(os.environ.get("SCRIPTS_DIR", ROOT / "scripts")).resolve()

# Entry points that take no options (--help would run them): the result counter of
# scripts/test.sh and the fault injector of scripts/soak.sh (needs a running node).
NO_HELP = {"count_results", "soak_faults"}
# Names every entry point may define for itself.
PER_MODULE = {"main", "parse_args"}


def installed():
    """The scripts catkin installs (catkin_install_python in CMakeLists.txt): they run from the
    package's lib folder, where scripts/tslib is not, so they stay self-contained and are left
    out of the duplicate check."""
    text = (ROOT / "CMakeLists.txt").read_text()
    found = set()
    for call in re.findall(r"catkin_install_python\(PROGRAMS(.*?)DESTINATION", text, re.S):
        found.update(pathlib.Path(word).stem for word in call.split())
    return found


def is_python(path):
    if path.suffix == ".py":
        return True
    if path.suffix or not path.is_file():
        return False
    with open(path, "rb") as f:
        first = f.readline()
    return first.startswith(b"#!") and b"python" in first


def modules(folder=None):
    """{dotted module name: path} of every Python module of scripts/ (entry points without the
    .py suffix included; a package's __init__.py is the package's name)."""
    folder = folder or SCRIPTS
    found = {}
    for path in sorted(folder.rglob("*")):
        if "__pycache__" in path.parts or not is_python(path):
            continue
        rel = path.relative_to(folder)
        parts = list(rel.parts[:-1]) + [rel.stem if rel.suffix == ".py" else rel.name]
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def package_of(name, path):
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def imports(name, path, known):
    """The modules of `known` that module `name` imports, anywhere in its text."""
    tree = ast.parse(path.read_text(), str(path))
    package = package_of(name, path)
    out = set()

    def add(target):
        # `import a.b.c` loads a, a.b and a.b.c: the deepest known one is the dependency (a
        # submodule's package is loaded first, which is not a cycle unless the package's own
        # __init__ imports the submodule back).
        while target and target not in known:
            target = target.rpartition(".")[0]
        if target and target != name:
            out.add(target)

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".") if package else []
                base = base[:len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            for alias in node.names:
                full = f"{module}.{alias.name}"
                add(full if full in known else module)
    return out


def import_graph(folder=None):
    known = modules(folder)
    return {name: imports(name, path, known) for name, path in known.items()}


def cycles(graph):
    """The strongly connected components of more than one module (Tarjan), and self-loops."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def top_level_names(path):
    """Names a module defines at its top level (def, class, assignment), not those it imports."""
    tree = ast.parse(path.read_text(), str(path))
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for leaf in ast.walk(target):
                    if isinstance(leaf, ast.Name):
                        names.add(leaf.id)
    return {n for n in names if not (n.startswith("__") and n.endswith("__"))}


def duplicates(folder=None):
    """{name: [modules]} of the top-level names defined in more than one module."""
    where = {}
    skip = installed()
    for name, path in modules(folder).items():
        if name in skip:
            continue
        for defined in top_level_names(path) - PER_MODULE:
            where.setdefault(defined, []).append(name)
    return {n: sorted(m) for n, m in sorted(where.items()) if len(m) > 1}


def entry_points():
    """The top-level scripts that run as commands (an `if __name__ == "__main__"` block)."""
    out = []
    for name, path in modules().items():
        if "." in name or path.name == "__init__.py" or name in NO_HELP:
            continue
        if '__name__ == "__main__"' in path.read_text():
            out.append(path)
    return out


class ScriptsPackage(unittest.TestCase):
    def test_no_import_cycle(self):
        found = cycles(import_graph())
        self.assertEqual(found, [], "import cycles among scripts/ modules: " +
                         "; ".join(" <-> ".join(c) for c in found))

    def test_no_name_defined_twice(self):
        found = duplicates()
        self.assertEqual(found, {}, "top-level names defined in several modules (define each "
                         "once, in tslib, and import it): " +
                         "; ".join(f"{n}: {', '.join(m)}" for n, m in found.items()))

    def test_entry_points_answer_help(self):
        points = entry_points()
        self.assertGreater(len(points), 5)
        env = dict(os.environ, MPLBACKEND="Agg")
        for path in points:
            with self.subTest(script=path.name):
                done = subprocess.run([sys.executable, str(path), "--help"], cwd=ROOT, env=env,
                                      capture_output=True, text=True, timeout=120, check=False)
                self.assertEqual(done.returncode, 0, f"{path.name} --help:\n{done.stderr}")
                self.assertIn("usage:", done.stdout, path.name)

    def test_guard_sees_a_cycle_and_a_duplicate(self):
        """The checks themselves, on a scripts folder of their own: a lazy import cycle between
        two scripts, one through a package's __init__, and helpers defined twice are found;
        a submodule importing its package and names merely imported are not reported."""
        with tempfile.TemporaryDirectory() as tmp:
            folder = pathlib.Path(tmp)
            (folder / "lib").mkdir()
            (folder / "lib/__init__.py").write_text("from lib import util\nROOT = 1\n")
            (folder / "lib/util.py").write_text("from lib import ROOT\nimport lib.util\n"
                                                "def fmt(x):\n    return x\n")
            (folder / "bench.py").write_text("from lib import ROOT\ndef main():\n"
                                             "    import bench_islands\n")
            (folder / "bench_islands.py").write_text("import bench\nfrom lib.util import fmt\n"
                                                     "def rel(a, b):\n    return a\n")
            (folder / "other.py").write_text("ROOT = 2\nfmt = str\nrel = 3\ndef main():\n"
                                             "    pass\n")
            self.assertEqual(cycles(import_graph(folder)),
                             [["bench", "bench_islands"], ["lib", "lib.util"]])
            self.assertEqual(duplicates(folder), {"ROOT": ["lib", "other"],
                                                  "fmt": ["lib.util", "other"],
                                                  "rel": ["bench_islands", "other"]})
        self.assertEqual(cycles({"a": {"b"}, "b": set()}), [])


if __name__ == "__main__":
    unittest.main()
