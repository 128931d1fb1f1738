"""Generated scenes of the benchmark: the stream scene's kernels for any count (in reach,
idle, hanging at rest or sparse) as override files."""
import math
import pathlib

from tslib import BENCH_DIR


# ------------------------------------------------------------------------------------------
# The stream scene's kernels.

STREAM_PITCH_RAD = 0.04                       # angle between two columns of kernels
STREAM_ROWS_M = [0.195, 0.180, 0.235, 0.250, 0.265, 0.280, 0.295]  # row radii, reachable first
# The idle variant (scaling only): every row beyond the teeth's reach and the grate, so that no
# pair can touch and the cost of the kernels themselves shows.
IDLE_ROWS_M = [0.235, 0.250, 0.265, 0.280, 0.295, 0.310, 0.325]
STREAM_FIRST_OFFSET = 1                       # first column this many pitches ahead of a tooth


# Rows added beyond the last one, this far apart, when a count needs more than the lattice's
# seven rows (the 10 000-kernel scaling points).
STREAM_EXTRA_ROW_PITCH_M = 0.015
# The kernels' pedicel (stream and idle layouts): stiffness [N/m], damping [N s/m], detachment
# force [N], stem length [m]; kernel mass [kg] and long semi-axis [m].
PEDICEL_K, PEDICEL_C, PEDICEL_BREAK, PEDICEL_LENGTH = 1600.0, 0.002, 1.6, 0.003
KERNEL_MASS, KERNEL_A = 2.8e-5, 5.0e-3


def lattice(count, rows, scene=BENCH_DIR / "stream.yaml"):
    """Lattice points (angle about the drum axis, row radius) of the stream scene for `count`
    kernels: columns filled quadrant by quadrant, column o of quadrant q (o + 1) pitches ahead of
    tooth q in the direction of rotation; each column takes the rows in order (reachable
    first), with rows added beyond the last one when the count needs them."""
    import yaml  # python3-yaml, a dependency of the ROS python tools
    with open(scene) as f:
        tree = yaml.safe_load(f)
    drum_angle = tree["drum"]["angle"]
    mounts = [t["mount_angle"] for t in tree["teeth"]]
    quadrant = 2 * math.pi / len(mounts)
    per_quadrant = int(quadrant / STREAM_PITCH_RAD) - STREAM_FIRST_OFFSET
    rows = list(rows)
    while per_quadrant * len(mounts) * len(rows) < count:
        rows.append(rows[-1] + STREAM_EXTRA_ROW_PITCH_M)
    points = []
    for j in range(count):
        # Row-major within a column group, so that the first rows fill first.
        column, row = divmod(j, len(rows)) if len(rows) == len(STREAM_ROWS_M) else (
            j % (per_quadrant * len(mounts)), j // (per_quadrant * len(mounts)))
        offset, q = divmod(column, len(mounts))
        phi = drum_angle + mounts[q] + (offset + STREAM_FIRST_OFFSET) * STREAM_PITCH_RAD
        points.append((phi, rows[row]))
    return points


def stream_kernels(count, rows=STREAM_ROWS_M, scene=BENCH_DIR / "stream.yaml"):
    """The kernel list of the stream scene for `count` kernels, as YAML flow mappings: each
    kernel radial, its pedicel 3 mm beyond its outer end, unstretched (so each starts to swing
    and fall under gravity)."""
    kernels = []
    for phi, r in lattice(count, rows, scene):
        e = (math.cos(phi), math.sin(phi))
        anchor = r + KERNEL_A + PEDICEL_LENGTH
        kernels.append(
            f"{{position: [{r * e[0]:.6f}, {r * e[1]:.6f}], angle: {phi:.6f}, "
            f"semi_axes: [5.0e-3, 1.3e-3], mass: 2.8e-5, youngs_modulus: 2.81e8, "
            f"poisson_ratio: 0.30, pedicel: {{anchor: [{anchor * e[0]:.6f}, {anchor * e[1]:.6f}], "
            f"attach_point: [5.0e-3, 0.0], stiffness: 1600.0, damping: 0.002, rest_length: -1, "
            f"detachment_force: 1.6}}}}")
    return kernels


# Anchors of kernels hanging at rest: a rectangular grid (8 mm across, 16 mm down, so that a
# kernel hanging 13 mm below its anchor clears the next row) from this radius outwards.
HANG_PITCH_M = (0.008, 0.016)
HANG_MIN_RADIUS_M = 0.235


def hanging_anchors(count):
    """The `count` grid anchors nearest the drum axis beyond HANG_MIN_RADIUS_M, nearest first."""
    px, py = HANG_PITCH_M
    reach = HANG_MIN_RADIUS_M
    while True:
        nx, ny = int(reach / px) + 1, int(reach / py) + 1
        points = [(i * px, j * py) for i in range(-nx, nx + 1) for j in range(-ny, ny + 1)]
        points = [p for p in points if HANG_MIN_RADIUS_M <= math.hypot(*p) <= reach]
        if len(points) >= count:
            points.sort(key=lambda p: (round(math.hypot(*p), 9), math.atan2(p[1], p[0])))
            return points[:count]
        reach += 0.05


def hanging_kernels(count):
    """Kernels at rest out of the teeth's reach: each hangs straight down from its anchor at its
    static equilibrium, the stem stretched by m g / k, so that nothing moves until struck."""
    import yaml
    with open(BENCH_DIR / "stream.yaml") as f:
        gravity = -yaml.safe_load(f)["gravity"][1]  # the scene's [m/s^2]
    kernels = []
    stem = PEDICEL_LENGTH + KERNEL_MASS * gravity / PEDICEL_K
    for ax, ay in hanging_anchors(count):
        kernels.append(
            f"{{position: [{ax!r}, {ay - stem - KERNEL_A!r}], angle: {math.pi / 2!r}, "
            f"semi_axes: [5.0e-3, 1.3e-3], mass: 2.8e-5, youngs_modulus: 2.81e8, "
            f"poisson_ratio: 0.30, pedicel: {{anchor: [{ax!r}, {ay!r}], "
            f"attach_point: [5.0e-3, 0.0], stiffness: 1600.0, damping: 0.002, "
            f"rest_length: {PEDICEL_LENGTH!r}, detachment_force: 1.6}}}}")
    return kernels


def stream_override_text(count, idle=False):
    """idle: False (the stream), "swinging" (out of reach, unstretched: they swing and fall),
    "rest" or True (out of reach, hanging at rest), or ("sparse", n): n live kernels of the
    stream and count - n at rest out of reach."""
    if idle is True:
        idle = "rest"
    if isinstance(idle, tuple):
        live = stream_kernels(idle[1], STREAM_ROWS_M[:2])  # the two rows in the teeth's reach
        kernels = live + hanging_kernels(count)[idle[1]:]
        what = f", {idle[1]} in reach and the rest hanging at rest out of reach"
        flag = f" --sparse {idle[1]}"
    elif idle == "swinging":
        kernels, what, flag = stream_kernels(count, IDLE_ROWS_M), ", all out of reach", " --idle swinging"
    elif idle == "rest":
        kernels, what, flag = hanging_kernels(count), ", all out of reach, hanging at rest", " --idle"
    else:
        kernels, what, flag = stream_kernels(count), "", ""
    return (f"# Kernels of config/bench/stream.yaml for N = {count}{what} "
            f"(scripts/bench.py --stream-kernels {count}{flag}).\n"
            "kernels: [\n  " + ",\n  ".join(kernels) + "]\n")


def stream_override_file(count, folder, idle=False):
    tag = ("_sparse%d" % idle[1]) if isinstance(idle, tuple) else (
        "" if not idle else "_idle" if idle in (True, "rest") else "_" + str(idle))
    path = pathlib.Path(folder) / f"stream_kernels_{count}{tag}.yaml"
    text = stream_override_text(count, idle)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path
