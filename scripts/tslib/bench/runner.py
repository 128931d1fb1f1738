"""Run points: bench_work_precision points in parallel, pinned and cached; bounded runs."""
import concurrent.futures
import hashlib
import json
import os
import pathlib
import signal
import subprocess
import threading
import time

from tslib.bench.config import say
from tslib.cache import file_digest


class Runner:
    """Runs bench_work_precision points in parallel, one CPU per worker, with a result cache."""

    def __init__(self, bench_bin, jobs, cache_dir, use_cache=True):
        self.bench_bin = pathlib.Path(bench_bin)
        self.jobs = jobs
        self.cache_dir = pathlib.Path(cache_dir)
        self.cache_dir.mkdir(parents=True, exist_ok=True)
        self.use_cache = use_cache
        self.bin_digest = file_digest(self.bench_bin, "sha1")
        self.cpus = sorted(os.sched_getaffinity(0))
        self.free_cpus = list(self.cpus[:max(1, jobs)])
        self.cpu_lock = threading.Lock()
        self.pool = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs))
        self.ran = 0     # points run by this invocation
        self.cached = 0  # points taken from the cache
        self.process_wall_s = 0.0  # summed wall time of every point's process, run or cached

    def key(self, scene, args):
        h = hashlib.sha1(self.bin_digest.encode())
        h.update(file_digest(scene, "sha1").encode())
        for a in args:
            h.update(b"\0" + a.encode())
            if a.endswith(".yaml") and os.path.exists(a):
                h.update(file_digest(a, "sha1").encode())
        return h.hexdigest()

    def _run(self, label, scene, args, reps, budget_s, samples, time_limit_s):
        full = list(args) + ["--reps", str(reps), "--budget", str(budget_s),
                             "--samples", str(samples)]
        if time_limit_s:
            full += ["--time-limit", str(time_limit_s)]
        path = self.cache_dir / (self.key(scene, full) + ".json")
        if self.use_cache and path.exists():
            with open(path) as f:
                result = json.load(f)
            with self.cpu_lock:
                self.cached += 1
                self.process_wall_s += result.get("process_wall_s", 0.0)
            return result
        with self.cpu_lock:
            cpu = self.free_cpus.pop(0)
        try:
            tmp = path.with_suffix(".tmp")
            cmd = [str(self.bench_bin), str(scene)] + full + ["--cpu", str(cpu), "--out", str(tmp)]
            started = time.monotonic()
            proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if proc.returncode not in (0, 1) or not tmp.exists():
                raise RuntimeError(f"{label}: {' '.join(cmd)} failed ({proc.returncode}): "
                                   f"{proc.stderr.strip()}")
            with open(tmp) as f:
                result = json.load(f)
            # The process's own wall time (all repetitions and the sampled run), kept so that
            # a report from the cache can still say what a run from scratch costs.
            result["process_wall_s"] = time.monotonic() - started
            with open(tmp, "w") as f:
                json.dump(result, f)
            os.replace(tmp, path)
            with self.cpu_lock:
                self.ran += 1
                self.process_wall_s += result["process_wall_s"]
            say(f"  {label}: {result['status']}, {result['median_wall_s'] * 1e3:.1f} ms per run "
                f"(median of {len(result['wall_times_s'])}"
                f"{'' if result['completed'] else ', cut short at t = %g s' % result['sim_time_s']}"
                f"), wall {time.monotonic() - started:.1f} s")
            return result
        finally:
            with self.cpu_lock:
                self.free_cpus.append(cpu)

    def submit(self, label, scene, args, reps=1, budget_s=1e9, samples=200, time_limit_s=None):
        return self.pool.submit(self._run, label, scene, args, reps, budget_s, samples,
                                time_limit_s)


def knob_args(integrator, knob):
    if integrator == "event_driven":
        return ["--set", "integrator.type=event_driven", "--set", f"integrator.tolerance={knob:g}"]
    return ["--set", "integrator.type=time_stepping", "--set", f"integrator.dt={knob:g}"]


def run_bounded(cmd, env, timeout_s):
    """Runs cmd in its own session; (stdout, stderr), or (None, None) when it ran past
    timeout_s (its whole process group, roslaunch and the nodes included, is then stopped:
    SIGINT, then SIGKILL after 20 s)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    try:
        return proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        for sig, wait_s in ((signal.SIGINT, 20), (signal.SIGKILL, 20)):
            try:
                os.killpg(proc.pid, sig)
                proc.communicate(timeout=wait_s)
                break
            except (subprocess.TimeoutExpired, ProcessLookupError):
                continue
        return None, None
