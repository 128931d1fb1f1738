"""The measurements: errors against a reference, the references, the knob sweeps, the
scaling runs and the node budget."""
import math
import os
import pathlib
import re

from tslib import BENCH_DIR, ROOT
from tslib.bench.config import (HEADLINE, METRICS, METRIC_LABELS, NODE_RTF_PASS, NODE_SETTINGS,
                                NODE_TIMEOUT_S, SCALING_SETTINGS, SCENES, say)
from tslib.bench.runner import knob_args, run_bounded
from tslib.bench.scenes import stream_override_file
from tslib.binaries import BIN_DIR
from tslib.numbers import fmt, rel_error


# ------------------------------------------------------------------------------------------
# Error metrics against a reference.


def errors(run, ref):
    """Relative errors of `run` against `ref` (impacts: absolute count difference)."""
    dv2 = vr2 = dp2 = pr2 = 0.0
    for k, kr in zip(run["kernels"], ref["kernels"]):
        a = kr["semi_axis_a_m"]
        for i in range(2):
            dv2 += (k["velocity_mps"][i] - kr["velocity_mps"][i]) ** 2
            vr2 += kr["velocity_mps"][i] ** 2
            dp2 += (k["position_m"][i] - kr["position_m"][i]) ** 2
            pr2 += (kr["position_m"][i] - kr["initial_position_m"][i]) ** 2
        dp2 += (a * (k["angle_rad"] - kr["angle_rad"])) ** 2
        pr2 += (a * (kr["angle_rad"] - kr["initial_angle_rad"])) ** 2
    e = {"exit_velocity": math.sqrt(dv2 / vr2) if vr2 > 0 else math.sqrt(dv2),
         "pose": math.sqrt(dp2 / pr2) if pr2 > 0 else math.sqrt(dp2),
         "peak_normal": rel_error(run["peak_normal_force_N"], ref["peak_normal_force_N"]),
         "peak_tangential": rel_error(run["peak_tangential_force_N"], ref["peak_tangential_force_N"]),
         "impulse": rel_error(run["total_normal_impulse_Ns"], ref["total_normal_impulse_Ns"]),
         "impacts": abs(run["impacts"] - ref["impacts"])}
    # Tip deflection history: RMS difference over every tooth and sample, relative to the RMS
    # of the reference (rigid teeth: none).
    d2 = w2 = 0.0
    count = 0
    if len(run["sample_times_s"]) == len(ref["sample_times_s"]):
        for tip, tip_ref in zip(run["tip_deflection_m"], ref["tip_deflection_m"]):
            for w, wr in zip(tip, tip_ref):
                d2 += (w - wr) ** 2
                w2 += wr ** 2
                count += 1
    e["tip_rms"] = math.sqrt(d2 / w2) if w2 > 0 else None
    e["headline"] = max(e[m] for m in HEADLINE)
    return e


def fit_slope(xs, ys):
    """Least-squares slope of log y against log x over the positive pairs (None if < 2)."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x > 0 and y and y > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx > 0 else None



# ------------------------------------------------------------------------------------------
# Stages.

def bench_scene_args(name, gen_dir):
    file, count, _ = SCENES[name]
    args = []
    if count is not None:
        args = ["--set-file", str(stream_override_file(count, gen_dir))]
    return BENCH_DIR / file, args


def samples_for(name, cfg):
    """Tip deflection samples: none for the costly stream (its sampled run would double it)."""
    return 0 if name == "stream" else cfg["samples"]


def modes_of(scene_path):
    import yaml
    with open(scene_path) as f:
        return int(yaml.safe_load(f)["teeth"][0].get("modes", 4))


def references(runner, names, cfg, gen_dir):
    """ED and TS references, and the ED reference with more modes, per scene."""
    futures = {}
    for name in names:
        scene, args = bench_scene_args(name, gen_dir)
        ref_dt = cfg["stream_ref_dt"] if name == "stream" else cfg["ref_dt"]
        samples = samples_for(name, cfg)
        futures[(name, "ed")] = runner.submit(
            f"{name} reference, event-driven tolerance {cfg['ref_tol']:g}", scene,
            args + knob_args("event_driven", cfg["ref_tol"]), samples=samples)
        futures[(name, "ts")] = runner.submit(
            f"{name} cross-check, time stepping dt {ref_dt:g}", scene,
            args + knob_args("time_stepping", ref_dt), samples=samples)
        n = modes_of(scene)
        if n > 0:
            for extra in cfg["mode_steps"]:
                futures[(name, f"modes+{extra}")] = runner.submit(
                    f"{name} reference with {n + extra} modes", scene,
                    args + knob_args("event_driven", cfg["ref_tol"]) +
                    ["--set", f"teeth.*.modes={n + extra}"], samples=samples)
    refs = {}
    for (name, kind), fut in futures.items():
        refs.setdefault(name, {})[kind] = fut.result()
    for name in names:
        r = refs[name]
        r["modes"] = modes_of(bench_scene_args(name, gen_dir)[0])
        r["agreement"] = errors(r["ts"], r["ed"])
        r["mode_change"] = {k: errors(r["ed"], v) for k, v in r.items()
                            if isinstance(k, str) and k.startswith("modes+")}
        a = r["agreement"]
        say(f"{name}: time stepping dt {r['ts']['dt_s']:g} against event-driven tolerance "
            f"{r['ed']['tolerance']:g}: " +
            ", ".join(f"{METRIC_LABELS[m]} {fmt(a[m])}" for m in METRICS))
        for k, e in r["mode_change"].items():
            say(f"{name}: {r['modes']} modes against {r['modes'] + int(k[6:])}: " +
                ", ".join(f"{METRIC_LABELS[m]} {fmt(e[m])}" for m in METRICS))
    return refs


def sweeps(runner, names, cfg, refs, gen_dir):
    futures = []
    for name in names:
        scene, args = bench_scene_args(name, gen_dir)
        steps = cfg["stream_steps"] if name == "stream" else cfg["steps"]
        for integrator, knobs in (("event_driven", cfg["tolerances"]), ("time_stepping", steps)):
            for knob in knobs:
                label = f"{name} {integrator} {knob:g}"
                futures.append((name, integrator, knob, runner.submit(
                    label, scene, args + knob_args(integrator, knob),
                    reps=1 if name == "stream" else cfg["reps"], budget_s=cfg["budget"],
                    samples=samples_for(name, cfg))))
    rows = []
    for name, integrator, knob, fut in futures:
        run = fut.result()
        e = errors(run, refs[name]["ed"])
        rows.append({"scene": name, "integrator": integrator, "knob": knob,
                     "status": run["status"], "deterministic": run["deterministic"],
                     "steps": run["steps"], "reps": len(run["wall_times_s"]),
                     "wall_per_sim_s": run["wall_per_sim_s"],
                     "real_time_factor": 1.0 / run["wall_per_sim_s"],
                     **{m: e[m] for m in METRICS}, "headline": e["headline"]})
    return rows


def scaling(runner, cfg, gen_dir):
    futures = []
    for integrator, settings in SCALING_SETTINGS.items():
        for series, idle in (("kernels", False), ("idle kernels", True)):
            for count in cfg["kernel_counts"]:
                args = ["--set-file", str(stream_override_file(count, gen_dir, idle))] + settings
                futures.append((series, integrator, count, runner.submit(
                    f"scaling: {count} {series}, {integrator}", BENCH_DIR / "stream.yaml", args,
                    reps=cfg["scaling_reps"], budget_s=cfg["budget"], samples=0,
                    time_limit_s=cfg["time_limit"])))
        for modes in cfg["mode_counts"]:
            args = settings + ["--set", f"teeth.*.modes={modes}"]
            futures.append(("modes", integrator, modes, runner.submit(
                f"scaling: {modes} modes, {integrator}", BENCH_DIR / "single_strike.yaml", args,
                reps=cfg["reps"], budget_s=cfg["budget"], samples=0)))
    rows = []
    for series, integrator, n, fut in futures:
        run = fut.result()
        struck = sum(1 for k in run["kernels"] if k["impacts"] > 0)
        rows.append({"series": series, "integrator": integrator, "n": n,
                     "status": run["status"], "completed": run["completed"],
                     "sim_time_s": run["sim_time_s"], "steps": run["steps"],
                     "wall_per_sim_s": run["wall_per_sim_s"],
                     "real_time_factor": 1.0 / run["wall_per_sim_s"],
                     "impacts": run["impacts"], "kernels_with_impacts": struck})
    return rows


def node_budget(cfg, gen_dir, node_counts):
    """The node's measured real-time factor on the stream at growing kernel counts, per
    integrator (stopping at the first count below the pass mark); None without the node."""
    setup = ROOT / ".build" / "ws" / "devel" / "setup.bash"
    if not (BIN_DIR / "threshing_sim_node").exists() or not setup.exists():
        say("node budget: threshing_sim_node not built, skipped")
        return None
    results = []
    port = 11600 + os.getpid() % 200
    for label, (integrator, settings) in NODE_SETTINGS.items():
        for count in node_counts:
            row = node_try(cfg, gen_dir, setup, port, integrator, settings, count)
            if row is None:
                break
            row["setting"] = label
            results.append(row)
            if row["rtf"] < NODE_RTF_PASS:
                break
    return results



def node_try(cfg, gen_dir, setup, port, integrator, settings, count):
    """One node run at real time: its final summary line parsed, or None."""
    import yaml
    kernels = stream_override_file(count, gen_dir)
    # The node reads the scene from a file: the stream scene with these kernels inlined.
    tag = "_".join(a.split("=")[1] for a in settings if "=" in a)
    scene = pathlib.Path(gen_dir) / f"stream_node_{tag}_{count}.yaml"
    with open(BENCH_DIR / "stream.yaml") as f:
        tree = yaml.safe_load(f)
    with open(kernels) as f:
        tree["kernels"] = yaml.safe_load(f)["kernels"]
    # The integrator of SCALING_SETTINGS (the node's default step follows from it).
    for key, value in (a.split("=") for a in settings if "=" in a):
        tree["integrator"][key.split(".")[1]] = float(value) if key.endswith(
            ("tolerance", "dt")) else value
    with open(scene, "w") as f:
        yaml.safe_dump(tree, f)
    cmd = (f"source {setup} && export ROS_IP=127.0.0.1 "
           f"ROS_MASTER_URI=http://127.0.0.1:{port} && "
           f"roslaunch -p {port} --no-summary threshing_sim simulator.launch scene:={scene} "
           f"clock_mode:=wall real_time_factor:=1 duration:={cfg['node_duration']} "
           "status_period:=0")
    env = dict(os.environ, PATH="/usr/bin:" + os.environ.get("PATH", ""))
    stdout, stderr = run_bounded(["bash", "-c", cmd], env, NODE_TIMEOUT_S)
    if stdout is None:
        say(f"node budget, {integrator}: {count} kernels: no summary within "
            f"{NODE_TIMEOUT_S:.0f} s (real-time factor below "
            f"{cfg['node_duration'] / NODE_TIMEOUT_S:.2g})")
        return None
    text = stdout + stderr
    m = re.search(r"simulated ([0-9.]+) s in ([0-9.]+) s of wall time \(real-time factor "
                  r"([0-9.eE+-]+) overall\).*?(\d+) overruns", text)
    if not m:
        say(f"node budget: {count} kernels: no summary line\n"
            f"{text[-800:]}")
        return None
    rtf = float(m.group(3))
    say(f"node budget, {tag}: {count} kernels: real-time factor {rtf:.3g} "
        f"({m.group(1)} s simulated in {m.group(2)} s, {m.group(4)} overruns)")
    return {"integrator": integrator, "n": count, "sim_s": float(m.group(1)),
            "wall_s": float(m.group(2)), "rtf": rtf, "overruns": int(m.group(4))}
