"""The work of the runs on a worker: one `simulate --batch` process runs many runs, each
result handed on as its run ends (run_tasks, run_batch on Dask, run_single for one run).

This module is shipped to the workers by value (cloudpickle), so a worker needs only Python,
python3-distributed and the simulate binary at the given path; it imports nothing from the
repository. A run's CPU time is the one simulate measures for it in its thread (thread CPU
clock, from reading its line to its result); the batch processes' own CPU (user + system from
wait4) is counted apart, so that the runner's overhead can be measured against both.
"""
import atexit
import hashlib
import json
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


def _signal_name(number):
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _thread_folder():
    """This thread's folder for its batch processes' stderr, made once (under $TMPDIR if set,
    else in memory where /dev/shm exists) and removed at exit: a folder made and removed per
    batch costs milliseconds on some file systems, during which the worker would idle."""
    key = (os.getpid(), threading.get_ident())
    folder = _FOLDERS.get(key)
    if folder is None or not os.path.isdir(folder):
        base = os.environ.get("TMPDIR") or \
            ("/dev/shm" if os.access("/dev/shm", os.W_OK) else None)
        folder = tempfile.mkdtemp(prefix="sweep-run-", dir=base)
        atexit.register(shutil.rmtree, folder, True)
        _FOLDERS[key] = folder
    for name in os.listdir(folder):  # nothing of the previous batch may be taken for this one's
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


# ------------------------------------------------------------------------------------------
# Many runs per process: simulate --batch.

# A batch process that closed its output: the wait for its exit status [s].
EXIT_WAIT_S = 10.0


def _batch_line(task):
    line = {"id": task["key"], "scene_yaml": task["scene"], "args": task["args"],
            "return": ["summary", "outcomes", *task["keep"]]}
    if task.get("scene_name"):
        line["scene_name"] = task["scene_name"]
    return json.dumps(line) + "\n"


class _Runs:
    """The runs of one caller of run_tasks, in order: those it was given, then the batches
    that `more` hands over while its processes work. The next batch is fetched when a process
    is on its last run (every run before it answered), so that the process never waits for a
    line and a thread holds at most one batch that another thread could have taken."""

    def __init__(self, tasks, more):
        self.tasks = list(tasks)
        self.more = more
        self.ended = more is None  # no batch will follow
        self.stopped = False       # the current process ended: its feeder stops
        self.cond = threading.Condition()

    def fetch(self):
        """Appends the next batch (or marks the end)."""
        if self.ended:
            return
        batch = self.more()
        with self.cond:
            if batch:
                self.tasks.extend(batch)
            else:
                self.ended = True
            self.cond.notify_all()

    def due(self, i):
        """Run i, fetching the next batch when i is the last one known; None when none is
        left."""
        if i >= len(self.tasks) - 1:
            self.fetch()
        return self.tasks[i] if i < len(self.tasks) else None

    def to_feed(self, i):
        """Run i once it is known; None at the end or when the process stopped."""
        with self.cond:
            while i >= len(self.tasks) and not self.ended and not self.stopped:
                self.cond.wait()
            return self.tasks[i] if i < len(self.tasks) and not self.stopped else None

    def stop(self, stopped=True):
        with self.cond:
            self.stopped = stopped
            self.cond.notify_all()


def _feed(proc, runs, first):
    """Writes the lines of runs[first:] to the batch process as they become known (in a
    thread: the process answers while it reads, and both pipes are bounded)."""
    try:
        i = first
        while True:
            task = runs.to_feed(i)
            if task is None:
                break
            proc.stdin.write(_batch_line(task).encode())
            i += 1
            if i >= len(runs.tasks):  # the process may be waiting for this line
                proc.stdin.flush()
        proc.stdin.close()
    except (BrokenPipeError, OSError, ValueError):
        pass  # the process died or was killed: its reader records why


def _line_result(task, line, worker):
    """A run's result from its line of simulate --batch output."""
    result = {"key": task["key"], "status": "error", "message": "", "summary": None,
              "outcomes": None, "files": {}, "wall_s": 0.0, "cpu_s": 0.0, "worker": worker}
    try:
        answer = json.loads(line)
    except ValueError:
        result["message"] = f"unreadable simulate --batch line: {line[:300]!r}"
        return result
    if answer.get("id") != task["key"]:
        result["message"] = f"simulate --batch answered {answer.get('id')!r} for {task['key']}"
        return result
    result.update(wall_s=answer.get("wall_s", 0.0), cpu_s=answer.get("cpu_s", 0.0),
                  summary=answer.get("summary"), outcomes=answer.get("outcomes"))
    result["files"] = {name: answer.get(name) for name in task["keep"]}
    status, message = answer.get("status"), answer.get("message", "")
    if status == "ok" and result["summary"] is not None:
        result["status"] = "ok"
    elif status == "failed" and result["summary"] is not None:
        result["status"], result["message"] = "failed", message or "status failed"
    else:
        result["message"] = f"exit status {answer.get('exit')}: simulate: error: {message}"
    return result


def start_batch_process(simulate, stderr_path):
    """A `simulate --batch -` process reading its lines from a pipe and answering on one, its
    standard error into the file stderr_path: (process, that file, open)."""
    err = open(stderr_path, "w+")
    try:
        return subprocess.Popen([simulate, "--batch", "-"], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=err), err
    except OSError:
        err.close()
        raise


def _not_done(tasks, done_variable):
    """The tasks whose keys the client has not marked done (its Variable, set when a worker
    left, so that a rerun does not redo finished runs); all of them when it does not answer in
    10 s (duplicates are ignored by the client)."""
    try:
        done = set(done_variable.get(timeout=10))
    except Exception:
        done = set()
    return [task for task in tasks if task["key"] not in done]


class _BatchProcess:
    """One simulate --batch process over a list of tasks, read as it answers."""

    def __init__(self, simulate, folder, feed, runs=None):
        """feed(proc) writes the input (in a thread); runs, when given, is stopped at the end
        (its feeder waits on it)."""
        self.runs = runs
        self.proc, self.err = start_batch_process(simulate, os.path.join(folder, "stderr.txt"))
        self.feeder = threading.Thread(target=feed, args=(self.proc,), daemon=True)
        self.feeder.start()
        self.chunks = []  # output read but not yet returned; only the last may hold a newline
        self.eof = False
        self.poller = select.poll()
        self.poller.register(self.proc.stdout.fileno(), select.POLLIN | select.POLLHUP)

    def next_line(self, timeout_s):
        """The next output line (text), None at the end of the output, or False when none
        came within timeout_s."""
        deadline = time.monotonic() + timeout_s
        # Each chunk is searched once, so a line of many MB (kept forces) costs linear time.
        while not (self.chunks and b"\n" in self.chunks[-1]) and not self.eof:
            left = deadline - time.monotonic()
            if left <= 0 or not self.poller.poll(left * 1000.0):
                return False
            data = os.read(self.proc.stdout.fileno(), 1 << 20)
            self.eof = not data
            if data:
                self.chunks.append(data)
        if not (self.chunks and b"\n" in self.chunks[-1]):
            return None
        line, rest = b"".join(self.chunks).split(b"\n", 1)
        self.chunks = [rest] if rest else []
        return line.decode("utf-8", "replace")

    def finish(self, kill):
        """Kills the process (when asked, or when it does not exit after its output ended)
        and reaps it: (exit code, its CPU time [s], the end of its stderr)."""
        if kill or not _wait_exit(self.proc, EXIT_WAIT_S):
            self.proc.kill()
        if self.runs is not None:
            self.runs.stop()
        _, status, usage = os.wait4(self.proc.pid, 0)
        self.proc.returncode = os.waitstatus_to_exitcode(status)
        self.feeder.join(timeout=EXIT_WAIT_S)
        self.proc.stdout.close()
        self.err.seek(0)
        stderr = self.err.read().strip()[-500:]
        self.err.close()
        return self.proc.returncode, usage.ru_utime + usage.ru_stime, stderr


def _end_result(task, worker, code, stderr, timed_out):
    """The result of the run a batch process was on when it was killed or ended."""
    result = _error_result_for(task, worker)
    if timed_out:
        result["status"] = "timeout"
        result["message"] = f"no result after {task['timeout_s']:g} s; killed"
    elif code < 0:
        result["status"] = "crash"
        result["message"] = f"simulate killed by {_signal_name(-code)}" + \
            (f": {stderr}" if stderr else "")
    else:
        result["message"] = f"exit status {code}" + (f": {stderr}" if stderr else "") + \
            " (simulate --batch ended before this run's result)"
    return result


def _error_result_for(task, worker, message=""):
    return {"key": task["key"], "status": "error", "message": message, "summary": None,
            "outcomes": None, "files": {}, "wall_s": 0.0, "cpu_s": 0.0, "worker": worker}


def _run_process(runs, first, worker, publish, stats):
    """Runs runs[first:] in one batch process until it ends; a run past its timeout or the
    end of the process before a result stops it, with that run recorded. Returns the index
    after the last run it consumed (at least first + 1)."""
    runs.stop(False)
    batch = _BatchProcess(runs.tasks[first]["simulate"], _thread_folder(),
                          lambda proc: _feed(proc, runs, first), runs)
    i, timed_out = first, False
    started = time.perf_counter()
    while True:
        task = runs.due(i)
        if task is None:
            break
        line = batch.next_line(task["timeout_s"])
        if line is False:
            timed_out = True
            break
        if line is None:
            break
        publish(_line_result(task, line, worker))
        i += 1
    code, cpu_s, stderr = batch.finish(kill=timed_out)
    stats["process_cpu_s"] += cpu_s
    stats["process_wall_s"] += time.perf_counter() - started
    stats["processes"] += 1
    if i < len(runs.tasks):
        publish(_end_result(runs.tasks[i], worker, code, stderr, timed_out))
        i += 1
    return i


def run_tasks(tasks, publish, worker=None, more=None):
    """Runs the tasks (dicts: key, scene, simulate, sha, timeout_s, keep) in simulate --batch
    processes, calling publish(result) for each run as it ends (result: key, status, message,
    summary, outcomes, files, wall_s, cpu_s, worker); then, given `more` (a function returning
    the next list of tasks, empty when there are none), the batches it returns, in the same
    process. A run that crashes the process or passes its timeout is recorded so, and a new
    process takes the runs after it. worker: the name in the results (default host:pid:Dask
    worker name). Returns the batch processes' statistics: processes, process_cpu_s (user +
    system, wait4), process_wall_s."""
    stats = {"processes": 0, "process_cpu_s": 0.0, "process_wall_s": 0.0}
    runs = _Runs(tasks, more)
    if runs.due(0) is None:
        return stats
    worker = worker or _worker_name()
    first = runs.tasks[0]
    try:
        sha = _binary_sha(first["simulate"])
    except OSError as e:
        sha, message = None, f"cannot read simulate at {first['simulate']}: {e.strerror}"
    if sha is not None and sha != first["sha"]:
        message = (f"simulate at {first['simulate']} on this worker is not the client's "
                   f"binary (sha256 {sha[:12]} != {first['sha'][:12]})")
    if sha is None or sha != first["sha"]:
        i = 0
        while runs.due(i) is not None:
            publish(_error_result_for(runs.tasks[i], worker, message))
            i += 1
        return stats
    position = 0
    while runs.due(position) is not None:  # each process consumes at least one task
        try:
            position = _run_process(runs, position, worker, publish, stats)
        except Exception as e:  # e.g. the binary vanished: this run's error, not the batch's
            publish(_error_result_for(runs.tasks[position], worker, f"{type(e).__name__}: {e}"))
            position += 1
    return stats


# ------------------------------------------------------------------------------------------
# Validation first: a share of the runs held in one process (simulate --batch's hold, barrier
# and go), run only when every share is valid.

# The wait for a share's validation: the runs' timeout plus this much per run [s].
VALIDATE_S_PER_RUN = 0.1


def validate_timeout_s(tasks):
    """How long the validation of these runs (one share) may take [s]."""
    return max(t["timeout_s"] for t in tasks) + VALIDATE_S_PER_RUN * len(tasks)


def _write(proc, data, close=False):
    """Writes data to the process's input (and closes it); a process that died is left to its
    reader, which records why."""
    try:
        proc.stdin.write(data)
        proc.stdin.flush()
        if close:
            proc.stdin.close()
    except (BrokenPipeError, OSError, ValueError):
        pass


def _verdict(batch, n_runs, timeout_s):
    """The barrier's answer of a batch process holding n_runs: {"lines", "invalid": [{"id",
    "message"}]}, or {"error": why} (the process is then reaped) when it ended or said nothing
    else within timeout_s."""
    line = batch.next_line(timeout_s)
    if line:
        try:
            answer = json.loads(line)
        except ValueError:
            answer = None
        if isinstance(answer, dict) and answer.get("barrier") is True:
            return answer
    code, _, stderr = batch.finish(kill=True)
    why = (f"it answered {line[:300]!r}" if line else "no answer" if line is False else
           f"exit status {code}" if code >= 0 else f"killed by {_signal_name(-code)}")
    return {"error": f"simulate --batch gave no verdict on its {n_runs} runs within "
                     f"{timeout_s:g} s ({why})" + (f": {stderr}" if stderr else "")}


def run_share(tasks, publish, verdict, wait_go, worker=None):
    """Validation first, then the runs: one simulate --batch process reads, loads and compiles
    every task (dicts as for run_tasks) and answers whether they are valid; verdict(answer) gets
    that answer ({"lines", "invalid": [{"id", "message"}]} or {"error"}); wait_go() blocks until
    the runner decides and returns whether to run. Then the process runs the tasks with the
    models it compiled, publish(result) for each as it ends. A run that crashes the process or
    passes its timeout is recorded so, and the runs after it go to run_tasks (a new process;
    they were validated). Returns the processes' statistics as run_tasks does."""
    stats = {"processes": 0, "process_cpu_s": 0.0, "process_wall_s": 0.0}
    if not tasks:
        verdict({"lines": 0, "invalid": []})
        wait_go()
        return stats
    worker = worker or _worker_name()
    first = tasks[0]
    try:
        sha, message = _binary_sha(first["simulate"]), ""
    except OSError as e:
        sha, message = None, f"cannot read simulate at {first['simulate']}: {e.strerror}"
    if sha is not None and sha != first["sha"]:
        message = (f"simulate at {first['simulate']} on this worker is not the client's "
                   f"binary (sha256 {sha[:12]} != {first['sha'][:12]})")
    if message:
        verdict({"error": message})
        wait_go()
        return stats
    timeout_s = validate_timeout_s(tasks)
    started = time.perf_counter()
    text = "".join(['{"hold": true}\n', *map(_batch_line, tasks),
                    json.dumps({"barrier": round(timeout_s + 30.0, 3)}) + "\n"]).encode()
    batch = _BatchProcess(first["simulate"], _thread_folder(), lambda proc: _write(proc, text))
    answer = _verdict(batch, len(tasks), timeout_s)
    verdict(answer)
    go = wait_go() and "error" not in answer
    if "error" in answer:
        return stats
    batch.feeder.join(timeout=EXIT_WAIT_S)
    _write(batch.proc, json.dumps({"go": go}).encode() + b"\n", close=True)
    i, timed_out = 0, False
    while go and i < len(tasks):
        line = batch.next_line(tasks[i]["timeout_s"])
        if line is False:
            timed_out = True
        if not line:
            break
        publish(_line_result(tasks[i], line, worker))
        i += 1
    code, cpu_s, stderr = batch.finish(kill=timed_out)
    stats["process_cpu_s"] += cpu_s
    stats["process_wall_s"] += time.perf_counter() - started
    stats["processes"] += 1
    if go and i < len(tasks):
        publish(_end_result(tasks[i], worker, code, stderr, timed_out))
        add_stats(stats, run_tasks(tasks[i + 1:], publish, worker))
    return stats


def add_stats(stats, more):
    """Adds the batch processes' statistics `more` to `stats`."""
    for name in ("processes", "process_cpu_s", "process_wall_s"):
        stats[name] += more.get(name, 0)


# Results of a Dask share are published in groups at most this far apart [s]: a message per
# result costs the worker, the scheduler and the client more than the result's own handling.
GROUP_S = 0.05


class _Grouped:
    """Results put one by one, published as {"results": [...]} at most GROUP_S apart (by a
    thread, so that a long run does not hold back the results before it) and at close()."""

    def __init__(self, pub):
        self.pub, self.items, self.lock = pub, [], threading.Lock()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def put(self, result):
        with self.lock:
            self.items.append(result)

    def flush(self):
        with self.lock:
            items, self.items = self.items, []
        if items:
            self.pub.put({"results": items})

    def _loop(self):
        while not self.done.wait(GROUP_S):
            self.flush()

    def close(self):
        self.done.set()
        self.thread.join(timeout=EXIT_WAIT_S)
        self.flush()


def run_dask_share(tasks, topic, share):
    """run_share on a Dask worker: the verdict published at once and the results in groups at
    most GROUP_S apart (Dask Pub/Sub topic `topic`; the verdict as {"verdict": share, ...}, the
    results as {"results": [...]}), the go read from the client's
    Variable `topic`-go. Runs whose keys are in the Variable `topic`-done (set when a worker
    left) are skipped: a share rerun after a worker died does not redo its finished runs.
    Returns run_share's statistics and the keys it ran."""
    from distributed import Pub, Variable

    pub = Pub(topic)
    todo = _not_done(tasks, Variable(topic + "-done"))
    limit_s = validate_timeout_s(tasks) + 30.0 if tasks else 30.0

    def wait_go():
        try:
            return bool(Variable(topic + "-go").get(timeout=limit_s))
        except Exception:  # no decision in time: nothing runs
            return False

    grouped = _Grouped(pub)
    try:
        stats = run_share(todo, grouped.put, lambda answer: pub.put({**answer, "verdict": share}),
                          wait_go)
    finally:
        grouped.close()
    stats["keys"] = [task["key"] for task in todo]
    return stats


def run_batch(tasks, topic):
    """Runs a batch of runs on one Dask worker (run_tasks), publishing each result at once
    (Dask Pub/Sub topic `topic`, to the client), so that a worker that dies loses only its
    current run. Runs whose keys are in the client's Variable `topic`-done (set when a worker
    left) are skipped: a batch rerun after a worker died does not redo the runs that worker
    finished. Returns run_tasks' statistics and the keys it ran."""
    from distributed import Pub, Variable

    pub = Pub(topic)
    todo = _not_done(tasks, Variable(topic + "-done"))
    stats = run_tasks(todo, pub.put)
    stats["keys"] = [task["key"] for task in todo]
    return stats


def run_single(task):
    """One run in a batch process of its own; returns its result (the runner's fallback for
    runs whose batch ended without their result)."""
    results = []
    run_tasks([task], results.append)
    return results[-1]
