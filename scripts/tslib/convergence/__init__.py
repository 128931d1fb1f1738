"""The mode convergence study (scripts/convergence_table.py): the runs and levels (study), the
tables and pages (docs) and the command line (cli)."""
