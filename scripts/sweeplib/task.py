"""The work of one run on a Dask worker: one `simulate` process on the resolved scene.

This module is shipped to the workers by value (cloudpickle), so a worker needs only Python,
python3-distributed and the simulate binary at the given path; it imports nothing from the
repository. The run's CPU time is the child's own (user + system from wait4), so that the
runner's overhead can be measured against it.
"""
import atexit
import hashlib
import os
import select
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time

# Per worker process: verified binaries, (path, size, mtime) -> sha256 (no lock: two threads
# hashing the same binary at once only repeat the work).
_VERIFIED = {}
# Per worker thread: its folder for the run files, (pid, thread id) -> path.
_FOLDERS = {}


def _binary_sha(path):
    st = os.stat(path)
    stamp = (path, st.st_size, st.st_mtime_ns)
    if stamp not in _VERIFIED:
        digest = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        _VERIFIED[stamp] = digest.hexdigest()
    return _VERIFIED[stamp]


def _worker_name():
    """host:pid:Dask worker name (workers that are threads of one process share the pid)."""
    name = f"{socket.gethostname()}:{os.getpid()}"
    try:
        from distributed import get_worker
        return f"{name}:{get_worker().name}"
    except (ImportError, ValueError):
        return name


def _read(path):
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return None


def _signal_name(number):
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def run_simulate(task):
    """Runs one simulation. task: key, scene (resolved YAML text), simulate (path), sha
    (expected sha256 of the binary), timeout_s, keep (extra outputs: events, forces).
    Returns a dict: key, status (ok, failed, crash, timeout, error), message, summary (JSON
    text), outcomes (CSV text), files (kept outputs), wall_s, cpu_s (the child's user + system
    time), worker (host:pid)."""
    started = time.perf_counter()
    result = {"key": task["key"], "status": "error", "message": "", "summary": None,
              "outcomes": None, "files": {}, "wall_s": 0.0, "cpu_s": 0.0,
              "worker": _worker_name()}
    try:
        sha = _binary_sha(task["simulate"])
    except OSError as e:
        result["message"] = f"cannot read simulate at {task['simulate']}: {e.strerror}"
        return result
    if sha != task["sha"]:
        result["message"] = (f"simulate at {task['simulate']} on this worker is not the "
                             f"client's binary (sha256 {sha[:12]} != {task['sha'][:12]})")
        return result
    try:
        _execute(task, _thread_folder(), result)
    except Exception as e:  # e.g. the binary vanished: this run's error, not the batch's
        result["status"], result["message"] = "error", f"{type(e).__name__}: {e}"
    result["wall_s"] = time.perf_counter() - started
    return result


def _thread_folder():
    """This thread's folder for its runs' files, made once (under $TMPDIR if set, else in
    memory where /dev/shm exists) and removed at exit: a folder made and removed per run costs
    milliseconds on some file systems, during which the worker would idle."""
    key = (os.getpid(), threading.get_ident())
    folder = _FOLDERS.get(key)
    if folder is None or not os.path.isdir(folder):
        base = os.environ.get("TMPDIR") or \
            ("/dev/shm" if os.access("/dev/shm", os.W_OK) else None)
        folder = tempfile.mkdtemp(prefix="sweep-run-", dir=base)
        atexit.register(shutil.rmtree, folder, True)
        _FOLDERS[key] = folder
    for name in os.listdir(folder):  # no output of the previous run may be taken for this one's
        os.unlink(os.path.join(folder, name))
    return folder


def _wait_exit(proc, timeout_s):
    """Whether the child exits within timeout_s, without reaping it (wait4 then reads its
    resource usage): a poll on a pidfd (Linux >= 5.3), else a timer thread."""
    try:
        fd = os.pidfd_open(proc.pid)
    except (AttributeError, OSError):
        fired = []
        timer = threading.Timer(timeout_s, lambda: fired.append(proc.kill()))
        timer.start()
        os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)
        timer.cancel()
        return not fired
    try:
        poller = select.poll()
        poller.register(fd, select.POLLIN)
        return bool(poller.poll(timeout_s * 1000.0))
    finally:
        os.close(fd)


def _execute(task, folder, result):
    scene = os.path.join(folder, "scene.yaml")
    with open(scene, "w") as f:
        f.write(task["scene"])
    summary, outcomes = os.path.join(folder, "summary.json"), os.path.join(folder, "outcomes.csv")
    command = [task["simulate"], scene, "--summary", summary, "--outcomes", outcomes, "--quiet"]
    for name in task["keep"]:
        command += [f"--{name}", os.path.join(folder, f"{name}.csv")]
    with open(os.path.join(folder, "stderr.txt"), "w+") as err:
        proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=err)
        timed_out = not _wait_exit(proc, task["timeout_s"])
        if timed_out:
            proc.kill()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read().strip()
    result["cpu_s"] = usage.ru_utime + usage.ru_stime
    result["summary"] = _read(summary)
    result["outcomes"] = _read(outcomes)
    for name in task["keep"]:
        result["files"][name] = _read(os.path.join(folder, f"{name}.csv"))
    code = proc.returncode
    if timed_out:
        result["status"] = "timeout"
        result["message"] = f"no result after {task['timeout_s']:g} s; killed"
    elif code < 0:
        result["status"] = "crash"
        result["message"] = f"simulate killed by {_signal_name(-code)}" + \
            (f": {stderr[-500:]}" if stderr else "")
    elif code == 0 and result["summary"] is not None:
        result["status"] = "ok"
    elif code == 1 and result["summary"] is not None:
        result["status"] = "failed"
        result["message"] = stderr[-500:] if stderr else "status failed"
    else:
        result["status"] = "error"
        result["message"] = f"exit status {code}" + (f": {stderr[-500:]}" if stderr else "")


def run_batch(tasks, topic):
    """Runs a batch of runs on one worker, publishing each result at once (Dask Pub/Sub topic
    `topic`, to the client), so that a worker that dies loses only its current run. Runs
    whose keys are in the client's Variable `topic`-done (set when a worker left) are skipped:
    a batch rerun after a worker died does not redo the runs that worker finished. Returns the
    keys it ran."""
    from distributed import Pub, Variable

    try:
        done = set(Variable(topic + "-done").get(timeout=10))
    except Exception:  # no answer: run everything (duplicates are ignored by the client)
        done = set()
    pub = Pub(topic)
    ran = []
    for task in tasks:
        if task["key"] in done:
            continue
        pub.put(run_simulate(task))
        ran.append(task["key"])
    return ran
