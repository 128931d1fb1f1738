"""Markdown splicing: the regenerated sections between `<!-- name -->` and `<!-- name-end -->`,
and which page of the repository holds each of them."""
import os
import pathlib

from tslib import ROOT

# Every regenerated section and the page that holds it (relative to the repository root). The
# scripts splice into these pages; scripts/check_doc_refs.py checks that each marker is there.
SECTIONS = {
    "default-timing": "README.md",          # scripts/time_default_scene.py
    "default-output": "README.md",          # simulate config/default_scene.yaml
    "sweep-overhead-readme": "README.md",   # scripts/sweep_overhead.py --docs
    "node-rtf": "docs/ros_interface.md",    # scripts/measure_node_rtf.sh
    "record-recipe": "docs/ros_interface.md",  # hand-written; test_recipe runs it
    "scene-reference": "docs/scene_reference.md",  # scripts/scene_reference.sh
    "profile": "docs/performance.md",       # scripts/profile_core.sh
    "profile-streams": "docs/performance.md",  # scripts/profile_core.sh --streams
    "free-teeth": "docs/performance.md",    # scripts/compare_free_teeth.py --callgrind
    "modal-split": "docs/performance.md",   # scripts/compare_modal_split.py --callgrind
    "islands-table": "docs/architecture.md",  # scripts/bench.py --part islands
    "stage-profile": "docs/bench_islands.md",  # scripts/stage_profile.py --docs
    # scripts/stage_profile.py --docs --section stage-profile-before --simulate <main's build>
    "stage-profile-before": "docs/bench_islands.md",
    # hand-written studies (issue 26's idle kernels), kept by scripts/bench.py --part islands
    "islands-studies": "docs/bench_islands.md",
    "bench-table": "docs/benchmarks.md",    # scripts/bench.py
    "scaling-table": "docs/benchmarks.md",  # scripts/bench.py
    "stability-table": "docs/numerical_stability.md",  # scripts/stability_table.py
    "stability-full": "docs/numerical_stability.md",   # scripts/stability_table.py --full
    "findings": "docs/threshing_findings.md",  # scripts/compare_teeth.py --findings
    "convergence": "README.md",             # scripts/convergence_table.py
    "correction-table": "docs/convergence.md",  # scripts/correction_table.py --docs
    # scripts/sweep report out/sweeps/stream_statistics --stream-docs docs/convergence.md
    "stream-statistics": "docs/convergence.md",
    "sweep-overhead": "docs/sweeps.md",     # scripts/sweep_overhead.py --docs
    "contact-phase-accuracy": "docs/contact_phase.md",  # scripts/contact_phase_table.py --docs
    "contact-phase-cost": "docs/contact_phase.md",      # scripts/contact_phase_table.py --docs
    "scene-loading": "docs/scene_loading.md",  # scripts/loading_profile.py --docs
}


def page_of(name):
    """The path of the page that holds section name."""
    if name not in SECTIONS:
        raise SystemExit(f"unknown section '{name}' (known: {', '.join(sorted(SECTIONS))})")
    return ROOT / SECTIONS[name]


def markers(name):
    return f"<!-- {name} -->", f"<!-- {name}-end -->"


def splice_text(text, name, body, where="the text"):
    """text with the lines between section name's markers replaced by body."""
    begin, end = markers(name)
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        raise SystemExit(f"{where}: no {begin} ... {end} markers")
    return text[:i + len(begin)] + "\n" + body.rstrip() + "\n" + text[j:]


def section_body(text, name):
    """The lines between section name's markers in text, or None when it has no markers."""
    begin, end = markers(name)
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        return None
    return text[i + len(begin):j].strip("\n")


def splice(name, body, path=None):
    """Replaces section name of its page (or of path) with body; returns the page's path."""
    path = pathlib.Path(path) if path else page_of(name)
    path.write_text(splice_text(path.read_text(), name, body, where=str(path)))
    return path


def link(target, page):
    """A link from page to target (both paths): relative to the page's folder."""
    return os.path.relpath(pathlib.Path(target).resolve(), pathlib.Path(page).resolve().parent)


def in_folder(folder, name):
    """name inside folder, as a link ("findings.md" where folder is ".")."""
    return name if folder == "." else f"{folder}/{name}"
