"""The long versions of the hard cases (scripts/stability_table.py): scenes, checks and bounds
(scenes), runs and their properties (runs), the pages (page) and the command line (cli)."""
