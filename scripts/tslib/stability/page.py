"""The stability table's pages: the document (docs/stability.md) and the summary section of
docs/numerical_stability.md."""
import sys

from tslib import markdown


# ---------------------------------------------------------------------------------------------
# Markdown.

HEADER = """# Stability on the hard cases

The ten scenes of `config/hard/` are the configurations contact simulators fail on: Zeno
accumulation, grazing, stick-slip at the friction limit, simultaneous impacts, the Painleve
configuration, a very stiff and a very soft tooth, a wedged kernel, a violent drum command and
a long run. Each file's header says what makes it hard and where its values come from. Their
short versions run in CI for both integrators (`test/core/hard_cases/`: closed forms,
convergence as the knob is refined, agreement of the two integrators within their error
estimates, order independence, bit-identical reruns, no energy gain, bounded penetration and
progress). The long versions below are made by the command below ({wall_minutes:.1f} minutes
of wall time, each run on one core; several commands ran side by side):

    {command}

Properties checked on each long run (all must hold):

- **finite**: `simulate` exits 0 with status ok (no NaN or infinity, no failed recovery).
- **progress**: the run reaches its end; accepted steps per simulated second stay below a bound
  (event-driven: the scene's bound, which a stall would exceed; time stepping: exactly 1/h).
- **impact energy**: no impact raised the energy (`max_energy_gain_at_impact_J` <= tol).
- **energy balance**: E(end) - E(0) - drive work <= tol: no energy gain beyond the drive's work.
- **penetration**: `max_penetration_m` below the bound: rigid contacts at 10 x the event
  tolerance (event-driven) or h x 40 m/s (time stepping); compliant tooth-kernel contacts at
  Hertz's closed form for the tooth's tip speed (plus the wedge's 0.6 mm interference, scene 8).
- **memory**: the resident size of `simulate` grows by less than 2 MB after the first tenth of
  the run.
- **rerun**: a run of a tenth of the duration (at most 10 s), made twice, gives identical
  summaries (every number printed with 17 digits).
- scene checks: the Zeno kernel at rest on the plate (1), no creep below the friction limit
  (3), one model-validity warning for the rubber tooth's deflection beyond 0.1 L (7), kernels on
  the floor not sunk into it (10).

"Worst energy error" is the larger of the largest energy gain at an impact (never below 0) and
the gain over the run beyond the drive's work, so 0 means that neither an impact nor the run as
a whole gained energy (the script prints each run's balance, E(end) - E(0) - drive work, on
stderr). "Worst penetration" is
`max_penetration_m` over closed contacts (compliant contacts indent by design). Contacts are
sampled by `simulate` every millisecond (`--sample-interval 1e-3`), so the step rates are the
integrators' own.

"""

FOOTER = """
## Fixes the hard scenes needed

All ten scenes pass for both integrators; the CI test has no skipped assertion. Five scenes
needed fixes (scenes 1, 2 and 5 in the event-driven integrator, scene 10 one in each
integrator, scene 7 a feature of the core):

- **Scene 1 (Zeno with a finer rule: zeno_velocity 1e-4 m/s, or max_step 1e-3 s) and scene 5
  (the tumbling Painleve kernel landing on the plate), event-driven.** After a bounce the impact
  is located just past the crossing, so the pair starts the next step with gap <= 0; the gap
  event only fired on a change from > 0 to <= 0, so it was not armed. A flight shorter than one
  step was caught a step late, by the start-of-step contact check: the kernel chattered at the
  step rate and sank into the plate by the distance it fell in the rest of that step. Fix
  (`src/core/event_driven/events.cc`, `armEvents()`): each event function is armed per step; a
  gap function at or below zero whose rate points to opening (a pair that just bounced apart,
  a compliant contact that just closed) is armed to fire when it falls below its start value
  again. `eventValues()` now also returns the gap rates (dg_N/dt of every pair whose geometry
  was evaluated in full).
- **Scene 2 (a 10 nm graze lasting 8 us, inside one step of several times that), event-driven.** The event
  functions were only compared by sign at the step ends, so a contact that opens and closes
  within one step was missed. Fix (same function): when a separated gap has a falling rate at
  the step start and a rising one at its end, the minimum of its cubic Hermite interpolant
  (values and rates at both ends) is computed; if it comes near zero, the state at the
  predicted minimum is computed by a step from the start and, if the gap there is below
  -tolerance x 1e-2 m (the integrator's position error scale; a path that exactly touches gives
  no contact), the crossing is bisected as for a sign change. The probe costs one extra step
  only where a predicted dip comes near zero.
- **Scene 2, the contact geometry (both integrators).** The closest point on the deformed tooth
  centreline is refined by secant iterations from the polyline's answer, starting with a probe
  1e-6 L away. When the closest-point condition has equal values at both points (a kernel flank
  square to the tooth axis at the tip: the point is held at x = L by the clamp), the secant made
  no step and the probe's point was kept: the gap came out too large by the probe's offset
  (1e-6 L) exactly at the graze's deepest point, which hid the 10 nm overlap. Fix (`src/core/contact/narrow_phase.cc`, `refineClosestPoint()`): without a secant step
  the closer of the two points is kept.
- **Scene 7 (soft rubber tooth at 1500 rpm), both integrators: model-validity warning.** The
  tip deflects beyond 0.1 L (the "validity warning" check of the table prints the largest
  ratio), outside the small-deflection range of the linear (Euler-Bernoulli,
  first-order foreshortening) beam model. The core now checks |w(L)| / L after every step
  (`checkToothDeflection`, `src/core/episodes.cc`); the first time it exceeds `deflection_validity` (scene key,
  default 0.1) one warning is recorded in `stats.warnings` with the tooth, the ratio and the
  time (`stats.deflection_warning_time_s`), and `stats.max_tip_deflection_ratio` keeps the
  largest ratio. `simulate` prints the warning in its summary (and `max_tip_deflection_ratio`,
  `warnings` in the JSON summary); the ROS node reports it on `/diagnostics` at WARN level.
- **Scene 10 over the full 10 000 revolutions, time stepping: closed contacts drifted.** The
  kernels that come to rest on the floor keep rocking on their flanks (rolling without slip
  dissipates nothing). Moreau-Jean time stepping constrains the normal velocity at the
  midpoint, not the gap; the second-order term of the rolling it drops moves a pressed
  contact's gap down and up in turn, with a net sinking of about 1e-12 m per step: 8.2e-4 m
  after 750 s at h = 1 us (the penetration bound is 4e-5 m). Fix (`src/core/time_stepping/`,
  `keepClosedContactDepths()` and the activation in `assembleContactRows()`): after the position
  update every rigid contact that carried an impulse is evaluated at the end state; its impact
  step records its depth (at least one slop, h x zeno_velocity). Afterwards a contact that sank
  a slop deeper is moved back to that depth, and one that rose half a slop above the surface
  while pressed is moved back onto it, by the smallest mass-weighted position change along its
  normal (Gauss-Seidel, velocities unchanged; the potential energy restored is at most what the
  sinking took). A pressed contact (sticking or sliding, past its impact step) stays active up
  to a slop of clearance. The second half matters: a first version corrected sinking only, and
  a kernel's contact that rose then opened at the next midpoint and closed again a few steps
  later, a new impact each time (9.5e5 impacts in 22.5 s of scene 10; 2.05e4 before any fix;
  573 now). Tests: `TimeStepping.RockingKernelOnTheFloorDoesNotSink`
  and `HardCase.Scene10KernelRockingOnTheFloorDoesNotSink` (a kernel rocking for 1 s at
  h = 1e-5: 2.5e-5 m deep before, within 1.2e-6 m now), `HardCase.Scene10LandedKernelsDoNotChatter`
  (at most 100 impacts per 0.1 s in the first second); `stats.depth_corrections` counts the
  corrections (`depth_corrections` in the JSON summary).
- **A spinning kernel grazing a wall or another kernel (scene 10's flying kernels; a scene-2
  test), event-driven.** For speed, the event functions evaluated a separated kernel-wall or
  kernel-kernel pair exactly only within 1 um, and as a bound (with no rate) beyond. A spinning
  kernel whose long end dips below a wall for a microsecond, inside a free-flight step of
  1e-4 s, is tens of micrometres clear at both ends of the step: the graze check had no rates
  to interpolate, and the contact was missed. Fix (`src/core/event_driven/evaluate.cc`,
  `evaluateAll()`): at both ends of a step such a pair is evaluated exactly when it lies within
  twice the distance its kernels can cover in the step at their present speeds (centre speed
  plus spin times the long semi-axis); a pair farther than that cannot close within the step.
  Test: `HardCase.Scene02SpinningKernelGrazingAWallIsNotMissed` (dips of 5 um to 50 nm: 0
  impacts before, 1 now, for both integrators) and
  `HardCases.Scene02SpinningKernelGrazeIntegratorsAgree`.

## Notes

"""


def results_table(rows, notes):
    lines = ["| scene | integrator | duration | passed properties | worst energy error (J) | "
             "worst penetration (m) | steps per simulated s | wall time (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %s | %s | %s | %s | %s | %s | %s | %s |" % r)
    text = "\n".join(lines) + "\n" + FOOTER
    text += "\n".join("- " + n for n in notes) + "\n" if notes else "- none\n"
    return text


def fmt_duration(seconds):
    return "%g s" % seconds



def write_document(command, rows, notes, output, wall_s, readme=None, marker="stability-table"):
    text = (HEADER.format(command=command.strip(), wall_minutes=wall_s / 60.0) +
            results_table(rows, notes))
    if output:
        with open(output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    if readme:
        markdown.splice(marker, summary_table(rows, command, wall_s), readme)


def summary_table(rows, command, wall_s):
    """The section between the summary page's markers: the table (without the wall-time column)
    and the command or commands that made it."""
    lines = ["| scene | integrator | duration | passed properties | worst energy error (J) | "
             "worst penetration (m) | steps per simulated s |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %s | %s | %s | %s | %s | %s | %s |" % tuple(r[:7]))
    made_by = " and ".join("`%s`" % c.strip() for c in command.split("\n    "))
    return ("\n".join(lines) + "\n\nMade by " + made_by +
            " in %.1f minutes of wall time." % (wall_s / 60.0))
