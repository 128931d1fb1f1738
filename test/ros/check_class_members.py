#!/usr/bin/env python3
"""Guard: no class or struct of the ROS layer (src/ros, include/threshing_sim/ros) holds more
than --max data members (issue 24: the node as small parts, none over ~30 members).

Counts the non-static data members declared directly in each class body (nested classes are
counted on their own; `std::atomic<long> a{0}, b{0};` is two members). Prints a table, writes a
JUnit file with --xml, exits 1 when a class is over the limit or no class was found.
--self-test checks the counter on tricky declarations and that an oversized class fails.
"""
import argparse
import os
import re
import sys
import xml.sax.saxutils as su

DEFAULT_MAX = 30


def strip_comments_and_strings(text):
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r'"(\\.|[^"\\])*"', '""', text)
    text = re.sub(r"'(\\.|[^'\\])*'", "''", text)
    return "\n".join(l for l in text.split("\n") if not l.lstrip().startswith("#"))


def matching(text, i, open_ch="{", close_ch="}"):
    """Index just past the bracket matching text[i]."""
    depth = 0
    for j in range(i, len(text)):
        if text[j] == open_ch:
            depth += 1
        elif text[j] == close_ch:
            depth -= 1
            if depth == 0:
                return j + 1
    raise ValueError("unbalanced %s at %d" % (open_ch, i))


def without_templates(s):
    prev = None
    while prev != s:
        prev = s
        s = re.sub(r"<[^<>;{}()]*>", "", s)
        s = re.sub(r"<[^<>;{}]*>", "", s)
    return s


def statements(body):
    """Member declarations of a class body at its own level: (text, kind) with kind 'decl' or
    'function' (a body-defined function)."""
    out, cur, i = [], "", 0
    while i < len(body):
        ch = body[i]
        if ch == "{":
            end = matching(body, i)
            head = cur.strip()
            if re.search(r"\)\s*(const|override|final|noexcept|\s)*$", head) or re.search(
                    r"\)\s*:\s*.*$", head, flags=re.S):
                out.append((head, "function"))
                cur = ""
            elif re.match(r"^(template\s*<.*>\s*)?(class|struct|union|enum)\b", head, flags=re.S):
                cur = cur + " NESTED "  # a nested type (counted on its own); ends at its ';'
            else:
                cur += " "  # a brace initializer
            i = end
            continue
        if ch == ";":
            out.append((cur.strip(), "decl"))
            cur = ""
        else:
            cur += ch
        i += 1
    return out


def count_members(body):
    n = 0
    for text, kind in statements(body):
        text = re.sub(r"^\s*(public|private|protected)\s*:", "", text.strip()).strip()
        while re.match(r"^(public|private|protected)\s*:", text):
            text = re.sub(r"^(public|private|protected)\s*:", "", text).strip()
        if kind == "function" or not text:
            continue
        if re.match(r"^(using|typedef|friend|static_assert|template|static|enum|class|struct|"
                    r"union)\b", text) or "NESTED" in text:
            continue
        flat = without_templates(text)
        head = flat.split("=", 1)[0]
        if "(" in head or "operator" in head:
            continue  # a function declaration
        depth, commas = 0, 0
        for ch in flat:
            if ch in "([":
                depth += 1
            elif ch in ")]":
                depth -= 1
            elif ch == "," and depth == 0:
                commas += 1
        n += commas + 1
    return n


def classes(text):
    """(name, member count) of every class/struct defined in text, nested ones included."""
    text = strip_comments_and_strings(text)
    found = []
    for m in re.finditer(r"\b(class|struct)\s+(\w+)\s*(final\s*)?(:[^;{}()]*)?\{", text):
        if re.search(r"\benum\s*$", text[:m.start()]):
            continue
        start = m.end() - 1
        body = text[start + 1:matching(text, start) - 1]
        found.append((m.group(2), count_members(body)))
    return found


def scan(root):
    rows = []
    for d in ("src/ros", "include/threshing_sim/ros"):
        for name in sorted(os.listdir(os.path.join(root, d))):
            if name.endswith((".h", ".cc")):
                path = os.path.join(d, name)
                with open(os.path.join(root, path)) as f:
                    for cls, n in classes(f.read()):
                        rows.append((path, cls, n))
    return rows


SELF_TEST = """
class A {
 public:
  A(int x) : x_(x) {}
  void f() const { if (x_) { g(); } }
  template <typename T> void h(T t) { t(); }
  static constexpr int kLimit = 3;
  using Map = std::map<int, int>;
  std::atomic<bool> a{false}, b{false};  // two
  std::function<void(const int&)> cb;    // one (parens inside a template)
  double arr[3] = {0, 0, 0};
  std::map<std::pair<int, int>, Vec2> m;
  Meter meter_{clock_};
  struct Inner { int p, q; long r = 0; };
  Inner inner;
  enum Kind : int { kX = 0, kY = 1 };
  bool operator==(const A& o) const;
 private:
  int x_ = 0;
};
"""


def self_test():
    got = dict(classes(SELF_TEST))
    ok = got == {"A": 8, "Inner": 3}
    big = "struct Big {\n" + "".join("  int m%d = 0;\n" % i for i in range(31)) + "};\n"
    ok = ok and dict(classes(big)) == {"Big": 31}
    print("self-test: %s (A: %s, Inner: %s)" % ("ok" if ok else "FAILED", got.get("A"),
                                               got.get("Inner")))
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(__file__), "..", ".."))
    ap.add_argument("--max", type=int, default=DEFAULT_MAX)
    ap.add_argument("--xml", help="write a JUnit result here")
    ap.add_argument("--self-test", action="store_true")
    args = ap.parse_args()
    failures = []
    if not self_test():
        failures.append("the member counter's self-test failed")
    if not args.self_test:
        rows = scan(args.root)
        if not rows:
            failures.append("no class found under src/ros or include/threshing_sim/ros")
        for path, cls, n in sorted(rows, key=lambda r: -r[2]):
            over = n > args.max
            print("%-45s %-22s %3d%s" % (path, cls, n, "  OVER %d" % args.max if over else ""))
            if over:
                failures.append("%s: class %s has %d data members (at most %d)" %
                                (path, cls, n, args.max))
    for f in failures:
        print("FAIL: " + f, file=sys.stderr)
    if args.xml:
        os.makedirs(os.path.dirname(os.path.abspath(args.xml)), exist_ok=True)
        with open(args.xml, "w") as out:
            out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
            out.write('<testsuite name="class_members" tests="1" failures="%d" errors="0">\n'
                      % (1 if failures else 0))
            out.write('  <testcase classname="class_members" name="at_most_%d_members">'
                      % args.max)
            if failures:
                out.write('<failure message="%s"/>' % su.escape("; ".join(failures), {'"': "&quot;"}))
            out.write("</testcase>\n</testsuite>\n")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
