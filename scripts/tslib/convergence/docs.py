"""The mode convergence study's verdicts, tables and pages: docs/convergence.md and the
README's convergence section."""
from tslib.convergence import runs
from tslib import markdown
from tslib.convergence.runs import (CHAOTIC_KERNELS, KNEAD_BENCH, ROTATION_CASE, ROTATION_LEVELS,
                                    TARGET, chaotic, max_modes, max_shapes, stats_agree, usable)
from tslib.numbers import rel_change
from tslib.teeth.cases import validity_fraction


def rotation_text(study):
    """The section rotation study as a sentence."""
    def series(word):
        rows = study[word]
        forces = ", ".join(f"{m['ft']:.4g}" for _, m in rows)
        changes = ", ".join(f"{100 * rel_change(a['ft'], b['ft']):.2f} %"
                            for (_, a), (_, b) in zip(rows, rows[1:]))
        return f"{forces} N (changes {changes})"
    levels = ", ".join(str(n) for n in ROTATION_LEVELS)
    return (f"Peak tangential force of the {ROTATION_CASE[0]} at {levels} modes (`--tolerance "
            f"1e-11`): with `section_rotation: shear_corrected` (the default) "
            f"{series('shear_corrected')}; with `euler_bernoulli` {series('euler_bernoulli')}.")



def not_run_text(m):
    return f"timed out (> {runs.TIME_LIMIT_S:.0f} s)" if m is None else m["failed"]


def change_cells(rows, i):
    if i + 1 >= len(rows) or not usable(rows[i + 1][1]):
        return ["-", "-", "-"]
    a, b = rows[i][1], rows[i + 1][1]
    return [f"{100 * rel_change(a[k], b[k]):.2f} %" for k in ("fn", "ft", "v")]


def verdict(rows):
    """(short verdict, detail) of a scene: its first level against the next finer one."""
    if not usable(rows[0][1]):
        return "not run", not_run_text(rows[0][1])
    if len(rows) < 2:
        return ("rigid" if rows[0][0] == 0 else "at cap"), ""
    if not usable(rows[1][1]):
        return "finer level not run", f"{not_run_text(rows[1][1])} at {rows[1][0]} modes"
    a, b = rows[0][1], rows[1][1]
    worst = max(rel_change(a[k], b[k]) for k in ("fn", "ft", "v"))
    if chaotic(rows):
        agree, ratio = stats_agree(a, b)
        return (("chaotic: means agree" if agree else "chaotic: means differ"),
                f"largest change {ratio:.1f} standard errors; run maxima {100 * worst:.2f} %")
    return ("yes" if worst <= TARGET else "no"), f"{100 * worst:.2f} %"


def stats_cell(m):
    return ", ".join(f"{m['stats'][k][0]:.3g} ± {m['stats'][k][1]:.2g}" for k in ("fn", "ft", "v"))


def full_table(results):
    lines = ["| scene | modes | peak normal [N] | peak tangential [N] | exit speed [m/s] | "
             "impacts | tip deflection / L | change to next level (N, T, v) | "
             "kernel means ± s.e. (N, T, v) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, rows in results:
        for i, (level, m) in enumerate(rows):
            label = f"| {name if i == 0 else ''} | {level}{' (auto)' if i == 0 else ''} |"
            if not usable(m):
                lines.append(f"{label} {not_run_text(m)} | | | | | | |")
                continue
            cells = change_cells(rows, i)
            stats = stats_cell(m) if chaotic(rows) else ""
            lines.append(f"{label} {m['fn']:.4g} | {m['ft']:.4g} | {m['v']:.4g} | "
                         f"{m['impacts']} | {m['tip']:.3f} | {', '.join(cells)} | {stats} |")
    return "\n".join(lines)


def short_table(results):
    lines = ["| scene | auto modes | peak N / T [N] | exit speed [m/s] | change to next level | "
             "within 1 % | tip / L |", "|---|---|---|---|---|---|---|"]
    for name, rows in results:
        level, m = rows[0]
        short, detail = verdict(rows)
        if not usable(m):
            lines.append(f"| {name} | {level} | - | - | {detail} | {short} | - |")
            continue
        lines.append(f"| {name} | {level} | {m['fn']:.3g} / {m['ft']:.3g} | {m['v']:.3g} | "
                     f"{detail or '-'} | {short} | {m['tip']:.3f} |")
    return "\n".join(lines)


def knead_text(before, after):
    b = ", ".join(f"{m['ft']:.1f} N ({n})" for n, m in before)
    a = ", ".join(f"{m['ft']:.2f} N ({n})" for n, m in after)
    change = (f"{100 * rel_change(after[0][1]['ft'], after[1][1]['ft']):.2f} %" if len(after) > 1
              else "-")
    return (f"Knead force of `config/bench/{KNEAD_BENCH}.yaml` at `--tolerance 1e-8` (peak "
            f"tangential tooth force, modes in brackets). Before (modal tooth only, "
            f"`static_correction: off`, `section_rotation: euler_bernoulli`): {b}. After (static "
            f"correction, shear-corrected sections, automatic count and finer levels): {a}; "
            f"change from the chosen level to the next: {change}.")


# The method; <N>, <S> and <V>: the most modes, the most shape functions and the validity
# limit over L, from the core (write_docs).
METHOD = """## Method

A contact load excites every bending mode, and n retained modes miss the quasi-static compliance
of the others; that of the slope, which friction acts on through the tooth's surface
(`(d/2) w'`), falls only like 1/n.

- **Static correction** (residual flexibility, docs/model.md §9b). Once per drum speed the
  exact static flexibility of the rotating cantilever, `EI w'''' - (N w')' - rho A Omega^2 w =
  load` clamped-free (the operator of the modal equations, centrifugal tension N included), is
  solved by 256 cubic Hermite elements at 33 points along the tooth, for a unit force and a unit
  couple at the same point; the retained modes' part `Phi^T K_n^-1 Phi` (K_n full: K_G couples
  the modes) is subtracted. The residual, a 2 x 2 block per point (w and w' under force and
  couple), is projected on the contact's normal. Along n it is a massless spring in series with
  the Hertz law, in both integrators and both schemes: the Hertz law sees `delta - r_n F`, and
  its damping the approach rate split between the two springs, `delta' / (1 + r_n dF_e/d
  delta_e)`; the relation is solved per evaluation by a bracketed Newton iteration
  (`compliantNormalForce` in `src/core/contact/contact_forces.cc`), and the release event of the contact is the
  same force before its no-adhesion clamp. The spring stores `r_n F^2 / 2`, zero whenever a
  contact opens or closes, so the energy checks at impacts are unchanged. At another drum speed
  the tables are rebuilt (per workspace, cleared by `resetData`). The residual along n changes
  as the contact point slides along the tooth and the normal turns, and the spring's energy
  with it (`dV = -F^2/2 dR` at a fixed approach): the contact force is the full gradient of the
  series potential, `F w_N + (F^2 / 2) dR/dq` (and `(F^2 / 2) dR/dtheta` on the drum, in the
  drive's work), with dR/dq from the closest point's sensitivity and the table interpolated
  C^1 along the tooth (monotone cubic Hermite; docs/model.md §9b, "Energy of the series
  spring"). An elastic strike (restitution 1, no friction, undamped tooth) then closes its
  energy balance to the integration error at any mode count, `|change - drive work| <= 1e-8`
  of the impact energy (`test/core/test_energy.cc`); before, the 4-mode tooth gained 8e-5 of it
  at every tolerance.
- **Shear-corrected sections** (`teeth.*.section_rotation: shear_corrected`, the default;
  docs/model.md §9b). The friction force acts on the tooth's surface, at `(d/2) n` from the
  centreline, so its couple turns the sections, and the surface point moves with their
  rotation. An Euler-Bernoulli section turns with the slope: mode i's rotation is phi_i', which
  grows with its wave number beta_i, and the couple reaches ever further into the high modes.
  A shear-flexible (Timoshenko) beam bent quasi-statically into a wave of number beta turns its
  sections by `psi = w' / (1 + (E / kappa G) (I / A) beta^2)` (kappa = 6 (1 + nu) / (7 + 6 nu),
  a solid round section): the shear takes up the rest of the slope. Each mode's rotation in
  the contact Jacobian (and its rate in the velocity drift) is scaled by that factor, the
  same in the force and the motion, so the contact's power balance is unchanged. The modes'
  shapes and frequencies stay Euler-Bernoulli; the correction only concerns the rotation that
  carries the surface points. For the teeth of `config/` (d / L = 1/6) it is 0.98 for the
  first mode and 0.48 for the fifth. A large-deflection tooth's sections turn with its
  centreline (a Kirchhoff rod); its surface points get the same factor, mode by mode of the
  rod linearised at rest (docs/large_deflection.md). Tried before it and measured on branch
  `tstick` (`scripts/probe_stick_convergence.sh` there): a Mindlin tangential spring in series
  with the stick (and the residual flexibility along t) does not converge the stick forces.
- **Automatic mode count** (`teeth.*.modes: auto`, the default). The Hertz contact time t_c of
  the stiffest kernel contact at the tooth's tip speed (flank against the kernel's sharpest
  curvature) is estimated at start-up; a truncated mode of frequency omega is followed
  quasi-statically with an error of about `(pi / (t_c omega))^2`. Modes are added until the
  first truncated one has `(pi / (t_c omega_{n+1}))^2 <= max(tolerance, 2.5e-4)`: at least 2,
  at most <N> (4 without kernels). `simulate --modes` prints the count and the contact time.
- **Large deflection.** A scene whose modal tooth bends past <V> L (the core's validity
  limit) is valid only with the geometrically exact rod (docs/large_deflection.md): the cases
  and teeth of `compare_teeth.LARGE_DEFLECTION` run with it (rows marked "(rod)"), and each
  bench scene past <V> L is run again with it. A rod's levels are shape functions: the
  automatic count (the modal count, within 6 to 24) and the two finer levels +4 and +8 (at
  most <S>; its highest Ritz frequencies, and with them its cost, grow fast with the count).
  A rod of a stiff material has spurious Ritz frequencies of tens of MHz (nylon), which hold
  the explicit event-driven integrator to steps of nanoseconds: a rerun of a scene with
  several stiff teeth can exceed the core's work budget, and is then listed with that status
  (the nylon stream, whose six teeth the chaotic kernel stream bends to 0.11-0.12 L at some
  levels at the scene's 83.78 rad/s; in the findings' sweep they stay below <V> L at every
  speed). The remedy would be a rod whose bending is integrated implicitly, or a basis without
  the spurious frequencies; neither is built.
"""


def summary_text(results):
    flexible = [(name, rows) for name, rows in results if rows[0][0] > 0]
    failed = [name for name, rows in flexible if not usable(rows[0][1])]
    ran = [rows for _, rows in flexible if usable(rows[0][1])]
    single = [rows for rows in ran if not chaotic(rows)]
    streams = [rows for rows in ran if chaotic(rows)]
    n_ok = sum(1 for rows in single if verdict(rows)[0] == "yes")
    n_agree = sum(1 for rows in streams if verdict(rows)[0] == "chaotic: means agree")
    text = (f"{n_ok} of {len(single)} scenes with flexible teeth and at most "
            f"{CHAOTIC_KERNELS} kernels meet the 1 % target (rigid teeth have no modes to "
            f"converge). Of the {len(streams)} streams (chaotic, judged by their kernel means), "
            f"{n_agree} of them agree between the levels within two standard errors.")
    if failed:
        text += (f" Not run to the end at the chosen level: {', '.join(failed)} (the core's work "
                 "budget, explained in docs/convergence.md).")
    return text


STREAM_STATISTICS_TEXT = (
    "The streams' statistics over many seeds, with both targets (standard error <= 0.5 % of each "
    "kernel mean, levels within 1 %), come from the sweep `config/sweeps/stream_statistics.yaml`"
    " (docs/sweeps.md, \"Stream statistics and the stop rule\"): the section [Stream statistics "
    "over seeds](#stream-statistics-over-seeds) below, which that sweep's report writes; the "
    "stream rows of the table are one seed each.")


def stream_statistics_section(out_md):
    """The section that `scripts/sweep report OUT --stream-docs` splices into the page, kept as
    it is when the page is regenerated (a placeholder on a new page)."""
    kept = None
    if out_md.is_file():
        kept = markdown.section_body(out_md.read_text(), "stream-statistics")
    begin, end = markdown.markers("stream-statistics")
    return "\n".join([
        "## Stream statistics over seeds", "",
        "Written by `scripts/sweep report out/sweeps/stream_statistics --stream-docs "
        "docs/convergence.md` after `scripts/sweep run config/sweeps/stream_statistics.yaml` "
        "(not by this script, which keeps the section).", "",
        begin, kept if kept is not None else "(not run yet)", end])


def write_docs(results, before, after, rotation, out_md, readme):
    summary = summary_text(results)
    limit = (f" A level whose run took longer than {runs.TIME_LIMIT_S:.0f} s is reported as timed out "
             "(`--time-limit`); one that failed (the work budget) is reported with its status.")
    body = [
        "# Mode convergence of the tooth forces",
        "",
        "Regenerated by `/usr/bin/python3 scripts/convergence_table.py` (README \"Converged tooth "
        "forces\"). Every scene of `config/bench/` and every case x tooth variant of "
        "`config/scenes/` (as `scripts/compare_teeth.py` combines them, at the scene's drum "
        "speed) runs at the automatic mode count (`teeth.*.modes: auto`, the first row of each "
        f"scene) and at ceil(1.5 n) and 2 n modes (at most {max_modes()}). Peak forces are the largest "
        "tooth force peaks on any kernel; the exit speed is the end speed of the kernel the "
        "tooth struck hardest; the change columns compare a row with the next finer one. "
        f"Target: every force and exit speed within {100 * TARGET:.0f} % between the chosen "
        "level and the next finer one." + limit,
        "",
        summary,
        "",
        "**What a converged stream is.** A stream (more than "
        f"{CHAOTIC_KERNELS} kernels meeting several teeth) is chaotic: a change in the last "
        "digits early on (a kernel caught a microsecond earlier) leads to other later "
        "collisions, so the largest force of one run is a sample, not a converged number, at "
        "any mode count or tolerance. What a designer can rely on is the distribution over "
        "kernels: the table gives, for the streams, the mean over the run's kernels of the "
        "peak normal and tangential tooth force and of the exit speed, with its standard "
        "error, and a stream counts as converged in modes when the means of two levels differ "
        "by at most two standard errors. That is a statistical statement at the run's sample "
        "size (10 kernels), much weaker than the 1 % of the single strikes; the run maxima and "
        "their changes are listed too, and are not converged. " + STREAM_STATISTICS_TEXT,
        "",
        "**Stick forces and the sections' rotation.** The normal forces and exit speeds "
        "converge through the static correction, which puts the truncated modes' normal "
        "compliance in series with the contact. The tangential peaks are mostly stick forces: "
        "while the kernel sticks, the friction force is set by the tooth surface point's "
        "tangential motion, which the friction couple (d/2) F_T drives through the rotation of "
        "the tooth's sections. An Euler-Bernoulli section turns with the slope w', and a mode's "
        "slope grows with its wave number, so with `section_rotation: euler_bernoulli` every "
        "added mode moves the stick force (about 1/n). A shear-flexible section turns by less "
        "than the slope at short waves, the shear taking up the rest; with `shear_corrected` "
        "(the default) the stick forces converge (Method, below). " + rotation_text(rotation),
        "",
        knead_text(before, after),
        "",
        full_table(results),
        "",
        stream_statistics_section(out_md),
        "",
        METHOD.replace("<N>", str(max_modes())).replace("<S>", str(max_shapes())).replace(
            "<V>", f"{validity_fraction():g}"),
    ]
    out_md.write_text("\n".join(body))
    if readme is None:
        return
    markdown.splice("convergence", "\n" + summary + " Every level, the kernel statistics of the "
                    "streams and why some rows miss the target: "
                    "[docs/convergence.md](docs/convergence.md). " + knead_text(before, after) +
                    "\n", readme)
