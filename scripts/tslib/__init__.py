"""The scripts' shared library: binary lookup (binaries), runs and caching (cache), markdown
splicing and the page of every regenerated section (markdown), plots (plots), the scene schema
of simulate --print-schema (schema), table formats and relative differences (numbers); the
benchmark (bench), the tooth comparison (teeth), the convergence study (convergence), the
static correction study (correction) and the stability table (stability), each behind a thin
entry point of scripts/ with the same options.
The paths of the repository are here (ROOT and its folders).

Entry points import it as `tslib` with scripts/ on sys.path (a script in scripts/ has it there).
"""
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent  # the repository
CONFIG = ROOT / "config"
SCENE_DIR = CONFIG / "scenes"   # the scenes (config/scenes/*.yaml, cases/, teeth/)
BENCH_DIR = CONFIG / "bench"    # the benchmark's scenes
DOCS = ROOT / "docs"
