"""Plots: matplotlib without a display (the Agg backend, chosen before pyplot is imported)."""


def pyplot():
    """matplotlib.pyplot on the Agg backend (PNG files, no display needed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt
