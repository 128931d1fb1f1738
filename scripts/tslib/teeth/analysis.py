"""Numbers from the tooth comparison's runs: per-run metrics, stick-slip, episodes, and the
whole analysis (analyse)."""
import math

import numpy as np

from tslib.teeth.cases import FLEXIBLE, VARIANTS


# ------------------------------------------------------------------------------------------
# Numbers from the runs.

def touched(kernels):
    """Outcome entries of the kernels a tooth touched."""
    return [k for k in kernels if k["time_of_peak_normal_s"] is not None]


def stick_slip_times(run):
    """Times [s] of the stick <-> slip transitions of every tooth contact, per kernel."""
    times = {}
    for e in run.events():
        if e["kind"] == "tooth_kernel" and {e["from"], e["to"]} == {"stick", "slip"}:
            times.setdefault(int(e["b"]), set()).add(float(e["t_s"]))
    return times


def state_at(tooth_events, kernel, t_s):
    """State (stick, slip, ...) of a kernel's tooth contact at time t_s: the `from` state of the
    first of its tooth events after t_s (the compliant law enters stick or slip without an
    event, so the event before t_s may still say `impact`); None without a later event."""
    return next((e["from"] for e in tooth_events
                 if int(e["b"]) == kernel and float(e["t_s"]) > t_s), None)


def metrics(run):
    """Per-run numbers for the tables, plots and findings."""
    kernels = run.kernels()
    hit = touched(kernels)
    transitions = stick_slip_times(run)
    tooth_events = [e for e in run.events() if e["kind"] == "tooth_kernel"]
    macros = sum(k["macro_collisions"] for k in kernels)
    subs = sum(k["sub_collisions"] for k in kernels)
    return {
        "peak_normal_N": max((k["peak_normal_force_N"] for k in hit), default=0.0),
        "knead_N": max((k["peak_tangential_force_N"] for k in hit), default=0.0),
        "max_contact_N": max(k["max_contact_force_N"] for k in kernels),
        "subs_per_macro": subs / macros if macros else float("nan"),
        "separations_us": [1e6 * k["peak_separation_s"] for k in hit],
        # Whether each touched kernel's tangential peak falls on a stick-slip transition (the
        # same time to the last bit: both are the time of one accepted step).
        "peak_at_transition": [k["time_of_peak_tangential_s"] in transitions.get(k["kernel"], ())
                               for k in hit],
        "state_at_normal_peak": [state_at(tooth_events, k["kernel"], k["time_of_peak_normal_s"])
                                 for k in hit],
        "damaged": sum(k["damage"] != "none" for k in kernels) / len(kernels),
        "detached": sum(k["detached"] for k in kernels) / len(kernels),
        "tip": run.summary()["max_tip_deflection_ratio"],
        "rod": run.rod(),
    }


def first_tooth_episode(run):
    """Duration [us] and approach speed [m/s] of the first tooth-kernel contact episode."""
    start = None
    for e in run.events():
        if e["kind"] != "tooth_kernel":
            continue
        if start is None and e["from"] == "separated" and e["to"] == "impact":
            start = float(e["t_s"])
        elif start is not None and e["is_impact"] == "1":
            return 1e6 * (float(e["t_s"]) - start), -float(e["vn_before_mps"])
    return float("nan"), float("nan")


def tooth_episodes(run, kernel):
    """(start, end) [ms] of every tooth contact episode (sub-collision) of one kernel."""
    episodes, start = [], None
    for e in run.events():
        if e["kind"] != "tooth_kernel" or int(e["b"]) != kernel:
            continue
        if e["from"] == "separated" and e["to"] == "impact":
            start = 1e3 * float(e["t_s"])
        elif e["is_impact"] == "1" and start is not None:
            episodes.append((start, 1e3 * float(e["t_s"])))
            start = None
    return episodes


def nan_mean(values):
    values = [v for v in values if not math.isnan(v)]
    return float(np.mean(values)) if values else float("nan")


def ratio_range(numerators, denominators):
    """(min, max) of numerator / denominator over the speeds both have (nan without any)."""
    ratios = [numerators[r] / denominators[r] for r in numerators
              if r in denominators and denominators[r] > 0]
    return (min(ratios), max(ratios)) if ratios else (float("nan"), float("nan"))


def analyse(runs, sample_us):
    """Every number the report and the findings state."""
    table, frozen, euler, modal = {}, {}, {}, {}
    for run in runs:
        if run.group == "sweep":
            table.setdefault((run.case, run.variant), {})[run.rpm] = metrics(run)
        elif run.group == "frozen":
            frozen.setdefault((run.case, run.variant), {})[run.rpm] = metrics(run)
        elif run.group == "euler_bernoulli":
            euler[(run.case, run.variant)] = metrics(run)
        elif run.group == "modal":
            modal[(run.case, run.variant)] = metrics(run)
    a = {"table": table, "frozen": frozen, "euler": euler, "modal": modal, "sample_us": sample_us,
         "threshold_us": 2 * sample_us}

    # Claim 1: share of touched kernels whose two peaks lie more than two sampling intervals
    # apart (simulate lands on every sample time near a tooth, so the interval bounds the
    # integrator's steps there and thus the resolution of the peak times).
    a["separation"] = {}
    for key, by_rpm in table.items():
        seps = [abs(s) for m in by_rpm.values() for s in m["separations_us"]]
        at_transition = [t for m in by_rpm.values() for t in m["peak_at_transition"]]
        states = [st for m in by_rpm.values() for st in m["state_at_normal_peak"]]
        a["separation"][key] = {
            "n": len(seps),
            "separated": sum(s > a["threshold_us"] for s in seps),
            "separated_at_transition": sum(s > a["threshold_us"] and t
                                           for s, t in zip(seps, at_transition)),
            "together_sliding": sum(s <= a["threshold_us"] and st == "slip"
                                    for s, st in zip(seps, states)),
            "median_us": float(np.median(seps)) if seps else float("nan")}

    # Claim 2: sub-collisions per macro-collision against the rigid tooth and the frozen tooth.
    a["subs"] = {}
    for (case, variant), by_rpm in table.items():
        rigid = table.get((case, "rigid"), {})
        still = frozen.get((case, variant), {})
        more = fewer = caused = compared = 0
        for rpm, m in by_rpm.items():
            if rpm not in rigid or math.isnan(m["subs_per_macro"] + rigid[rpm]["subs_per_macro"]):
                continue
            compared += 1
            more += m["subs_per_macro"] > rigid[rpm]["subs_per_macro"]
            fewer += m["subs_per_macro"] < rigid[rpm]["subs_per_macro"]
            caused += (rpm in still and m["subs_per_macro"] > still[rpm]["subs_per_macro"]
                       and m["subs_per_macro"] > rigid[rpm]["subs_per_macro"])
        a["subs"][(case, variant)] = {
            "mean": nan_mean([m["subs_per_macro"] for m in by_rpm.values()]),
            "more": more, "fewer": fewer, "by_bending": caused, "n": compared,
            "rigid_max": max((m["subs_per_macro"] for m in by_rpm.values()
                              if not math.isnan(m["subs_per_macro"])), default=float("nan"))}

    # Claim 3: knead force on the knead scene against the rigid tooth and the frozen tooth.
    knead = {v: {r: m["knead_N"] for r, m in table.get(("knead", v), {}).items()}
             for v in VARIANTS}
    knead_frozen = {v: {r: m["knead_N"] for r, m in frozen.get(("knead", v), {}).items()}
                    for v in FLEXIBLE}
    a["knead"] = {v: {"to_rigid": ratio_range(knead[v], knead["rigid"]),
                      "to_frozen": ratio_range(knead[v], knead_frozen[v]),
                      "frozen_to_rigid": ratio_range(knead_frozen[v], knead["rigid"])}
                  for v in FLEXIBLE if knead[v]}

    # Threshing force and contact time of the single strike.
    a["strike"] = {}
    for run in runs:
        if run.group == "sweep" and run.case == "single_strike":
            duration_us, speed_mps = first_tooth_episode(run)
            a["strike"][(run.variant, run.rpm)] = {
                "peak_N": table[(run.case, run.variant)][run.rpm]["peak_normal_N"],
                "contact_us": duration_us, "speed_mps": speed_mps}

    # Modal convergence of the single strike.
    a["convergence"] = {}
    for run in runs:
        if run.group == "convergence":
            duration_us, _ = first_tooth_episode(run)
            m = metrics(run)
            a["convergence"][(run.variant, run.modes)] = (m["peak_normal_N"], duration_us,
                                                          m["subs_per_macro"])
    return a
