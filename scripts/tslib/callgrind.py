"""Reading callgrind output files."""
import re


def total_instructions(path):
    """The total instruction count (Ir) of a callgrind output file, or None if it has none."""
    with open(path) as f:
        for line in f:
            m = re.match(r"(?:summary|totals):\s+(\d+)", line)
            if m:
                return int(m.group(1))
    return None
