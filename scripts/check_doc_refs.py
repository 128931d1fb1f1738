#!/usr/bin/python3
"""Checks that every reference to a document of the repository resolves.

Scanned: code, tests, scripts, launch files, messages, configuration, README.md and docs/*.md
(not the fuzzing corpora, which are inputs). A reference is

- a path to a document: `docs/NAME.md` (or .png, .csv, ...), or a bare `NAME.md` naming a page
  (it must be a file of docs/ or of the repository root, or a known generated output);
- a section cited by name: `README "Heading"`, `docs/x.md, "Heading"`, `docs/x.md ("Heading")`
  (the page must have a heading that starts with that text);
- a section of the model: `§N` (docs/model.md must have a heading `§N.`; a file that writes §
  must name docs/model.md somewhere, so that a reader knows what § is);
- in README.md and docs/*.md, every relative markdown link `[text](path#anchor)` outside code
  fences: the path must exist and the anchor must be a heading of the target page;
- in README.md and docs/*.md, every `<!-- name -->` marker of a regenerated section must have its
  `<!-- name-end -->`, and every section of scripts/tslib/markdown.py's SECTIONS (where the
  scripts splice it) must be on its page.

Prints one line per dangling reference (file:line: what) and exits 1 if there is any, else
prints a count and exits 0. `--self-test` builds a small tree with one dangling reference of
each kind and checks that each is reported (and that the clean tree passes).
"""
import argparse
import pathlib
import re
import sys
import tempfile

from tslib import ROOT
SCANNED_DIRS = ["src", "include", "test", "bench", "scripts", "launch", "msg", "srv", "cfg",
                "config", "rviz", ".ci", "docs"]
SCANNED_ROOT_FILES = ["README.md", "CMakeLists.txt", "package.xml"]
SKIPPED_PARTS = {"corpus", "__pycache__"}
SELF = pathlib.Path(__file__).name  # its own examples of dangling references
TEXT_SUFFIXES = {".cc", ".h", ".hpp", ".cpp", ".py", ".sh", ".launch", ".test", ".xml", ".msg",
                 ".srv", ".cfg", ".yaml", ".yml", ".md", ".txt", ".rviz", ""}
# Bare page names that are outputs of the scripts, not files of the repository.
GENERATED_NAMES = {"report.md"}

PATH_RE = re.compile(r"(?<![\w./-])(docs/[A-Za-z0-9_./-]*[A-Za-z0-9_])")
BARE_MD_RE = re.compile(r"(?<![\w./-])([A-Za-z0-9_-]+\.md)\b")
CITED_RE = re.compile(r"(?<![\w./-])((?:docs/)?[A-Za-z0-9_-]+\.md|README)`?\]?(?:\([^)\s]*\))?,? "
                      r"\(?((?:\"[^\"\n]+\"(?:, )?)+)")
SECTION_RE = re.compile(r"§(\d+[a-z]?)(?:-(\d+[a-z]?))?")
LINK_RE = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def headings(path):
    """The headings of a markdown file (outside code fences), as written."""
    out, fence = [], False
    for line in path.read_text(encoding="utf-8").split("\n"):
        if line.startswith("```"):
            fence = not fence
        elif not fence and re.match(r"#{1,6} ", line):
            out.append(line.lstrip("#").strip())
    return out


def anchors(path):
    seen, out = {}, set()
    for h in headings(path):
        s = slug(h)
        n = seen.get(s, 0)
        seen[s] = n + 1
        out.add(s if n == 0 else f"{s}-{n}")
    return out


def scanned_files(root):
    files = [root / name for name in SCANNED_ROOT_FILES if (root / name).is_file()]
    for d in SCANNED_DIRS:
        for p in sorted((root / d).rglob("*")) if (root / d).is_dir() else []:
            if (p.is_file() and p.suffix in TEXT_SUFFIXES and p.name != SELF
                    and not SKIPPED_PARTS.intersection(p.relative_to(root).parts)):
                files.append(p)
    return files


class Checker:
    def __init__(self, root):
        self.root = root
        self.problems = []
        self.references = 0
        model = root / "docs/model.md"
        self.sections = set()
        if model.is_file():
            for h in headings(model):
                m = re.match(r"§(\w+)\.", h)
                if m:
                    self.sections.add(m.group(1))

    def bad(self, path, line, what):
        self.problems.append(f"{path.relative_to(self.root)}:{line}: {what}")

    def page(self, name, source):
        """The file a cited page name means, or None."""
        if name == "README":
            name = "README.md"
        for base in (self.root, self.root / "docs", source.parent):
            if (base / name).is_file():
                return base / name
        return None

    def check_file(self, path):
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            return
        markdown = path.suffix == ".md" and (path.parent == self.root / "docs"
                                             or path == self.root / "README.md")
        if "§" in text and "model.md" not in text and path != self.root / "docs/model.md":
            self.bad(path, 1, "uses § but never names docs/model.md")
        fence = False
        for number, line in enumerate(text.split("\n"), 1):
            if line.startswith("```"):
                fence = not fence
            self.check_paths(path, number, line)
            self.check_cited(path, number, line)
            self.check_sections(path, number, line)
            if markdown and not fence:
                self.check_links(path, number, line)
        if markdown:
            self.check_markers(path, text)

    def check_paths(self, path, number, line):
        for m in PATH_RE.finditer(line):
            target = m.group(1).rstrip(".")
            if line[m.end():m.end() + 1] in ("{", "*", "<"):
                continue  # a pattern or a formatted name, not a path
            self.references += 1
            if not (self.root / target).exists():
                self.bad(path, number, f"no such file: {target}")
        for m in BARE_MD_RE.finditer(LINK_RE.sub("", line)):
            name = m.group(1)
            if name in GENERATED_NAMES or (name[:-3].isupper() and name != "README.md"):
                continue  # an output of a script, or a placeholder such as PAGE.md
            self.references += 1
            if self.page(name, path) is None:
                self.bad(path, number, f"no such page: {name}")

    def check_cited(self, path, number, line):
        for m in CITED_RE.finditer(line):
            target = self.page(m.group(1), path)
            if target is None:
                continue  # reported by check_paths
            titles = headings(target)
            for name in re.findall(r"\"([^\"\n]+)\"", m.group(2)):
                if name.startswith("§"):
                    continue
                self.references += 1
                if not any(t == name or t.startswith(name) for t in titles):
                    self.bad(path, number, f"{m.group(1)} has no section \"{name}\"")

    def check_sections(self, path, number, line):
        for m in SECTION_RE.finditer(line):
            for s in m.groups():
                if s is None:
                    continue
                self.references += 1
                if s not in self.sections:
                    self.bad(path, number, f"docs/model.md has no §{s}")

    def check_links(self, path, number, line):
        for m in LINK_RE.finditer(line):
            link = m.group(1)
            if re.match(r"[a-z]+:", link):
                continue
            self.references += 1
            file_part, _, anchor = link.partition("#")
            target = (path.parent / file_part).resolve() if file_part else path
            if not target.exists():
                self.bad(path, number, f"broken link: {link}")
            elif anchor and target.suffix == ".md" and anchor not in anchors(target):
                self.bad(path, number, f"no anchor #{anchor} in {target.name}")

    def check_markers(self, path, text):
        text = re.sub(r"`[^`\n]*`", "", text)  # markers quoted as code are not markers
        names = set(re.findall(r"<!-- ([a-z0-9-]+)(?: -->|:)", text))
        for name in sorted(n for n in names if not n.endswith("-end")):
            self.references += 1
            if f"<!-- {name}-end" not in text:
                self.bad(path, 1, f"marker <!-- {name} --> has no <!-- {name}-end -->")

    def check_section_pages(self):
        """Each regenerated section is on the page the scripts splice it into."""
        from tslib import markdown  # scripts/tslib
        for name, page in markdown.SECTIONS.items():
            self.references += 1
            path = self.root / page
            text = path.read_text(encoding="utf-8") if path.is_file() else ""
            begin, end = markdown.markers(name)
            if not (begin in text or f"<!-- {name}:" in text) or end not in text:
                self.bad(self.root / "scripts/tslib/markdown.py", 1,
                         f"section {name} is not on its page {page}")

    def run(self, sections=False):
        for path in scanned_files(self.root):
            self.check_file(path)
        if sections:
            self.check_section_pages()
        return self.problems


def self_test():
    """A clean tree passes; each kind of dangling reference is reported."""
    clean = {
        "README.md": "# t\n\n## Quick start\n\nSee [model](docs/model.md#2-frames) and "
                     "[x](docs/x.md).\n",
        "docs/model.md": "# Model\n\n## §2. Frames\n\n## §9a. Laws\n",
        "docs/x.md": "# X\n\n<!-- t -->\n1\n<!-- t-end -->\n\n## Part one\n",
        "src/a.cc": "// docs/model.md §2 and §9a; README \"Quick start\"; docs/x.md, \"Part one\"\n",
    }
    broken = {
        "src/b.cc": "// see docs/gone.md\n",
        "src/c.cc": "// docs/model.md §7\n",
        "src/d.cc": "// README \"No such part\"\n",
        "docs/y.md": "# Y\n\n[a](missing.md) and [b](x.md#nowhere)\n\n<!-- open -->\n",
        "config/e.yaml": "# values from physics.md\n",
        "config/f.yaml": "# values (§2), never saying of what\n",
    }
    expected = ["no such file: docs/gone.md", "docs/model.md has no §7",
                "README has no section \"No such part\"", "broken link: missing.md",
                "no anchor #nowhere in x.md", "marker <!-- open --> has no",
                "no such page: physics.md", "uses § but never names docs/model.md"]
    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        for name, text in clean.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_text(text)
        problems = Checker(root).run()
        if problems:
            print("self-test: the clean tree was refused:\n" + "\n".join(problems))
            return 1
        for name, text in broken.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_text(text)
        problems = Checker(root).run()
    missed = [e for e in expected if not any(e in p for p in problems)]
    if missed or len(problems) != len(expected):
        print("self-test: expected\n  " + "\n  ".join(expected) + "\ngot\n  " +
              "\n  ".join(problems))
        return 1
    print(f"self-test: {len(expected)} kinds of dangling reference reported, clean tree passes")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--root", default=str(ROOT), help="repository root (default: this one)")
    ap.add_argument("--self-test", action="store_true", help="check the checker")
    args = ap.parse_args()
    if args.self_test:
        return self_test()
    checker = Checker(pathlib.Path(args.root).resolve())
    problems = checker.run(sections=checker.root == ROOT)
    for p in problems:
        print(p)
    print(f"check_doc_refs: {checker.references} references, {len(problems)} dangling")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
