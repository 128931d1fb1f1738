#!/usr/bin/python3
"""Replaces the text between `<!-- NAME -->` and `<!-- NAME-end -->` in a markdown file with
standard input (optionally inside a code fence), so that a command's output is the README's text.

Usage: some_command | scripts/readme_section.py NAME [--file README.md] [--fence LANG]
Exit status 2 if the markers are missing.
"""
import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("name")
    ap.add_argument("--file", default=os.path.join(ROOT, "README.md"))
    ap.add_argument("--fence", default=None, help="wrap the text in a ``` fence with this tag")
    args = ap.parse_args()
    body = sys.stdin.read().rstrip("\n")
    if args.fence is not None:
        body = f"```{args.fence}\n{body}\n```"
    begin, end = f"<!-- {args.name} -->", f"<!-- {args.name}-end -->"
    with open(args.file) as f:
        text = f.read()
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        print(f"readme_section.py: markers {begin} ... {end} not found in {args.file}",
              file=sys.stderr)
        sys.exit(2)
    text = text[:i + len(begin)] + "\n" + body + "\n" + text[j:]
    with open(args.file, "w") as f:
        f.write(text)


if __name__ == "__main__":
    main()
