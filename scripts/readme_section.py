#!/usr/bin/python3
"""Replaces the text between `<!-- NAME -->` and `<!-- NAME-end -->` with standard input
(optionally inside a code fence), so that a command's output is the text of a page. The page is
the one that holds section NAME (scripts/tslib/markdown.py, SECTIONS), or --file.

Usage: some_command | scripts/readme_section.py NAME [--file PAGE.md] [--fence LANG]
Exit status 2 if the markers are missing.
"""
import argparse
import sys

from tslib import markdown


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("name")
    ap.add_argument("--file", help="the page (default: the section's page)")
    ap.add_argument("--fence", default=None, help="wrap the text in a ``` fence with this tag")
    args = ap.parse_args()
    body = sys.stdin.read().rstrip("\n")
    if args.fence is not None:
        body = f"```{args.fence}\n{body}\n```"
    try:
        markdown.splice(args.name, body, args.file)
    except SystemExit as e:
        print(f"readme_section.py: {e}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
