"""The tooth comparison (scripts/compare_teeth.py): cases and runs (cases), numbers (analysis),
plots (plots), the report (report), the findings page (findings), the findings section of
docs/threshing_findings.md (summary) and the command line (cli)."""
