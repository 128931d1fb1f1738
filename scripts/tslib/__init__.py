"""The scripts' shared library: binary lookup (binaries), runs and caching (cache), markdown
splicing and the page of every regenerated section (markdown), plots (plots).

Entry points import it as `tslib` with scripts/ on sys.path (a script in scripts/ has it there).
"""
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent  # the repository
