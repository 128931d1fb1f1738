"""Runs a sweep on Dask distributed: a local cluster by default, or an existing scheduler.

Results are cached in OUT/sweep.sqlite by run key (hash of the resolved scene, the binary and
the kept outputs): runs with status ok or failed (deterministic) are not run again, so an
interrupted sweep resumes where it stopped. Crashes, timeouts and errors are recorded but run
again by the next invocation. The table (OUT/runs.csv, one row per run, and the `runs` table
of OUT/sweep.sqlite) is written as results arrive and rewritten in sweep order at the end.
"""
import collections
import csv
import io
import json
import math
import os
import select
import signal
import sqlite3
import sys
import threading
import time

from tslib.binaries import find_binary
from tslib.cache import file_digest

from . import spec
from . import task as task_module

META_COLUMNS = ["run", "status", "message"]
TAIL_COLUMNS = ["wall_s", "cpu_s", "worker", "key"]
# Columns that may differ between two runs of the same sweep (where and how fast it ran).
VOLATILE_COLUMNS = {"wall_s", "cpu_s", "worker"}
CACHED_STATUSES = {"ok", "failed"}


# Results are committed to the cache, and their rows written to runs.csv, in groups at most
# this far apart [s] (and at the end): a commit per result cost a tenth of the runner's CPU.
SYNC_S = 0.5


class Cache:
    """Run results by key, in SQLite (WAL). store() keeps a result until commit(), which the
    runner calls before it writes the results' rows (Table.write), so that an interrupted
    sweep's runs.csv holds no run its cache lacks."""

    def __init__(self, path):
        self.db = sqlite3.connect(str(path), timeout=30)
        self.db.execute("PRAGMA journal_mode=WAL")
        self.db.execute("PRAGMA synchronous=NORMAL")
        self.db.execute("CREATE TABLE IF NOT EXISTS cache (key TEXT PRIMARY KEY, result TEXT)")
        self.db.commit()
        self.unsaved = []  # (key, result as JSON) not yet committed

    def load(self, keys):
        found = {}
        keys = list(keys)
        for i in range(0, len(keys), 500):
            chunk = keys[i:i + 500]
            marks = ",".join("?" * len(chunk))
            for key, text in self.db.execute(
                    f"SELECT key, result FROM cache WHERE key IN ({marks})", chunk):
                found[key] = json.loads(text)
        return found

    def store(self, result):
        if result["status"] in CACHED_STATUSES:
            self.unsaved.append((result["key"], json.dumps(result)))

    def commit(self):
        if self.unsaved:
            self.db.executemany("INSERT OR REPLACE INTO cache VALUES (?, ?)", self.unsaved)
            self.db.commit()
            self.unsaved = []


def _lookup(summary, path):
    value = summary
    for part in path.split("."):
        if isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        elif isinstance(value, dict) and part in value:
            value = value[part]
        else:
            return None
    return value


class Table:
    """Turns results into rows and writes them: CSV (incrementally: write() appends the rows
    added since) and SQLite."""

    def __init__(self, sweep, out, db):
        self.sweep = sweep
        self.columns = (["run"] + sweep.axis_columns() + META_COLUMNS[1:] +
                        list(sweep.outcomes) + list(sweep.derived) + TAIL_COLUMNS)
        self.csv_path = out / "runs.csv"
        self.kernels_path = out / "kernels.csv"
        self.files_dir = out / "files"
        self.db = db
        self.rows = {}        # run index -> row
        self.kernels = {}     # run index -> list of per-kernel rows
        self.file = open(self.csv_path, "w", newline="")
        self.writer = csv.writer(self.file)
        self.writer.writerow(self.columns)
        self.unwritten = []   # rows added, not yet in the CSV file

    def row(self, run, result):
        row = {"run": run.index, **run.labels, "status": result["status"],
               "message": result["message"], "wall_s": round(result["wall_s"], 6),
               "cpu_s": round(result["cpu_s"], 6), "worker": result["worker"], "key": run.key}
        summary = None
        if result["summary"]:
            try:
                summary = json.loads(result["summary"])
            except ValueError:
                row["status"], row["message"] = "error", "unreadable summary"
        if summary is not None and result["status"] == "failed":
            row["message"] = summary.get("status", row["message"])
        for column, path in self.sweep.outcomes.items():
            value = _lookup(summary, path) if summary is not None else None
            row[column] = "" if value is None else value
        for column, expression in self.sweep.derived.items():
            value = expression.evaluate(row)
            row[column] = "" if math.isnan(value) else value
        return row

    def add(self, run, result):
        row = self.row(run, result)
        self.rows[run.index] = row
        self.unwritten.append(row)
        if result["outcomes"]:
            reader = csv.DictReader(io.StringIO(result["outcomes"]))
            self.kernels[run.index] = [{"run": run.index, **run.labels, **k} for k in reader]
        # Runs that keep outputs get a folder with them, the summary and the outcomes.
        files = {f"{name}.csv": text for name, text in (result.get("files") or {}).items()}
        if files:
            files.update({"summary.json": result["summary"], "outcomes.csv": result["outcomes"]})
            folder = self.files_dir / run.key
            folder.mkdir(parents=True, exist_ok=True)
            for name, text in files.items():
                if text is not None:
                    (folder / name).write_text(text)
        return row

    def write(self):
        """Appends the rows added since the last call to the CSV file."""
        self.writer.writerows([[r.get(c, "") for c in self.columns] for r in self.unwritten])
        self.file.flush()
        self.unwritten = []

    def finish(self):
        """Rewrites the CSV files and the SQLite tables in sweep order."""
        self.file.close()
        ordered = [self.rows[i] for i in sorted(self.rows)]
        _write_csv(self.csv_path, self.columns, ordered)
        kernels = [k for i in sorted(self.kernels) for k in self.kernels[i]]
        kernel_columns = list(kernels[0]) if kernels else ["run"]
        _write_csv(self.kernels_path, kernel_columns, kernels)
        _write_sqlite(self.db, "runs", self.columns, ordered)
        _write_sqlite(self.db, "kernels", kernel_columns, kernels)


def _write_csv(path, columns, rows):
    tmp = path.with_suffix(".tmp")
    with open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


def _write_sqlite(db, name, columns, rows):
    quoted = ", ".join(f'"{c}"' for c in columns)
    db.execute(f'DROP TABLE IF EXISTS "{name}"')
    db.execute(f'CREATE TABLE "{name}" ({quoted})')
    scalar = (type(None), int, float, str, bool)
    values = [[v if type(v) in scalar else json.dumps(v) for v in map(r.get, columns)]
              for r in rows]
    db.executemany(f'INSERT INTO "{name}" VALUES ({", ".join("?" * len(columns))})', values)
    db.commit()


# ------------------------------------------------------------------------------------------

class Progress:
    """done/total, failures, elapsed and ETA on stderr: one rewritten line on a terminal, a
    line every 10 % otherwise."""

    def __init__(self, total, done=0, stream=sys.stderr):
        self.total, self.done, self.failed = total, done, 0
        self.first = done
        self.stream = stream
        self.tty = stream.isatty()
        self.started = time.monotonic()
        self.last = 0.0
        self.decile = -1

    def update(self, status):
        self.done += 1
        self.failed += status != "ok"
        now = time.monotonic()
        decile = 10 * self.done // max(self.total, 1)
        if self.done == self.total or (self.tty and now - self.last > 0.25) or \
                (not self.tty and decile != self.decile):
            self.last, self.decile = now, decile
            self.draw(now)

    def draw(self, now):
        elapsed = now - self.started
        fresh = self.done - self.first
        left = self.total - self.done
        eta = f"{elapsed / fresh * left:.0f} s" if fresh else "?"
        width = 30
        filled = width * self.done // max(self.total, 1)
        line = (f"[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} runs, "
                f"{self.failed} failed, {elapsed:.0f} s, ETA {eta}")
        self.stream.write(("\r" + line) if self.tty else line + "\n")
        if self.tty and self.done == self.total:
            self.stream.write("\n")
        self.stream.flush()


# ------------------------------------------------------------------------------------------

def _connect(scheduler, workers):
    """A Dask client: to an existing scheduler, or to a new local cluster of `workers`
    single-threaded worker processes."""
    import logging

    import cloudpickle
    import dask
    from distributed import Client, LocalCluster

    # Workers need nothing from this repository: the task module travels by value.
    cloudpickle.register_pickle_by_value(task_module)
    if scheduler:
        return Client(scheduler, timeout=30), None
    # The local cluster shares the cores with the runs: no statistical profiler (a sample of
    # every thread each 10 ms), no work stealing (the scheduler queues the batches), and
    # slower health checks and memory monitor.
    dask.config.set({"distributed.worker.profile.enabled": False,
                     "distributed.scheduler.work-stealing": False,
                     "distributed.admin.tick.interval": "500ms",
                     "distributed.worker.memory.monitor-interval": "1s"})
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    return Client(cluster), cluster


def _scene_of(run):
    """What a batch line runs: the run's base scene (its scene with the override files) and
    its --set overrides, so that a simulate --batch process parses each base once and applies
    the overrides to a copy of the tree; the resolved scene when no base is known. scene_name
    names the scene in messages as simulate --check-batch does (its path)."""
    name = run.arguments[0] if run.arguments else ""
    if run.base is None:
        return {"scene": run.scene, "args": [], "scene_name": name}
    flags = run.arguments[1::2] if len(run.arguments) % 2 else []
    values = run.arguments[2::2] if len(run.arguments) % 2 else []
    if not flags or any(f not in ("--set", "--set-file") for f in flags):
        return {"scene": run.scene, "args": [], "scene_name": name}
    return {"scene": run.base, "scene_name": name,
            "args": [a for f, v in zip(flags, values) if f == "--set" for a in (f, v)]}


def run_sweep(sweep, runs, simulate, binary_sha, out, scheduler=None, workers=None,
              processes=False, batch=None, progress_stream=sys.stderr, log=print):
    """Runs every run not in the cache; returns the table (rows in sweep order) and stats.
    Without a scheduler the runs go to `workers` threads of this process (default: one per
    core), each feeding simulate --batch processes; with processes=True to a local Dask
    cluster of worker processes instead; with a scheduler to its Dask workers.

    Without `batch`, validation first: the runs are shared out, one share per worker (thread
    or Dask worker thread), each held in one simulate --batch process that reads, loads and
    compiles its runs and answers which are invalid; the runs start, on the models compiled
    then, only when every share is valid. Otherwise SweepError (spec.invalid_error) before
    anything is written to `out`. With `batch`, the runs go in batches of that size, handed
    out as workers free up; spec.validate (with compile_models) must have checked them."""
    cache_path = out / "sweep.sqlite"
    cache = Cache(cache_path) if cache_path.exists() else None
    cached = cache.load({r.key for r in runs}) if cache is not None else {}
    by_key = {}
    for run in runs:
        by_key.setdefault(run.key, []).append(run)
    todo = [key for key in by_key if key not in cached]
    n_todo = sum(len(by_key[k]) for k in todo)
    stats = {"runs": len(runs), "cached": len(runs) - n_todo, "processes": 0,
             "process_cpu_s": 0.0, "process_wall_s": 0.0, "hold_s": 0.0}
    payload = {key: {"key": key, **_scene_of(by_key[key][0]), "simulate": str(simulate),
                     "sha": binary_sha, "timeout_s": sweep.timeout_s, "keep": by_key[key][0].keep}
               for key in todo}
    work = [payload[key] for key in todo]
    shares = None
    try:
        if work and batch is None:
            started = time.monotonic()
            shares = (_DaskShares(work, scheduler, workers, stats) if scheduler or processes
                      else _LocalShares(work, workers or os.cpu_count() or 1, stats))
            _check_verdicts(shares.verdicts(), sweep, runs, by_key, shares)
            stats["hold_s"] = time.monotonic() - started
        rows = _run_checked(sweep, runs, out, cache, cached, by_key, todo, work, shares, stats,
                            scheduler, workers, processes, batch, progress_stream, log)
    finally:
        if shares is not None:
            shares.close()
    return rows, stats


def _check_verdicts(answers, sweep, runs, by_key, shares):
    """Raises SweepError (after telling the shares not to run) unless every share is valid."""
    errors = [a["error"] for a in answers if "error" in a]
    invalid = {item["id"]: item["message"] for a in answers if "error" not in a
               for item in a.get("invalid", [])}
    if not errors and not invalid:
        return
    shares.go(False)
    if errors:
        raise spec.SweepError(f"{sweep.path}: the validation failed: {errors[0]}")
    bad = [(run, invalid[run.key]) for run in runs if run.key in invalid]
    raise spec.invalid_error(sweep, len(runs), bad)


def _run_checked(sweep, runs, out, cache, cached, by_key, todo, work, shares, stats, scheduler,
                 workers, processes, batch, progress_stream, log):
    """run_sweep once the runs to run are valid: the table of the cached runs, the runs, the
    table in sweep order."""
    out.mkdir(parents=True, exist_ok=True)
    cache = cache or Cache(out / "sweep.sqlite")
    table = Table(sweep, out, cache.db)
    for run in runs:
        if run.key in cached:
            table.add(run, cached[run.key])
    table.write()
    log(f"sweep {sweep.name}: {len(runs)} runs, {stats['cached']} from the cache, "
        f"{len(runs) - stats['cached']} to run -> {out}")
    progress = Progress(len(runs), stats["cached"], progress_stream)
    started = time.monotonic()
    if todo:
        pending = set(todo)
        synced = [time.monotonic()]

        def accept(result):
            if result["key"] not in pending:
                return  # a run redone after a worker died: the first result stands
            pending.discard(result["key"])
            cache.store(result)
            for run in by_key[result["key"]]:
                table.add(run, result)
                progress.update(result["status"])
            if time.monotonic() - synced[0] >= SYNC_S:
                synced[0] = time.monotonic()
                cache.commit()
                table.write()

        if shares is not None:
            shares.go(True)
            shares.collect(accept, pending)
        elif scheduler or processes:
            _dispatch(work, scheduler, workers or os.cpu_count() or 1, batch, accept, pending,
                      stats)
        else:
            _dispatch_local(work, workers or os.cpu_count() or 1, batch, accept, pending, stats)
        cache.commit()
        table.write()
    stats["dispatch_s"] = time.monotonic() - started
    table.finish()
    rows = [table.rows[i] for i in sorted(table.rows)]
    stats["failed"] = sum(r["status"] != "ok" for r in rows)
    return rows


# Margin on a share's validation time for the runner's wait for all verdicts [s] (the Dask
# workers' task start, the processes' start).
VERDICT_MARGIN_S = 30.0


def _shares(work, slots):
    """The runs shared out to `slots` workers, interleaved (each share holds runs of every
    part of the sweep, so that the shares cost about the same); no empty share."""
    return [work[i::slots] for i in range(min(slots, len(work)))]


class _PoolProcess:
    """A simulate --batch process of the local pool: the runs it holds (validated, run by id),
    its share not yet sent, and the runs sent to it whose results are awaited (in order)."""

    def __init__(self, simulate, folder, index, name, own=(), held=()):
        self.proc, self.err = task_module.start_batch_process(
            simulate, os.path.join(folder, f"stderr-{index}.txt"))
        self.fd = self.proc.stdout.fileno()
        self.name = name
        self.own = collections.deque(own)
        self.held = set(held)
        self.sent = collections.deque()
        self.chunks = []          # output read, not yet a whole line
        self.started = time.monotonic()  # when the run at the head of sent started
        self.begun = time.perf_counter()
        self.feeder = None
        self.closed = False

    def send(self, tasks):
        """Held runs as one run line by id, the others as whole lines."""
        if not self.sent:
            self.started = time.monotonic()
        parts, ids = [], []
        for t in tasks:
            if t["key"] in self.held:
                ids.append(t["key"])
                continue
            if ids:
                parts.append(json.dumps({"run": ids}) + "\n")
                ids = []
            parts.append(task_module._batch_line(t))
        if ids:
            parts.append(json.dumps({"run": ids}) + "\n")
        self.sent.extend(tasks)
        self.write("".join(parts).encode())

    def write(self, data, close=False):
        try:
            if data:
                self.proc.stdin.write(data)
                self.proc.stdin.flush()
            if close:
                self.closed = True
                self.proc.stdin.close()
        except (BrokenPipeError, OSError, ValueError):
            pass  # the process died: its end is read on its output

    def lines(self, data):
        """The whole lines in the output read so far, with data."""
        if b"\n" not in data:
            self.chunks.append(data)
            return []
        self.chunks.append(data)
        *whole, rest = b"".join(self.chunks).split(b"\n")
        self.chunks = [rest] if rest else []
        return [line.decode("utf-8", "replace") for line in whole]

    def reap(self, kill):
        """Kills (when asked) and reaps the process: (exit code, CPU time [s], stderr's end)."""
        if kill:  # not Popen.kill, which may reap the process (its usage then lost)
            try:
                os.kill(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.write(b"", close=True)
        _, status, usage = os.wait4(self.proc.pid, 0)
        self.proc.returncode = os.waitstatus_to_exitcode(status)
        self.proc.stdout.close()
        self.err.seek(0)
        stderr = self.err.read().strip()[-500:]
        self.err.close()
        return self.proc.returncode, usage.ru_utime + usage.ru_stime, stderr


# Runs per run line sent to a pool process at most.
POOL_CHUNK = 8
# A pool process gets its next runs when it has at most this many left to answer. (A pause
# after each wake-up, to read a few results at once, saved no CPU and starved the processes.)
POOL_AHEAD = 1


class _LocalShares:
    """Validation first on simulate --batch processes of this process, one per worker: each
    holds its share (hold, barrier); then one thread (no worker threads: their queues and the
    interpreter lock cost more than the runs' lines) hands each process its held runs by id a
    few at a time, and a process whose share is done takes runs from the end of the largest
    share left, as whole lines (compiled again: their held models are dropped unused)."""

    def __init__(self, work, workers, stats):
        import socket

        self.stats, self.work = stats, work
        self.shares = _shares(work, workers)
        stats.update(workers=workers, batch=max(map(len, self.shares)),
                     batches=len(self.shares))
        self.simulate = work[0]["simulate"]
        sha = task_module._binary_sha(self.simulate)
        if sha != work[0]["sha"]:
            raise spec.SweepError(f"simulate at {self.simulate} changed since the sweep started "
                                  f"(sha256 {sha[:12]} != {work[0]['sha'][:12]})")
        self.limit_s = max(map(task_module.validate_timeout_s, self.shares)) + VERDICT_MARGIN_S
        self.folder = task_module._thread_folder()
        self.prefix = f"{socket.gethostname()}:{os.getpid()}"
        self.procs = []
        for i, share in enumerate(self.shares):
            p = _PoolProcess(self.simulate, self.folder, i, f"{self.prefix}:thread-{i}",
                             own=share, held=[t["key"] for t in share])
            text = "".join(['{"hold": true}\n', *map(task_module._batch_line, share),
                            json.dumps({"barrier": round(self.limit_s, 3)}) + "\n"]).encode()
            # A thread writes the share (the pipe is bounded; the process reads as it compiles).
            p.feeder = threading.Thread(target=p.write, args=(text,), daemon=True)
            p.feeder.start()
            self.procs.append(p)

    def verdicts(self):
        """Every share's answer (an error for a share that gave none in time)."""
        deadline = time.monotonic() + self.limit_s
        answers = {}
        poller = select.poll()
        by_fd = {p.fd: p for p in self.procs}
        for fd in by_fd:
            poller.register(fd, select.POLLIN | select.POLLHUP)
        while len(answers) < len(self.procs):
            left = deadline - time.monotonic()
            events = poller.poll(max(0.0, left) * 1000.0) if left > 0 else []
            if not events:
                break
            for fd, _ in events:
                p = by_fd[fd]
                data = os.read(fd, 1 << 20)
                lines = p.lines(data) if data else []
                if lines or not data:
                    poller.unregister(fd)
                    answers[fd] = self._verdict(p, lines[0] if lines else None)
        for p in self.procs:
            if p.fd not in answers:
                answers[p.fd] = {"error": f"simulate --batch gave no verdict on its "
                                          f"{len(p.own)} runs within {self.limit_s:g} s"}
        return list(answers.values())

    @staticmethod
    def _verdict(p, line):
        try:
            answer = json.loads(line) if line else None
        except ValueError:
            answer = None
        if isinstance(answer, dict) and answer.get("barrier") is True:
            return answer
        return {"error": f"simulate --batch ended its validation with "
                         f"{line[:300] if line else 'no answer'!r}"}

    def go(self, value):
        if value:
            return
        for p in self.procs:
            if not p.closed:
                p.write(json.dumps({"go": False}).encode() + b"\n", close=True)

    def _next(self, p):
        """The next runs for p: its own share's, else the end of the largest share left."""
        if p.own:
            n = max(1, min(POOL_CHUNK, len(p.own) // 8))
            return [p.own.popleft() for _ in range(n)]
        victim = max(self.procs, key=lambda q: len(q.own))
        if not victim.own:
            return []
        n = max(1, min(POOL_CHUNK // 2, len(victim.own) // 2))
        taken = [victim.own.pop() for _ in range(n)]
        return taken[::-1]

    def _top_up(self, p):
        """Keeps p one run line ahead of the run it is on; closes its input at the end."""
        if p.closed or len(p.sent) > POOL_AHEAD:
            return
        tasks = self._next(p)
        if tasks:
            p.send(tasks)
        elif not p.sent:
            p.write(b"", close=True)

    def collect(self, accept, pending):
        """Hands each result to accept as it arrives, until every run has one."""
        self._accept = accept
        for p in self.procs:
            p.feeder.join(timeout=task_module.EXIT_WAIT_S)
        for p in self.procs:
            self._top_up(p)
        poller = select.poll()
        by_fd = {}

        def watch(p):
            by_fd[p.fd] = p
            poller.register(p.fd, select.POLLIN | select.POLLHUP)

        for p in self.procs:
            watch(p)
        while by_fd:
            now = time.monotonic()
            waits = [p.started + p.sent[0]["timeout_s"] - now for p in by_fd.values() if p.sent]
            wait = min(waits) if waits else 0.5
            events = poller.poll(max(0.0, wait) * 1000.0 + 1.0)
            for fd, _ in events:
                p = by_fd[fd]
                data = os.read(fd, 1 << 20)
                for line in (p.lines(data) if data else []):
                    if not p.sent:
                        continue  # nothing asked: not a result
                    accept(task_module._line_result(p.sent.popleft(), line, p.name))
                    p.started = time.monotonic()
                if data:
                    self._top_up(p)
                else:
                    poller.unregister(fd)
                    del by_fd[fd]
                    self._end(p, timed_out=False, watch=watch)
            now = time.monotonic()
            for p in list(by_fd.values()):
                if p.sent and now > p.started + p.sent[0]["timeout_s"]:
                    poller.unregister(p.fd)
                    del by_fd[p.fd]
                    self._end(p, timed_out=True, watch=watch)
        for key in sorted(pending):
            accept(_error_result(key, "no result from the local simulate --batch processes"))

    def _end(self, p, timed_out, watch):
        """p's output ended (or its run timed out): reap it, record the run it was on, and
        start a new process (holding nothing) for the runs it had left."""
        code, cpu_s, stderr = p.reap(kill=timed_out or bool(p.sent))
        self.stats["process_cpu_s"] += cpu_s
        self.stats["process_wall_s"] += time.perf_counter() - p.begun
        self.stats["processes"] += 1
        index = self.procs.index(p)
        left = list(p.sent)
        if left:
            self._accept(task_module._end_result(left[0], p.name, code, stderr, timed_out))
            left = left[1:]
        left += list(p.own)
        p.own.clear()
        if not left:
            return
        fresh = _PoolProcess(self.simulate, self.folder, index, p.name, own=left)
        self.procs[index] = fresh
        watch(fresh)
        self._top_up(fresh)

    def close(self):
        for p in self.procs:
            if p.proc.returncode is None:
                p.reap(kill=True)


class _DaskShares:
    """Validation first on Dask: one task per worker thread (task.run_dask_share, placed on
    that worker), each holding its share in one simulate --batch process; verdicts and results
    arrive on a Pub/Sub topic, the go is a Variable."""

    def __init__(self, work, scheduler, workers, stats):
        self.work, self.stats = work, stats
        self.client, self.cluster = _connect(scheduler, workers or os.cpu_count() or 1)
        try:
            self._start(work, scheduler, stats)
        except BaseException:
            self.client.close()
            if self.cluster is not None:
                self.cluster.close()
            raise

    def _start(self, work, scheduler, stats):
        import queue
        import uuid

        from distributed import Sub, Variable

        info = self.client.scheduler_info()["workers"]
        slots = [address for address, w in sorted(info.items()) for _ in range(w["nthreads"])]
        if not slots:
            raise spec.SweepError(f"no Dask worker at {scheduler}")
        self.shares = _shares(work, len(slots))
        stats.update(workers=len(slots), batch=max(map(len, self.shares)),
                     batches=len(self.shares))
        self.topic = f"threshing-sweep-{uuid.uuid4().hex}"
        self.sub = Sub(self.topic, client=self.client)
        self.done_keys = Variable(self.topic + "-done", client=self.client)
        self.done_keys.set([])
        self.go_flag = Variable(self.topic + "-go", client=self.client)
        self.departures = queue.Queue()
        self.client.subscribe_topic("all", lambda event: self.departures.put(event)
                                    if event[1].get("action") == "remove-worker" else None)
        self.limit_s = max(map(task_module.validate_timeout_s, self.shares)) + VERDICT_MARGIN_S
        self.futures = [
            self.client.submit(task_module.run_dask_share, share, self.topic, i,
                               key=f"{self.topic}-share-{i}", workers=[slots[i]],
                               allow_other_workers=True, pure=False)
            for i, share in enumerate(self.shares)]
        self.early = []  # results read while waiting for verdicts (none expected)

    def _messages(self, timeout_s):
        """The next message of the topic, or None after timeout_s."""
        buffered = getattr(self.sub, "buffer", None)
        if buffered is None:
            try:
                return self.sub.get(timeout=timeout_s)
            except TimeoutError:
                return None
        deadline = time.monotonic() + timeout_s
        while not buffered:
            if time.monotonic() >= deadline:
                return None
            time.sleep(0.002)
        return buffered.popleft()

    def verdicts(self):
        deadline = time.monotonic() + self.limit_s
        answers = {}
        while len(answers) < len(self.shares):
            message = self._messages(max(0.0, min(0.5, deadline - time.monotonic())))
            if message is not None and "verdict" in message:
                answers.setdefault(message["verdict"], message)
            elif message is not None:
                self.early.append(message)
            elif time.monotonic() >= deadline or any(f.status == "error" for f in self.futures):
                missing = [i for i in range(len(self.shares)) if i not in answers]
                return list(answers.values()) + [{"error": f"no verdict from share {i} within "
                                                           f"{self.limit_s:g} s"}
                                                 for i in missing]
        return list(answers.values())

    def go(self, value):
        self.go_flag.set(bool(value))

    def collect(self, accept, pending):
        for message in self.early:
            _accept_message(message, accept)
        _collect(self.client, self.sub, self.futures, self.shares, self.work, accept, pending,
                 self.stats, self.done_keys, self.departures)

    def close(self):
        try:
            self.go(False)  # after the go: no effect on the shares that run
            self.client.unsubscribe_topic("all")
            del self.sub
        finally:
            self.client.close()
            if self.cluster is not None:
                self.cluster.close()


# Largest batch of the local threads: their processes take one batch after another, so a
# batch only sets how finely the runs are shared out.
MAX_BATCH = 64
# Largest batch of a Dask task: each task costs a simulate --batch process start (exec,
# dynamic linking: about 3 ms of CPU) and the task's own round trips to the scheduler.
MAX_TASK_BATCH = 128


def batch_sizes(n_runs, workers, fixed=None, parts=4, largest=MAX_BATCH):
    """Runs per batch, in order: `fixed` each, or guided (each batch 1 / parts of the remaining
    runs' share per worker, at most `largest`), so that the first batches spread the process
    start over many runs and the last ones, of one or two runs, balance the workers."""
    sizes, left = [], n_runs
    while left > 0:
        k = fixed or max(1, min(largest, math.ceil(left / (parts * max(workers, 1)))))
        k = min(k, left)
        sizes.append(k)
        left -= k
    return sizes


def _split(work, sizes):
    batches, start = [], 0
    for k in sizes:
        batches.append(work[start:start + k])
        start += k
    return batches


def _dispatch_local(work, workers, batch, accept, pending, stats):
    """Threads of this process, each taking the next batch when its simulate --batch process
    is on the last run of the one before (task.run_tasks with `more`: one process per thread
    unless a run crashes or times out); results arrive on a queue as each run ends. No Dask:
    its import and cluster start cost more than the threads need (docs/sweeps.md,
    "Overhead")."""
    import queue
    import socket
    import threading

    batches = queue.Queue()
    sizes = batch_sizes(len(work), workers, batch)
    for b in _split(work, sizes):
        batches.put(b)
    stats.update(workers=workers, batch=max(sizes), batches=len(sizes))
    results, lock = queue.Queue(), threading.Lock()
    prefix = f"{socket.gethostname()}:{os.getpid()}"

    def next_batch():
        try:
            return batches.get_nowait()
        except queue.Empty:
            return []

    def worker(i):
        # One simulate --batch process takes this thread's batches one after the other (a new
        # one only after a crash or a timeout): one process start per thread, and its scene
        # trees and compiled teeth serve all its batches.
        batch_stats = task_module.run_tasks([], results.put, f"{prefix}:thread-{i}",
                                            more=next_batch)
        with lock:
            task_module.add_stats(stats, batch_stats)

    threads = [threading.Thread(target=worker, args=(i,), daemon=True) for i in range(workers)]
    for t in threads:
        t.start()
    # Every run ends within its timeout, so the threads end; the wait is bounded by them.
    while pending and (any(t.is_alive() for t in threads) or not results.empty()):
        try:
            accept(results.get(timeout=0.5))
        except queue.Empty:
            pass
    for t in threads:
        t.join(timeout=10)
    for key in sorted(pending):
        accept(_error_result(key, "no result from the local worker threads"))


def _error_result(key, message):
    return {"key": key, "status": "error", "message": message, "summary": None,
            "outcomes": None, "files": {}, "wall_s": 0.0, "cpu_s": 0.0, "worker": ""}


def _dispatch(work, scheduler, workers, batch, accept, pending, stats):
    """Sends the runs to Dask in batches (task.run_batch: one simulate --batch process per
    batch); results arrive one by one on a Pub/Sub topic as each run ends. Runs whose batch
    finished without their result (a lost message) are sent again one per task, returning
    their result."""
    import queue
    import uuid

    from distributed import Sub, Variable

    client, cluster = _connect(scheduler, workers)
    try:
        threads = sum(w["nthreads"] for w in client.scheduler_info()["workers"].values())
        stats["workers"] = threads
        topic = f"threshing-sweep-{uuid.uuid4().hex}"
        sub = Sub(topic, client=client)
        done_keys = Variable(topic + "-done", client=client)
        done_keys.set([])
        departures = queue.Queue()
        client.subscribe_topic("all", lambda event: departures.put(event)
                               if event[1].get("action") == "remove-worker" else None)
        # Half of each worker's remaining share: about half the tasks of a quarter.
        sizes = batch_sizes(len(work), threads, batch, parts=2, largest=MAX_TASK_BATCH)
        stats.update(batch=max(sizes), batches=len(sizes))
        batches = _split(work, sizes)
        # One map call: every submit call would read the caller's source (Dask records it).
        futures = client.map(task_module.run_batch, batches, [topic] * len(batches),
                             key=[f"{topic}-batch-{i}" for i in range(len(batches))], pure=False)
        _collect(client, sub, futures, batches, work, accept, pending, stats, done_keys,
                 departures)
        client.unsubscribe_topic("all")
        del sub
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _collect(client, sub, futures, batches, work, accept, pending, stats, done_keys,
             departures):
    """Hands each result published on the topic (sub) to accept until every run has one or
    every task ended; batches: the runs of each future. Runs whose task finished without
    their result go to _run_singly. Verdict messages (validation first) are skipped."""
    all_keys = [p["key"] for p in work]
    deadline = None
    # Sub's deque, filled by the event loop: read directly, with a short sleep when empty
    # (a Sub.get per result would cost a round trip through the event loop).
    buffered = getattr(sub, "buffer", None)
    checked = time.monotonic()
    while pending:
        if buffered is not None:
            if buffered:
                _accept_message(buffered.popleft(), accept)
                continue
            if time.monotonic() - checked < 0.2:
                time.sleep(0.005)
                continue
            checked = time.monotonic()
        else:
            try:
                _accept_message(sub.get(timeout=0.2), accept)
                continue
            except TimeoutError:
                pass
        if not departures.empty():
            while not departures.empty():
                departures.get()
            done_keys.set([key for key in all_keys if key not in pending])
        if all(f.done() for f in futures):
            # Every batch ended. Results of the batches that finished are at most a moment
            # behind; those of failed batches (e.g. KilledWorker) will not come.
            expected = {p["key"] for f, b in zip(futures, batches) if f.status == "finished"
                        for p in b} & pending
            deadline = deadline or time.monotonic() + 10
            if not expected or time.monotonic() > deadline:
                break
    # A task returns its statistics just after its last result: wait for it, briefly.
    from distributed import wait

    try:
        wait(futures, timeout=task_module.EXIT_WAIT_S)
    except TimeoutError:
        pass
    for f in futures:
        if f.status == "finished":
            task_module.add_stats(stats, f.result())
    if pending:
        _run_singly(client, [p for p in work if p["key"] in pending], accept)


def _accept_message(message, accept):
    """A message of the topic: a result, a group of results, or a verdict (skipped)."""
    if "results" in message:
        for result in message["results"]:
            accept(result)
    elif "verdict" not in message:
        accept(message)


def _run_singly(client, payloads, accept):
    """One task per run, results returned by the tasks (the fallback path)."""
    from distributed import as_completed

    futures = client.map(task_module.run_single, payloads,
                         key=[f"threshing-run-{p['key']}" for p in payloads], pure=False)
    key_of = {f.key: p["key"] for f, p in zip(futures, payloads)}
    limit_s = max(p["timeout_s"] for p in payloads) + 60
    try:
        for future in as_completed(futures, timeout=limit_s):
            if future.status == "finished":
                accept(future.result())
            else:
                error = future.exception()
                accept(_error_result(key_of[future.key], f"{type(error).__name__}: {error}"))
            future.release()
    except TimeoutError:  # e.g. no worker left: the runs without a result are errors
        for future in futures:
            accept(_error_result(key_of[future.key], f"no result after {limit_s:g} s"))


def compare_tables(a_path, b_path):
    """Differences between two runs.csv files apart from the volatile columns (wall and CPU
    time, worker): a list of messages, empty when equal."""
    def load(path):
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    a, b = load(a_path), load(b_path)
    if not a or not b:
        return [f"empty table: {a_path if not a else b_path}"]
    if list(a[0]) != list(b[0]):
        return [f"columns differ: {list(a[0])} != {list(b[0])}"]
    if len(a) != len(b):
        return [f"{len(a)} rows != {len(b)} rows"]
    diffs = []
    for ra, rb in zip(a, b):
        for column in ra:
            if column not in VOLATILE_COLUMNS and ra[column] != rb[column]:
                diffs.append(f"run {ra['run']}: {column} {ra[column]!r} != {rb[column]!r}")
    return diffs


def binary_sha(simulate):
    return file_digest(simulate)


def resolve_simulate(path, root=None):
    """The simulate binary (--simulate, else the workspace's), as an absolute path."""
    return find_binary("simulate", path).resolve()
