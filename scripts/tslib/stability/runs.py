"""Running simulate on a hard case (wall time, resident memory, summary) and the properties
of one run."""
import json
import os
import subprocess
import tempfile
import time

from tslib.stability.scenes import HARD_DIR, num, penetration_bound


# ---------------------------------------------------------------------------------------------
# Running simulate.

def resident_kb(pid):
    """VmRSS of a running process [kB], or None once it has gone."""
    try:
        with open("/proc/%d/status" % pid) as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def run_simulate(simulate, scene, integrator, duration_s):
    """One run: the summary (dict), the wall time and the resident-memory samples (t, kB)."""
    with tempfile.TemporaryDirectory() as tmp:
        summary_path = os.path.join(tmp, "summary.json")
        # Contacts are sampled every millisecond only: simulate's default (every microsecond
        # near a contact) would make every sample a step and hide the integrator's own rate.
        cmd = [simulate, os.path.join(HARD_DIR, scene.file), "--quiet",
               "--summary", summary_path, "--sample-interval", "1e-3"]
        for o in scene.overrides:
            cmd += ["--set", o]
        cmd += ["--duration", repr(duration_s), "--integrator", integrator]
        start = time.monotonic()
        with tempfile.TemporaryFile(mode="w+") as err:
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, text=True)
            memory = []
            while True:
                kb = resident_kb(proc.pid)
                if kb is not None:
                    memory.append((time.monotonic() - start, kb))
                try:
                    proc.wait(timeout=0.2 if time.monotonic() - start < 10 else 1.0)
                    break
                except subprocess.TimeoutExpired:
                    pass
            wall = time.monotonic() - start
            err.seek(0)
            stderr = err.read()
        summary = None
        if os.path.exists(summary_path):
            with open(summary_path) as f:
                summary = json.load(f)
        return proc.returncode, summary, wall, memory, stderr.strip()


def memory_growth_kb(memory):
    """Growth of the resident size over the run after its first tenth (allocations while
    warming up) [kB]: the largest sample minus the sample at 10 % of the wall time."""
    if len(memory) < 4:
        return 0
    t_end = memory[-1][0]
    early = next(kb for t, kb in memory if t >= 0.1 * t_end)
    return max(kb for _, kb in memory) - early


def without_wall_time(summary):
    out = dict(summary)
    out.pop("wall_time_s", None)
    return out


# ---------------------------------------------------------------------------------------------
# The properties of one run.

def evaluate(scene, doc, integrator, duration_s, code, summary, memory, rerun_same):
    """(name, passed, detail) for every property of one run."""
    props = []
    if summary is None:
        return [("ok", False, "no summary (exit %d)" % code)]
    status = summary["status"]
    props.append(("finite", code == 0 and status == "ok", status))
    # Progress: the run reached its end; bounded steps per simulated second.
    dt = num(doc.get("integrator", {}), "dt", "integrator.dt")
    sim = summary["sim_time_s"]
    rate = summary["steps"] / sim if sim > 0 else float("inf")
    bound = scene.ed_steps_per_s if integrator == "event_driven" else 1.0 / dt + 1
    props.append(("progress", abs(sim - duration_s) <= 0.5 * dt and rate <= bound,
                  "%.3g steps/s (bound %.3g)" % (rate, bound)))
    # No impact raises the energy; no gain beyond the drive's work over the run.
    gain_impact = summary["max_energy_gain_at_impact_J"]
    gain_run = summary["energy_final_J"] - summary["energy_initial_J"] - summary["drive_work_J"]
    props.append(("impact energy", gain_impact <= scene.energy_tol_j, "%.2e J" % gain_impact))
    props.append(("energy balance", gain_run <= scene.energy_tol_j, "%.2e J" % gain_run))
    # Penetration.
    pen = summary["max_penetration_m"]
    pen_bound = penetration_bound(scene, doc, integrator)
    props.append(("penetration", pen <= pen_bound, "%.2e m (bound %.2e)" % (pen, pen_bound)))
    # Memory flat: less than 2 MB of growth after the first tenth of the run.
    growth = memory_growth_kb(memory)
    props.append(("memory", growth <= 2048, "%+d kB" % growth))
    # Bit-identical rerun of a shortened run.
    props.append(("rerun", rerun_same, "identical" if rerun_same else "differs"))
    for name, check in scene.checks:
        ok, detail = check(scene, doc, summary, integrator)
        props.append((name, ok, detail))
    return props
