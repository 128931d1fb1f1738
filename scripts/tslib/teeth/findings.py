"""The findings page (docs/findings.md): the paper's three claims judged from the runs, the
agreement with measurements, the rotation and large-deflection controls."""



import numpy as np

from tslib.numbers import fmt3, fmt3_range
from tslib.teeth.analysis import nan_mean
from tslib.teeth.cases import (CASES, CONVERGENCE_MODES, FLEXIBLE, FROZEN_CASES,
                               HERTZ_SPEED_MPS, HERTZ_TIME_US, LARGE_DEFLECTION, MEASURED_FORCE_N,
                               VARIANTS, damage_thresholds, partial_paragraph, validity_fraction)
from tslib.teeth.report import markdown_table, strike_table


def peaks_numbers(a):
    """Claim 1 numbers: the verdict, totals over every case and tooth, and which cases show
    separated peaks in nearly every contact or in none."""
    sep = {k: s for k, s in a["separation"].items() if s["n"]}
    total = sum(s["n"] for s in sep.values())
    separated = sum(s["separated"] for s in sep.values())
    share = separated / total if total else float("nan")
    together = total - separated
    return {
        "total": total, "separated": separated, "share": share, "together": together,
        "at_transition": sum(s["separated_at_transition"] for s in sep.values()),
        "together_sliding": sum(s["together_sliding"] for s in sep.values()),
        "verdict": ("holds" if share > 0.9 else "holds in part" if share > 0.1 else
                    "does not hold"),
        "mostly": [f"{c}/{v}" for (c, v), s in sep.items() if s["separated"] >= 0.9 * s["n"]],
        "never": [f"{c}/{v}" for (c, v), s in sep.items() if s["separated"] == 0],
        "widest": max(((s["median_us"], f"{c}/{v}") for (c, v), s in sep.items()),
                      default=(float("nan"), "-"))}


def claim_peaks(a):
    """Claim 1 verdict and text."""
    sep = a["separation"]
    rows = []
    for case in CASES:
        for v in VARIANTS:
            s = sep.get((case, v))
            if s and s["n"]:
                rows.append([case, v, s["n"], f"{fmt3(100 * s['separated'] / s['n'])} %",
                             s["separated_at_transition"], s["n"] - s["separated"],
                             s["together_sliding"], fmt3(s["median_us"])])
    p = peaks_numbers(a)
    text = (f"Time between the peak tangential and the peak normal tooth force on each kernel a "
            f"tooth touched (the core's peaks, at every accepted step and event); separated "
            f"means more than {fmt3(a['threshold_us'])} us apart (two sampling intervals: "
            "simulate stops the integrator at every sample near a tooth, so its steps there are "
            f"no longer). Separated in {p['separated']} of {p['total']} kernel contacts "
            f"({fmt3(100 * p['share'])} %); in {p['at_transition']} of those {p['separated']} the "
            "tangential peak falls on a stick-slip transition of the contact (same accepted "
            f"step). Of the {p['together']} contacts whose peaks coincide, "
            f"{p['together_sliding']} slide at the normal peak.\n\n"
            + markdown_table(["case", "tooth", "kernels touched", "separated",
                              "separated, tangential peak at stick-slip", "together",
                              "together, sliding at normal peak",
                              "median abs time between peaks [us]"], rows)
            + f"\n\nThe widest median separation: {p['widest'][1]}, {fmt3(p['widest'][0])} us. "
            "Where the peaks part, the contact sticks while the normal force rises and the "
            "tangential force peaks at a stick-slip transition (the friction force is largest "
            "where it reaches mu N), or the largest tangential and the largest normal force "
            "belong to different contact episodes. Where they coincide at every speed ("
            + (", ".join(p["never"]) or "nowhere") + "), the contact slides through its force "
            "peak: a sliding Coulomb contact carries tangential force mu N, so both peak at the "
            "same instant.")
    return p["verdict"], text


def claim_subs(a):
    """Claim 2 verdict and text."""
    subs = a["subs"]
    rows = []
    for case in CASES:
        if (case, "rigid") not in subs:
            continue
        row = [case, fmt3(subs[(case, "rigid")]["mean"])]
        for v in FLEXIBLE:
            s = subs.get((case, v))
            if not s:
                row.append("-")
                continue
            control = f", {s['by_bending']} by bending" if case in FROZEN_CASES else ""
            row.append(f"{fmt3(s['mean'])} (more {s['more']}/{s['n']}, fewer {s['fewer']}/"
                       f"{s['n']}{control})")
        rows.append(row)
    flexible = [s for (c, v), s in subs.items() if v != "rigid"]
    more = sum(s["more"] for s in flexible)
    fewer = sum(s["fewer"] for s in flexible)
    by_bending = sum(s["by_bending"] for s in flexible)
    rigid_several = [c for (c, v), s in subs.items() if v == "rigid" and s["rigid_max"] > 1]
    bending = [f"{c}/{v}" for (c, v), s in subs.items() if s["by_bending"] > 0]
    uncontrolled = [f"{c}/{v} ({s['more']} of {s['n']} speeds)" for (c, v), s in subs.items()
                    if c not in FROZEN_CASES and v != "rigid" and s["more"] > s["fewer"]]
    verdict = ("holds" if more > fewer and not rigid_several else
               "holds in part" if by_bending > 0 else "does not hold")
    text = ("Mean sub-collisions per tooth macro-collision over the speeds (macro-collision: the "
            "contact episodes of one tooth-kernel pair less than `macro_collision_gap`, 2 ms, "
            "apart; each episode is a sub-collision). In brackets: at how many speeds the "
            "flexible tooth has more or fewer than the rigid tooth, and at how many it has more "
            "than both the rigid tooth and itself frozen (no bending modes, same material and "
            "contact), i.e. extra sub-collisions caused by its bending.\n\n"
            + markdown_table(["case", "rigid"] + FLEXIBLE, rows)
            + f"\n\nOver all cases and speeds a flexible tooth had more sub-collisions per "
            f"macro-collision than the rigid tooth {more} times and fewer {fewer} times; "
            f"{by_bending} of those excesses are caused by bending (the frozen tooth has fewer). "
            "The rigid tooth produces several sub-collisions in "
            + (", ".join(rigid_several) or "no case")
            + ": there the kernel is thrown back onto the tooth by the concave bar, by its "
            "pedicel or by its own spin after an off-centre hit, with or without bending. "
            "Sub-collisions caused by bending (more than both the rigid and the frozen tooth at "
            "some speed): " + (", ".join(bending) or "none") + ". More often than the rigid "
            "tooth where no frozen control was run, so that bending and the kernels' own "
            "rebounds cannot be told apart: " + (", ".join(uncontrolled) or "none")
            + ". Where the compliant contact "
            "holds on through the tooth's vibration, the vibration shows as ripples on the "
            "force of one contact episode (see the knead force history) rather than as "
            "separate episodes.")
    return verdict, text


def claim_knead(a):
    """Claim 3 verdict and text."""
    k = a["knead"]
    rows = [[v, fmt3_range(k[v]["to_rigid"]), fmt3_range(k[v]["frozen_to_rigid"]),
             fmt3_range(k[v]["to_frozen"])] for v in FLEXIBLE if v in k]
    below = [v for v in FLEXIBLE if v in k and k[v]["to_rigid"][1] < 1.0]
    verdict = ("holds" if len(below) == len(k) else "holds in part" if below else
               "does not hold")
    text = ("Knead force: the peak tangential tooth force on the knead scene (kernel pressed "
            "between the tooth and a concave bar). Ranges over the drum speeds of the ratio of "
            "the flexible tooth to the rigid steel tooth, of the same tooth frozen (no bending) "
            "to the rigid tooth, and of the flexible tooth to itself frozen:\n\n"
            + markdown_table(["tooth", "flexible / rigid", "frozen / rigid",
                              "flexible / frozen"], rows)
            + f"\n\nBelow the rigid tooth at every speed: {', '.join(below) or 'none'}. Two "
            "causes separate: the contact material (frozen / rigid: the soft polyurethane "
            "contact alone cuts the force) and the bending (flexible / frozen below 1: the "
            "tooth gives way to the wedged kernel).")
    return verdict, text


def damage_table(a):
    """Per case and tooth: mean damaged and detached fractions over the speeds, and the speeds
    with any damage."""
    rows = []
    for case in CASES:
        for v in VARIANTS:
            by_rpm = a["table"].get((case, v))
            if not by_rpm:
                continue
            damaged = [r for r, m in sorted(by_rpm.items()) if m["damaged"] > 0]
            rows.append([case, v, fmt3(nan_mean([m["damaged"] for m in by_rpm.values()])),
                         ", ".join(str(r) for r in damaged) or "none",
                         fmt3(nan_mean([m["detached"] for m in by_rpm.values()]))])
    return markdown_table(["case", "tooth", "damaged (mean fraction)", "speeds with damage [rpm]",
                           "detached (mean fraction)"], rows)


def agreement_paragraph(a):
    """Single strike: peak normal force against the measured threshing force, its growth with
    the impact speed, and the first contact's duration against the Hertz estimate."""
    strike = a["strike"]
    in_band = [k for k, s in strike.items()
               if MEASURED_FORCE_N[0] <= s["peak_N"] <= MEASURED_FORCE_N[1]]
    band_rpms = sorted({rpm for (v, rpm) in in_band if v == "rigid"})
    # Contact times at the speeds of the Hertz estimate: stiff teeth (the kernel's modulus
    # dominates the contact) apart from the soft polyurethane.
    in_range = {k: s for k, s in strike.items()
                if HERTZ_SPEED_MPS[0] <= s["speed_mps"] <= HERTZ_SPEED_MPS[1]}
    stiff = [s["contact_us"] for (v, _), s in in_range.items() if v != "polyurethane"]
    soft = [s["contact_us"] for (v, _), s in in_range.items() if v == "polyurethane"]
    # Force against impact speed, rigid tooth: the log-log slope (Hertz: 6/5).
    rigid = [(s["speed_mps"], s["peak_N"]) for (v, _), s in strike.items() if v == "rigid"]
    exponent = (float(np.polyfit(np.log([p[0] for p in rigid]), np.log([p[1] for p in rigid]),
                                 1)[0]) if len(rigid) > 1 else float("nan"))
    return (
        f"Single strike: {len(in_band)} of {len(strike)} runs give a peak normal force within "
        f"the measured threshing force {MEASURED_FORCE_N[0]}-{MEASURED_FORCE_N[1]} N, the "
        f"rigid tooth at {', '.join(str(r) for r in band_rpms) or 'no speed'}"
        + (" rpm" if band_rpms else "") + ". For the "
        f"rigid tooth the peak force grows as the impact speed to the power {fmt3(exponent)} "
        "(log-log fit; Hertz: 1.2). At impact speeds of "
        f"{HERTZ_SPEED_MPS[0]:g}-{HERTZ_SPEED_MPS[1]:g} m/s the first contact lasted "
        f"{fmt3(min(stiff, default=float('nan')))}-{fmt3(max(stiff, default=float('nan')))} us "
        "for the rigid, steel and nylon teeth, whose contact modulus the kernel dominates, "
        f"against the Hertz estimate {HERTZ_TIME_US[0]:g}-{HERTZ_TIME_US[1]:g} us of docs/model.md "
        f"§9a; {fmt3(min(soft, default=float('nan')))}-"
        f"{fmt3(max(soft, default=float('nan')))} us for the soft polyurethane, whose low "
        "modulus lengthens the contact and lowers its force.")


def rotation_paragraph(history_rpm):
    return (f"The teeth's sections now turn as shear-flexible ones (`teeth.*.section_rotation: "
            f"shear_corrected`, docs/model.md §9b), no longer with the Euler-Bernoulli slope, "
            f"whose high modes kept the stick forces from converging in the mode count. At "
            f"{history_rpm} rpm, the peak tooth forces of the single strikes and the knead with "
            f"each (both at the automatic mode count; the rigid tooth has no sections to turn), "
            f"and the knead force over the rigid tooth's:")


def rotation_table(a, history_rpm):
    """Peak forces with the shear-corrected and the Euler-Bernoulli sections."""
    rows = []
    for case in FROZEN_CASES:
        for v in FLEXIBLE:
            before = a["euler"].get((case, v))
            if before is None:
                continue
            now = a["table"][(case, v)][history_rpm]
            rigid = a["table"][(case, "rigid")][history_rpm]["knead_N"]
            rows.append([case, v,
                         f"{fmt3(now['peak_normal_N'])} / {fmt3(before['peak_normal_N'])}",
                         f"{fmt3(now['knead_N'])} / {fmt3(before['knead_N'])}",
                         f"{fmt3(now['knead_N'] / rigid)} / {fmt3(before['knead_N'] / rigid)}"])
    return markdown_table(["case", "tooth", "peak normal [N], shear-corrected / Euler-Bernoulli",
                           "peak tangential [N], shear-corrected / Euler-Bernoulli",
                           "tangential / rigid tooth's, shear-corrected / Euler-Bernoulli"], rows)


def rod_cases():
    """The cases whose soft teeth are rods, in words."""
    return ", ".join(f"the {case} with the {' and '.join(v)} "
                     f"{'teeth' if len(v) > 1 else 'tooth'}"
                     for case, v in LARGE_DEFLECTION.items())


def invalid_runs(a):
    """(case, tooth, rpm, tip / L) of the sweep's modal runs past the small-deflection range."""
    return [(case, v, rpm, m["tip"]) for (case, v), by_rpm in sorted(a["table"].items())
            for rpm, m in sorted(by_rpm.items()) if not m["rod"] and m["tip"] > validity_fraction()]


def rod_paragraph(a, history_rpm):
    beyond = invalid_runs(a)
    check = ("No modal run of the sweep leaves the range." if not beyond else
             "Modal runs of the sweep past it (add them to `LARGE_DEFLECTION`): " +
             "; ".join(f"{c} {v} {r} rpm ({fmt3(t)} L)" for c, v, r, t in beyond) + ".")
    return (f"The modal tooth is a small-deflection beam, valid to a tip deflection of "
            f"{validity_fraction():g} L (the core warns past it). Where it bends further at some "
            f"speed, the tooth is the geometrically exact large-deflection rod "
            f"(`config/scenes/cases/large_deflection.yaml`, docs/large_deflection.md; its "
            f"automatic count of shape functions): {rod_cases()}. {check} The same cases at "
            f"{history_rpm} rpm with the modal tooth against the rod (largest tip deflection "
            f"over L; the stream is chaotic, its maxima compare one seed's kernels):")


def rod_table(a, history_rpm):
    """Peak forces and tip deflection of the rod runs and their modal reruns."""
    rows = []
    for (case, v), before in sorted(a["modal"].items()):
        now = a["table"].get((case, v), {}).get(history_rpm)
        if now is None:
            continue
        rows.append([case, v, f"{fmt3(now['peak_normal_N'])} / {fmt3(before['peak_normal_N'])}",
                     f"{fmt3(now['knead_N'])} / {fmt3(before['knead_N'])}",
                     f"{fmt3(now['tip'])} / {fmt3(before['tip'])}"])
    return markdown_table(["case", "tooth", "peak normal [N], rod / modal",
                           "peak tangential [N], rod / modal", "tip deflection / L, rod / modal"],
                          rows)


def write_findings(path, a, plots, rpms, history_rpm):
    convergence = (markdown_table(
        ["tooth"] + [f"{m} modes" for m in CONVERGENCE_MODES],
        [[v] + [" / ".join(fmt3(x) for x in a["convergence"][(v, m)]) for m in CONVERGENCE_MODES]
         for v in FLEXIBLE if (v, CONVERGENCE_MODES[0]) in a["convergence"]])
        if a["convergence"] else "Not run (--quick).")
    claims = [("Normal and tangential force peaks are not simultaneous", *claim_peaks(a)),
              ("Many sub-collisions per macro-collision from the tooth's vibration",
               *claim_subs(a)),
              ("A flexible tooth kneads with less force than a rigid one", *claim_knead(a))]
    lines = [
        "# Findings: the paper's three claims in this model", "",
        "Generated by `scripts/compare_teeth.py --findings`: every number on this page comes "
        "from that command (rerun it to regenerate the page and its plots). Cases: "
        "`config/scenes/{single_strike,knead,stream}.yaml` and the single strike with "
        "`config/scenes/cases/tip_strike.yaml`; teeth: `config/scenes/teeth/{rigid,"
        "spring_steel,nylon,polyurethane}.yaml` (values and sources in the files); drum "
        f"speeds {rpms[0]}-{rpms[-1]} rpm; {rod_cases()} as large-deflection rods (below); "
        "force peaks and their times from the core at every "
        "accepted step, at located maxima of the compliant normal forces and on both sides of "
        "every located event (steps near a tooth at most "
        f"{fmt3(a['sample_us'])} us); force histories sampled every {fmt3(a['sample_us'])} us near "
        "contacts; all contacts compliant (Hertz with Hunt-Crossley damping, Coulomb "
        "friction), integrated event-driven. The stream is one seed of a chaotic process (its "
        "kernels hit each other and the bars), so its numbers scatter from speed to speed: read "
        "them as trends. " + partial_paragraph(), "",
        "| claim | verdict |", "|---|---|"]
    lines += [f"| {title} | {verdict} |" for title, verdict, _ in claims]
    lines.append("")
    for i, (title, verdict, text) in enumerate(claims, 1):
        lines += [f"## Claim {i}: {title}: {verdict}", "", text, ""]
    lines += [
        "## Threshing force and Hertz contact time", "",
        agreement_paragraph(a), "",
        strike_table(a), "",
        "## Damage and detachment", "",
        "A kernel is damaged when the largest normal force of any of its contacts reaches the "
        "plastic threshold ({:g} N; fracture {:g} N). The knead kernel has no pedicel.".format(
            *damage_thresholds()), "",
        damage_table(a), "",
        "## Large deflection: where the tooth is a rod", "",
        rod_paragraph(a, history_rpm), "",
        rod_table(a, history_rpm), "",
        "## What the shear-corrected sections changed", "",
        rotation_paragraph(history_rpm), "",
        rotation_table(a, history_rpm), "",
        "## Modal convergence", "",
        f"Single strike at {history_rpm} rpm with 2 to 10 bending modes: peak normal force "
        "[N] / first contact [us] / sub-collisions per macro-collision. The scenes choose the "
        "count automatically (`modes: auto`) and carry the static correction of the truncated "
        "modes; their mode convergence is in [convergence.md](convergence.md).", "",
        convergence, "", "## Plots", ""]
    for name, caption in plots:
        lines += [f"### {caption}", "", f"![{caption}](findings/{name})", ""]
    path.write_text("\n".join(lines))
