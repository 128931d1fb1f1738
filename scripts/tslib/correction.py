"""The static correction study of scripts/correction_table.py (docs/convergence.md, "Static
correction against the mode count"): the runs, the tables and the static estimates."""
import argparse
import csv
import json
import math
import pathlib
import re
import subprocess
import tempfile

from tslib import BENCH_DIR
from tslib.binaries import find_binary
from tslib import markdown

CORRECTION_MODES = [1, 2, 3, 4, 6, 8, 12, 16, 24]
CORRECTION_REF_MODES = 64
CORRECTION_TOLERANCE = 1e-9
CORRECTION_REF_TOLERANCE = 1e-10
SAMPLE_S = 1e-7     # force history interval near contacts [s]
WORSE_MARGIN = 1e-3  # "worse" only by more than this fraction of the reference

SOFT = ["--set", "teeth.*.youngs_modulus=8e6", "--set", "drum.speed=94.2478"]  # 8 MPa, 900 rpm
# (name, arguments, tooth (E [Pa], rho [kg/m^3], nu [-]) as the scene sets it)
CORRECTION_SCENES = [
    ("default strike (nylon)", [str(BENCH_DIR / "single_strike.yaml")], (3e9, 1140.0, 0.39)),
    ("polyurethane knead (5 MPa, 800 rpm)", [str(BENCH_DIR / "knead_polyurethane.yaml")],
     (5e6, 1200.0, 0.49)),
    ("soft knead (8 MPa, 900 rpm)", [str(BENCH_DIR / "knead_polyurethane.yaml")] + SOFT,
     (8e6, 1200.0, 0.49)),
    # The same knead without tooth-kernel friction: what the normal correction alone leaves.
    ("polyurethane knead, no tooth friction", [str(BENCH_DIR / "knead_polyurethane.yaml"),
                                               "--set", "contact.tooth_kernel.friction=0"],
     (5e6, 1200.0, 0.49)),
]
CORRECTION_METRICS = [("fn", "peak F_N"), ("ft", "peak F_T"), ("jn", "J_N"), ("jt", "J_T")]


def run_case(simulate, args, modes, correction, tolerance, work):
    """Peak forces [N] and tooth-kernel impulses [N s] of one run."""
    tag = f"{abs(hash(tuple(args))) % 10**8}_{modes}_{correction}_{tolerance:g}"
    summary, forces = work / f"{tag}.json", work / f"{tag}.csv"
    cmd = [str(simulate)] + args + [
        "--set", f"teeth.*.modes={modes}", "--set", f"teeth.*.static_correction={correction}",
        "--tolerance", repr(tolerance), "--summary", str(summary), "--forces", str(forces),
        "--sample-interval", repr(SAMPLE_S), "--quiet"]
    subprocess.run(cmd, check=True, capture_output=True)
    s = json.loads(summary.read_text())
    if s["status"] != "ok":
        raise SystemExit(" ".join(cmd) + ": " + s["status"])
    per = s["outcomes"]["per_kernel"]
    out = {"fn": max(k["peak_normal_force_N"] for k in per),
           "ft": max(k["peak_tangential_force_N"] for k in per),
           "tip": s["max_tip_deflection_ratio"], "wall": s["wall_time_s"]}
    out["jn"], out["jt"] = impulses(forces)
    return out


def impulses(path):
    """Trapezoidal normal and |tangential| impulse of the tooth-kernel rows [N s]."""
    last = {}
    jn = jt = 0.0
    with open(path) as f:
        for row in csv.DictReader(f):
            if row["kind"] != "tooth_kernel":
                continue
            key = (row["a"], row["b"])
            t, fn, ft = float(row["t_s"]), float(row["normal_force_N"]), \
                abs(float(row["tangential_force_N"]))
            if key in last:
                t0, fn0, ft0 = last[key]
                jn += 0.5 * (fn + fn0) * (t - t0)
                jt += 0.5 * (ft + ft0) * (t - t0)
            last[key] = (t, fn, ft)
    return jn, jt


def cantilever_root(i):
    """beta_i L of the clamped-free beam: cos(bL) cosh(bL) = -1 (Newton from the asymptote)."""
    b = [1.8751, 4.6941, 7.8548, 10.9955][i] if i < 4 else (2 * i + 1) * math.pi / 2
    for _ in range(50):
        f = math.cos(b) + 1 / math.cosh(b)
        df = -math.sin(b) - math.tanh(b) / math.cosh(b)
        b -= f / df
    return b


def mode_at(i, x_m, length_m, mass_kgpm):
    """Mass-normalised clamped-free mode i and its slope at x_m, in a form free of the
    cancellation of cosh - sigma sinh (good to beta L ~ 700)."""
    bl = cantilever_root(i)
    b, bx = bl / length_m, bl / length_m * x_m
    den = math.sinh(bl) + math.sin(bl)
    # cosh(bx) - sigma sinh(bx) = ((1 - sigma) e^bx + (1 + sigma) e^-bx) / 2, with
    # 1 - sigma = (sin bL - cos bL - e^-bL) / den and 1 + sigma = 2 - (1 - sigma)
    one_minus = (math.sin(bl) - math.cos(bl) - math.exp(-bl)) / den
    grow = one_minus * math.exp(bx - bl) * math.exp(bl) / 2 if bx < 700 else 0.0
    decay = (2 - one_minus) * math.exp(-bx) / 2
    sigma = 1 - one_minus
    c = 1 / math.sqrt(mass_kgpm * length_m)
    phi = c * (grow + decay - math.cos(bx) + sigma * math.sin(bx))
    dphi = c * b * (grow - decay + math.sin(bx) + sigma * math.cos(bx))
    return b, phi, dphi


def tip_residual(n, youngs_Pa=5e6, density=1200.0, length_m=0.06, diameter_m=0.01,
                 poisson=0.49, all_modes=200):
    """At rest, at the tip of the knead's tooth: the share of the static flexibility that n
    modes miss, (w under a force, Euler-Bernoulli; the surface point's turn under a couple,
    Euler-Bernoulli; the same with each mode's turn scaled by 1 / (1 + (E / kappa G)(I / A)
    beta^2) as the core's section_rotation: shear_corrected, against all_modes modes), and the
    flexibilities w/F = L^3/3EI [m/N] and w'/M of the shear-corrected sections [1/(N m)]."""
    area = math.pi * diameter_m ** 2 / 4
    ei = youngs_Pa * area * diameter_m ** 2 / 16
    mass = density * area  # per length [kg/m]
    kappa = 6 * (1 + poisson) / (7 + 6 * poisson)
    e_over_kg = 2 * (1 + poisson) / kappa
    ww = tt = 0.0
    tt_shear = []
    for i in range(all_modes):
        b, phi, dphi = mode_at(i, length_m, length_m, mass)
        k = b ** 4 * ei / mass  # omega^2
        shear = 1 / (1 + e_over_kg * diameter_m ** 2 / 16 * b * b)
        if i < n:
            ww += phi * phi / k
            tt += dphi * dphi / k
        tt_shear.append((shear * dphi) ** 2 / k)
    ww_exact, tt_exact = length_m ** 3 / (3 * ei), length_m / ei
    shear_all = sum(tt_shear)
    return (1 - ww / ww_exact, 1 - tt / tt_exact, 1 - sum(tt_shear[:n]) / shear_all,
            ww_exact, shear_all)


def hertz_compliance(force_N, youngs_Pa=5e6, poisson=0.49):
    """d(delta)/dF [m/N] of the knead's tooth flank on the paddy kernel's sharpest curvature
    (the core's shortestContactTime geometry) at force_N."""
    e_star = 1 / ((1 - poisson ** 2) / youngs_Pa + (1 - 0.3 ** 2) / 2.81e8)
    a, b, r_t = 5e-3, 1.3e-3, 5e-3
    k = 4 / 3 * e_star * math.sqrt(math.sqrt(b * b / a * r_t * b / (r_t + b)))
    return 2 / 3 * (force_N / k) ** (2 / 3) / force_N


def residual_lines():
    r_t = 0.005
    miss_ww, miss_tt, miss_shear, ww, tt_shear = tip_residual(6)
    return [f"Static compliance at the 5 MPa tooth's tip, at rest: w under a force L^3/3EI = "
            f"{ww:.3g} m/N, of which 6 modes miss {100 * miss_ww:.3f} %; the surface point's "
            f"turn under the friction couple, (d/2)^2 w'/M with the shear-corrected sections "
            f"(200 modes) = {r_t ** 2 * tt_shear:.3g} m/N, of which 6 modes miss "
            f"{100 * miss_shear:.2f} % ({miss_shear * r_t ** 2 * tt_shear:.2g} m/N; of the "
            f"Euler-Bernoulli turn, which the residual table holds, they miss "
            f"{100 * miss_tt:.1f} %); Hertz compliance of the tooth on the kernel at 30 N: "
            f"{hertz_compliance(30.0):.2g} m/N.", ""]


def contact_time(simulate, args):
    """The Hertz contact time estimate of `modes: auto` [s] (simulate --modes)."""
    text = subprocess.run([str(simulate)] + args + ["--set", "teeth.*.modes=auto", "--modes"],
                          capture_output=True, text=True, check=True).stdout
    return float(re.search(r"contact time estimate ([0-9.e+-]+) us", text).group(1)) * 1e-6


def remainder_estimate(n, t_c, force_N, youngs_Pa, density, poisson, length_m=0.06,
                       diameter_m=0.01, all_modes=200):
    """The truncated modes' dynamic remainder beyond the static correction, as `modes: auto`
    would estimate it from the impact: each truncated mode j follows a pulse of omega_c =
    pi / t_c with a relative error (omega_c / omega_j)^2 of its static flexibility at the tip,
    summed over j > n; normal: w under a force, over the Hertz compliance at force_N;
    tangential: the surface point's shear-corrected turn under the friction couple, over its
    value with all modes. At rest, Euler-Bernoulli frequencies."""
    area = math.pi * diameter_m ** 2 / 4
    ei = youngs_Pa * area * diameter_m ** 2 / 16
    mass = density * area
    kappa = 6 * (1 + poisson) / (7 + 6 * poisson)
    e_over_kg = 2 * (1 + poisson) / kappa
    r_t = diameter_m / 2
    omega_c = math.pi / t_c
    normal = turn = turn_all = 0.0
    for j in range(all_modes):
        b, phi, dphi = mode_at(j, length_m, length_m, mass)
        k = b ** 4 * ei / mass
        shear = 1 / (1 + e_over_kg * diameter_m ** 2 / 16 * b * b)
        f_turn = (r_t * shear * dphi) ** 2 / k
        turn_all += f_turn
        if j >= n:
            normal += omega_c ** 2 / k * phi * phi / k
            turn += omega_c ** 2 / k * f_turn
    return (normal / hertz_compliance(force_N, youngs_Pa, poisson), turn / turn_all)


def rel(x, ref):
    return (x - ref) / ref if ref else 0.0


def correction_tables(simulate, work):
    lines = []
    summary = []
    for name, args, tooth in CORRECTION_SCENES:
        ref = run_case(simulate, args, CORRECTION_REF_MODES, "on", CORRECTION_REF_TOLERANCE, work)
        lines += [f"**{name}**: reference {CORRECTION_REF_MODES} modes, tolerance "
                  f"{CORRECTION_REF_TOLERANCE:g}: "
                  f"peak F_N {ref['fn']:.4g} N, F_T {ref['ft']:.4g} N, J_N {ref['jn']:.4g} N s, "
                  f"J_T {ref['jt']:.4g} N s, tip deflection {ref['tip']:.3f} L", "",
                  "| modes | " + " | ".join(f"{label} off / on" for _, label in CORRECTION_METRICS)
                  + " |",
                  "|---|" + "---|" * len(CORRECTION_METRICS)]
        worse_at = {"peaks": [], "impulses": []}
        at6 = None
        for n in CORRECTION_MODES:
            off = run_case(simulate, args, n, "off", CORRECTION_TOLERANCE, work)
            on = run_case(simulate, args, n, "on", CORRECTION_TOLERANCE, work)
            at6 = on if n == 6 else at6
            cells = []
            for key, _ in CORRECTION_METRICS:
                if ref[key] == 0:
                    cells.append("-")
                    continue
                e_off, e_on = rel(off[key], ref[key]), rel(on[key], ref[key])
                worse = abs(e_on) > abs(e_off) + WORSE_MARGIN
                if worse:
                    worse_at["peaks" if key in ("fn", "ft") else "impulses"].append(n)
                cells.append(f"{100 * e_off:+.1f} / {100 * e_on:+.1f}{' *' if worse else ''}")
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
        t_c = contact_time(simulate, args)
        est = {n: remainder_estimate(n, t_c, ref["fn"], *tooth) for n in (6, 12)}
        lines += ["", f"A-priori remainder of the truncated modes at the impact's contact time "
                  f"({1e6 * t_c:.0f} us, `simulate --modes`), normal / tangential: "
                  + "; ".join(f"{n} modes {100 * e[0]:.2g} % / {100 * e[1]:.2g} %"
                              for n, e in est.items()) + ".", ""]

        def worst6(keys):
            return 100 * max(abs(rel(at6[k], ref[k])) for k in keys if ref[k] > 0)

        def listed(counts):
            return ", ".join(map(str, sorted(set(counts)))) or "no"

        summary.append(f"- {name}: 6 modes with the correction within {worst6(('fn', 'ft')):.1f} % "
                       f"of the reference peaks ({worst6(('jn', 'jt')):.1f} % of the impulses); "
                       f"the correction is worse than off in the peaks at "
                       f"{listed(worse_at['peaks'])} modes, in the impulses at "
                       f"{listed(worse_at['impulses'])} modes.")
    return "\n".join(lines + summary)


def main(doc):
    """scripts/correction_table.py; doc: its docstring (the first paragraph is --help's)."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    p.add_argument("--simulate", help="path of a built simulate (default: the worktree's)")
    p.add_argument("--docs", action="store_true",
                   help="write the table into docs/convergence.md (correction-table section)")
    a = p.parse_args()
    simulate = find_binary("simulate", a.simulate)
    with tempfile.TemporaryDirectory() as tmp:
        body = ("Errors in % against the reference, correction off / on "
                "(`scripts/correction_table.py --docs`; `*`: on is worse than off).\n\n"
                + "\n".join(residual_lines()) + "\n"
                + correction_tables(simulate, pathlib.Path(tmp)))
    print(body)
    if a.docs:
        markdown.splice("correction-table", body)
    return 0

