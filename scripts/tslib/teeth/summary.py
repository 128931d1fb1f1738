"""The findings section of docs/threshing_findings.md (between the findings markers): the
verdicts with their key numbers, the key plots and the command."""
import math
import os
import pathlib

from tslib import markdown
from tslib.markdown import in_folder
from tslib.numbers import fmt3, fmt3_range
from tslib.teeth.cases import CASES, FLEXIBLE, FROZEN_CASES, VARIANTS, validity_fraction
from tslib.teeth.findings import (agreement_paragraph, claim_knead, claim_peaks, claim_subs,
                                  peaks_numbers, rod_cases)


# ------------------------------------------------------------------------------------------
# The findings section (docs/threshing_findings.md, between the findings markers).

# Key plots of the section: (file name, what it shows there).
README_PLOTS = [
    ("force_history_knead.png", "Claim 1: normal (blue) and tangential (red) tooth force on the "
     "kernel kneaded against the bar, each contact episode shaded"),
    ("sub_collisions.png", "Claim 2: sub-collisions per tooth macro-collision against drum "
     "speed"),
    ("knead_force.png", "Claim 3: knead force (peak tangential tooth force) against drum speed"),
    ("peak_forces.png", "Peak normal tooth force against drum speed, with the measured "
     "threshing force (band) and the damage thresholds")]


def duration(seconds):
    """A wall time for people: seconds below two minutes, else minutes."""
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"



def readme_section(a, rpms, docs_rel, n_runs, jobs, wall_s):
    """Markdown of the findings section (between the markers); docs_rel: the folder of
    findings.md relative to the section's page."""
    verdicts = [("1. The peaks of the normal and the tangential force are not simultaneous",
                 claim_peaks(a)[0]),
                ("2. One macro-collision holds many sub-collisions, caused by the tooth's "
                 "high-frequency vibration", claim_subs(a)[0]),
                ("3. A flexible tooth gives a smaller knead force than a rigid one",
                 claim_knead(a)[0])]

    # Claim 1.
    p = peaks_numbers(a)
    claim1 = (
        f"**Claim 1 ({verdicts[0][1]}).** The two peaks lie more than "
        f"{fmt3(a['threshold_us'])} us apart in {p['separated']} of {p['total']} tooth-kernel "
        f"contacts ({fmt3(100 * p['share'])} %); in {p['at_transition']} of them the tangential "
        "peak falls on a stick-slip transition: the contact sticks while the normal force "
        "rises, and the friction force is largest where it reaches mu N. Apart in at least "
        f"90 % of the contacts: {', '.join(p['mostly']) or 'none'}. The widest median "
        f"separation is {fmt3(p['widest'][0])} us ({p['widest'][1]}). Not apart in any contact: "
        f"{', '.join(p['never']) or 'none'}. Of all {p['together']} contacts whose peaks "
        f"coincide, {p['together_sliding']} slide at the normal peak, where Coulomb friction "
        "is mu N and peaks with N.")

    # Claim 2.
    subs = a["subs"]
    flexible = {k: s for k, s in subs.items() if k[1] != "rigid"}
    more = sum(s["more"] for s in flexible.values())
    fewer = sum(s["fewer"] for s in flexible.values())
    compared = sum(s["n"] for s in flexible.values())
    controlled = sum(s["n"] for (c, _), s in flexible.items() if c in FROZEN_CASES)
    by_bending = sum(s["by_bending"] for s in flexible.values())
    bending = [f"{c}/{v} ({s['by_bending']} of {s['n']} speeds)"
               for (c, v), s in flexible.items() if s["by_bending"] > 0]
    rigid = {c: s["mean"] for (c, v), s in subs.items() if v == "rigid"
             and not math.isnan(s["mean"])}
    rigid_several = [f"{c} {fmt3(m)}" for c, m in rigid.items() if m > 1]
    claim2 = (
        f"**Claim 2 ({verdicts[1][1]}).** Against the rigid tooth at the same case and speed, "
        f"a flexible tooth had more sub-collisions per macro-collision {more} times and fewer "
        f"{fewer} times out of {compared}. Extra sub-collisions caused by bending (more than "
        "both the rigid tooth and the same tooth frozen, without bending modes) appear in "
        f"{by_bending} of {controlled} controlled comparisons: "
        f"{', '.join(bending) or 'none'}. The rigid tooth itself averages more than one "
        f"sub-collision per macro-collision in {', '.join(rigid_several) or 'no case'}: the "
        "bar, the pedicel or the kernel's own spin bring the kernel back onto the tooth "
        "without any vibration. Where the compliant contact lasts through the tooth's "
        "vibration, the vibration shows as ripples on one episode's force rather than as "
        "separate sub-collisions.")

    # Claim 3.
    k = a["knead"]
    ratios = ", ".join(f"{v} {fmt3_range(k[v]['to_rigid'])}" for v in FLEXIBLE if v in k)
    frozen = ", ".join(f"{v} {fmt3_range(k[v]['frozen_to_rigid'])}" for v in FLEXIBLE if v in k)
    bent = ", ".join(f"{v} {fmt3_range(k[v]['to_frozen'])}" for v in FLEXIBLE if v in k)
    below = [v for v in FLEXIBLE if v in k and k[v]["to_rigid"][1] < 1.0]
    not_below = [v for v in FLEXIBLE if v in k and v not in below]
    claim3 = (
        f"**Claim 3 ({verdicts[2][1]}).** Knead force (peak tangential tooth force on the "
        "kernel wedged between the tooth and the concave bar, knead scene) of the flexible "
        f"tooth over the rigid one, {rpms[0]}-{rpms[-1]} rpm: {ratios or 'not run'}. Below the "
        f"rigid tooth at every speed: {', '.join(below) or 'none'}"
        + (f"; not at every speed: {', '.join(not_below)}" if not_below else "")
        + ". Two causes separate: the contact material (the "
        f"same tooth frozen over the rigid one: {frozen or '-'}) and the bending (flexible "
        f"over frozen: {bent or '-'}; below 1, the bending tooth gives way to the wedged "
        "kernel).")

    cases = [c for c in CASES if any(key[0] == c for key in a["table"])]
    teeth = [v for v in VARIANTS if any(key[1] == v for key in a["table"])]
    lines = [
        f"Generated by `scripts/compare_teeth.py --findings` from the built `simulate`: "
        f"{n_runs} simulations (cases {', '.join(cases)}; teeth {', '.join(teeth)}; "
        f"{rpms[0]}-{rpms[-1]} rpm; controls with frozen teeth; {rod_cases()} as "
        f"large-deflection rods, where the modal tooth bends past {validity_fraction():g} L), all "
        "contacts compliant, integrated event-driven. Force peaks and their "
        "times are the core's (every accepted step, the located maxima of compliant normal "
        "forces, and both sides of every located event). "
        f"This run took {duration(wall_s)} on {jobs} workers. The full report, with every "
        f"table and plot, is [`{in_folder(docs_rel, 'findings.md')}`]({in_folder(docs_rel, 'findings.md')}).",
        "",
        "```bash",
        "bash scripts/setup.sh                              # build",
        "/usr/bin/python3 scripts/compare_teeth.py --findings  "
        "# rewrites this section, docs/findings.md, docs/findings/*.png",
        "```", "",
        "| claim (Qian, Jin & Zhang 2017) | in this model |", "|---|---|"]
    lines += [f"| {title} | {verdict} |" for title, verdict in verdicts]
    lines += ["", claim1, "", claim2, "", claim3, "",
              "**Threshing force and contact time.** " + agreement_paragraph(a), ""]
    for name, caption in README_PLOTS:
        lines += [f"![{name}]({in_folder(docs_rel, 'findings/' + name)})", "", f"*{caption}.*", ""]
    return "\n".join(lines).rstrip("\n")


def write_summary(page, docs, a, rpms, n_runs, jobs, wall_s):
    """Rewrites the findings section of page (default: its page, docs/threshing_findings.md),
    with links to docs (the folder of findings.md) relative to the page; returns the page."""
    page = pathlib.Path(page) if page else markdown.page_of("findings")
    docs_rel = os.path.relpath(pathlib.Path(docs).resolve(), page.resolve().parent)
    return markdown.splice("findings", readme_section(a, rpms, docs_rel, n_runs, jobs, wall_s),
                           page)
