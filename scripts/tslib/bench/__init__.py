"""The work-precision benchmark (scripts/bench.py): settings (config), generated scenes
(scenes), cached run points (runner), measurements (measure), figures (plots), tables and pages
(tables), the island-local scheme's part (islands, stages) and the command line (cli).

The modules import downwards only: config <- scenes, runner <- measure <- plots, tables <-
islands (with stages) <- cli."""
