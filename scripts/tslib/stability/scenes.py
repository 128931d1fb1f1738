"""The hard cases' long runs: the scenes of config/hard/ with their durations and extra
checks, and the bounds derived from a scene file (penetration, Hertz indentation) with the
core's defaults for the keys a scene leaves out (simulate --print-schema)."""
import math

from tslib import CONFIG, schema


HARD_DIR = CONFIG / "hard"
INTEGRATORS = ("event_driven", "time_stepping")


# ---------------------------------------------------------------------------------------------
# The long runs.

class Scene:
    """One hard scene's long run and the bounds its properties are checked against."""

    def __init__(self, key, file, duration_s, title, overrides=(), energy_tol_j=1e-7,
                 ed_steps_per_s=1e6, checks=(), note="", quick_duration_s=None):
        self.key = key                  # "01"
        self.file = file                # "01_zeno.yaml"
        self.duration_s = duration_s    # long duration [s]
        self.title = title
        self.overrides = list(overrides)
        self.energy_tol_j = energy_tol_j      # energy gain allowed (impact and run) [J]
        self.ed_steps_per_s = ed_steps_per_s  # event-driven progress bound
        self.checks = list(checks)            # extra (name, function(scene, yaml, summary, it))
        self.note = note
        self.quick_duration_s = quick_duration_s  # shorter long run (both integrators) [s],
                                                  # unless --full


def kernel_half_height(a, b, psi):
    """Height of an ellipse's centre above its lowest point [m]."""
    return math.sqrt((a * math.sin(psi)) ** 2 + (b * math.cos(psi)) ** 2)


def check_zeno_rest(scene, doc, summary, integrator):
    """Scene 1: after 10 s the kernel lies on the plate (centre b above it), at rest."""
    k = summary["kernels"][0]
    b = float(doc["kernels"][0]["semi_axes"][1])
    speed = math.hypot(*k["velocity_mps"])
    ok = abs(k["position_m"][1] - b) <= penetration_bound(scene, doc, integrator) and speed < 1e-9
    return ok, "y - b = %.2e m, |v| = %.1e m/s" % (k["position_m"][1] - b, speed)


def check_no_creep(scene, doc, summary, integrator):
    """Scene 3 (atan(mu) - 0.01 rad): after 20 s the kernel has not crept down the incline.

    Bound 2 nm: the 1 nm touchdown fall moves it by 0.5 nm, time stepping's touchdown delay
    by another 0.6 nm; a creep of 1 nm/s (a regularised friction law) would show as 20 nm."""
    x = summary["kernels"][0]["position_m"][0]
    return abs(x) <= 2e-9, "x = %.2e m" % x


def check_resting_on_floor(scene, doc, summary, integrator):
    """Scene 10: kernels lying on the floor do not sink into it.

    A kernel counts as on the floor if its lowest point (from its final pose) is within 1 mm of
    the floor (y = -0.30); none of them may be below it by more than the penetration bound.
    (Kernels keep rocking on their flanks: rolling without slip does not dissipate, so they
    are not required to be at rest.)"""
    floor = -0.30
    worst, counted = 0.0, 0
    for kd, ks in zip(doc["kernels"], summary["kernels"]):
        a, b = (float(x) for x in kd["semi_axes"])
        gap = ks["position_m"][1] - floor - kernel_half_height(a, b, ks["angle_rad"])
        if gap < 1e-3:
            counted += 1
            worst = min(worst, gap)
    ok = -worst <= penetration_bound(scene, doc, integrator)
    return ok, "%d kernels on the floor, lowest gap %.2e m" % (counted, worst)


def check_deflection_warning(scene, doc, summary, integrator):
    """Scene 7: the rubber tooth bends beyond 0.1 L; the run must carry the model-validity
    warning (once) and report the largest |w(L)| / L above the validity fraction."""
    warnings = [w for w in summary.get("warnings", []) if "tip deflection" in w]
    ratio = summary.get("max_tip_deflection_ratio", 0.0)
    limit = float(doc.get("deflection_validity", schema.default("deflection_validity")))
    # A large-deflection tooth (--set teeth.0.model=large_deflection) is valid there: no warning.
    expected = 0 if "teeth.0.model=large_deflection" in scene.overrides else 1
    return (len(warnings) == expected and ratio > limit,
            "%d warning(s), max |w(L)|/L = %.3f" % (len(warnings), ratio))


HARD_SCENES = [
    Scene("01", "01_zeno.yaml", 10.0, "Zeno drop, e = 0.5",
          energy_tol_j=1e-12, ed_steps_per_s=1e5, checks=[("rest on plate", check_zeno_rest)]),
    Scene("02", "02_grazing.yaml", 1.0, "grazing the tooth tip", energy_tol_j=1e-11,
          ed_steps_per_s=5e5),
    Scene("03", "03_stick_slip.yaml", 20.0, "stick at atan(mu) - 0.01",
          energy_tol_j=1e-15, ed_steps_per_s=2e4, checks=[("no creep", check_no_creep)]),
    Scene("04", "04_simultaneous.yaml", 0.1, "simultaneous impacts", energy_tol_j=1e-9),
    Scene("05", "05_painleve.yaml", 1.0, "Painleve, mu = 1.3", energy_tol_j=1e-12),
    Scene("06", "06_stiff_tooth.yaml", 0.1, "stiff steel tooth, 1500 rpm"),
    Scene("07", "07_soft_tooth.yaml", 0.1, "soft rubber tooth, 1500 rpm",
          checks=[("validity warning", check_deflection_warning)]),
    Scene("08", "08_wedged.yaml", 0.1, "wedged kernel"),
    Scene("09", "09_drum_command.yaml", 1.0, "drum at 1500 rpm (ramps: CI only)",
          overrides=["drum.speed=157.08"],
          note="simulate has no drum command schedule: the long run turns at the commanded "
               "1500 rpm from the start; the ramps 0 -> 1500 -> 0 rpm run in CI only"),
    Scene("10", "10_long_run.yaml", 750.0, "long run, 800 rpm",
          checks=[("no sinking", check_resting_on_floor)], quick_duration_s=22.5,
          note="the long run covers 300 revolutions (22.5 s) with both integrators unless --full "
               "is given (10 000 revolutions, 750 s: about 33 times the wall time of the "
               "scene 10 rows); 300 revolutions keep the whole table near 10 minutes"),
]


# ---------------------------------------------------------------------------------------------
# Bounds derived from the scene file.

def num(section, key, schema_key):
    """A number from a scene section, else the default of schema_key (the core's, simulate
    --print-schema). PyYAML reads YAML 1.1, where 2.8e8 (no sign in the exponent) is a string,
    so every number is converted here."""
    return float(section[key]) if key in section else schema.default(schema_key)

def penetration_bound(scene, doc, integrator):
    """Largest penetration allowed [m]: rigid contacts at 10 x the event tolerance
    (event-driven) or h x the fastest approach (time stepping, h x 40 m/s: the strikes); compliant
    tooth-kernel contacts by Hertz's closed form at the tooth's tip speed plus the kernel's speed,
    with the kernel's mass, plus the wedge's geometric interference (scene 8)."""
    integ = doc.get("integrator", {})
    if integrator == "event_driven":
        rigid = 10 * num(integ, "tolerance", "integrator.tolerance") * 1e-2
    else:
        rigid = num(integ, "dt", "integrator.dt") * 40.0
    if not doc.get("teeth"):
        return rigid
    law = doc.get("contact", {}).get("tooth_kernel", {}).get(
        "law", schema.value("contact.tooth_kernel.law"))
    if law != "compliant":
        return rigid
    tooth, kernel = doc["teeth"][0], doc["kernels"][0]
    drum = doc.get("drum", {})
    omega = abs(float(next((o.split("=")[1] for o in scene.overrides
                            if o.startswith("drum.speed=")),
                           drum.get("speed", schema.default("drum.speed")))))
    rest = schema.value("kernels.*.velocity")
    v_kernel = max(math.hypot(*(float(x) for x in k.get("velocity", rest))) for k in doc["kernels"])
    v = (omega * (num(drum, "radius", "drum.radius") + num(tooth, "length", "teeth.*.length")) +
         v_kernel)
    hertz = hertz_indentation(tooth, kernel, v)
    interference = 0.6e-3 if scene.key == "08" else 0.0
    extra = 0.0 if integrator == "event_driven" else num(integ, "dt", "integrator.dt") * v
    return max(rigid, 1.05 * hertz + interference + extra)


def hertz_indentation(tooth, kernel, v):
    """(5 m v^2 / (4 K))^(2/5) with the smallest Hertz constant of the pair (the kernel's
    sharpest curvature b^2/a against the tooth's round tip), as in test/core/hard_cases/."""
    e_t, nu_t = (num(tooth, "youngs_modulus", "teeth.*.youngs_modulus"),
                 num(tooth, "poisson_ratio", "teeth.*.poisson_ratio"))
    e_k, nu_k = (num(kernel, "youngs_modulus", "kernels.*.youngs_modulus"),
                 num(kernel, "poisson_ratio", "kernels.*.poisson_ratio"))
    a, b = (float(x) for x in kernel.get("semi_axes", schema.value("kernels.*.semi_axes")))
    r_t = 0.5 * num(tooth, "diameter", "teeth.*.diameter")
    e_star = 1.0 / ((1 - nu_t ** 2) / e_t + (1 - nu_k ** 2) / e_k)
    r_in = 1.0 / (1.0 / r_t + a / (b * b))
    r_out = 1.0 / (1.0 / r_t + 1.0 / b)
    k_hertz = 4.0 / 3.0 * e_star * math.sqrt(math.sqrt(r_in * r_out))
    mass = num(kernel, "mass", "kernels.*.mass")
    return (5.0 * mass * v * v / (4.0 * k_hertz)) ** 0.4
