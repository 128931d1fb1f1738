"""Numbers for tables and checks: the formats of the scripts' tables and the relative
differences they report (one definition each; the scripts import them from here)."""
import math

RADPS_PER_RPM = math.pi / 30.0  # rad/s per rpm


def fmt(x, digits=2, none="–"):
    """x with `digits` significant digits, in exponent form outside [1e-3, 1e4); integers as
    they are, 0 as "0", None as `none` (the benchmark's tables)."""
    if x is None:
        return none
    if isinstance(x, int):
        return str(x)
    if x == 0:
        return "0"
    return f"{x:.{digits}g}" if 1e-3 <= abs(x) < 1e4 else f"{x:.{digits - 1}e}"


def fmt4(value):
    """A float with four significant digits ("%.4g"), anything else as str() (the sweep reports)."""
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def fmt3(value):
    """value with three significant digits ("%.3g"), NaN as "-" (the tooth comparison)."""
    if isinstance(value, float) and math.isnan(value):
        return "-"
    return f"{value:.3g}"


def fmt3_range(pair):
    """A range "lo-hi" of two values in fmt3's form."""
    return f"{fmt3(pair[0])}-{fmt3(pair[1])}"


def rel_error(a, b):
    """Relative error of a against the reference b: |a - b| / |b| (absolute when b is 0)."""
    return abs(a - b) / abs(b) if b != 0 else abs(a - b)


def rel_change(a, b):
    """Relative change from a to b: |b - a| / |a| (|a| floored at 1e-12)."""
    return abs(b - a) / max(abs(a), 1e-12)


def exit_velocity_error(run, ref):
    """Largest exit velocity difference over the kernels of two runs (their "kernels" lists with
    "velocity_mps"), relative to the reference kernel's speed."""
    worst = 0.0
    for k, kr in zip(run["kernels"], ref["kernels"]):
        dv = math.hypot(k["velocity_mps"][0] - kr["velocity_mps"][0],
                        k["velocity_mps"][1] - kr["velocity_mps"][1])
        worst = max(worst, dv / max(math.hypot(*kr["velocity_mps"]), 1e-12))
    return worst
