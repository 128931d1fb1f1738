"""A Dask cluster of separate processes on the loopback address: one dask-scheduler and N
single-threaded dask-worker processes (no nanny, so a killed worker stays dead). Used by the
tests and by scripts/sweep_overhead.py; every wait has a timeout and stop() kills what start()
started."""
import json
import os
import pathlib
import signal
import subprocess
import time


def wait_for(condition, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.05)
    raise TimeoutError(f"timed out after {timeout_s} s waiting for {what}")


class LoopbackCluster:
    def __init__(self, folder, workers=2, timeout_s=60):
        self.folder = pathlib.Path(folder)
        self.n_workers = workers
        self.timeout_s = timeout_s
        self.procs = []
        self.workers = []
        self.address = None

    def _spawn(self, command, log_name):
        log = open(self.folder / log_name, "w")
        # Run files of a killed worker stay in this folder, not in /dev/shm.
        tmp = self.folder / "tmp"
        tmp.mkdir(exist_ok=True)
        proc = subprocess.Popen(command, stdout=log, stderr=log, start_new_session=True,
                                env={**os.environ, "TMPDIR": str(tmp)})
        log.close()
        self.procs.append(proc)
        return proc

    def start(self):
        self.folder.mkdir(parents=True, exist_ok=True)
        info = self.folder / "scheduler.json"
        info.unlink(missing_ok=True)
        self._spawn(["/usr/bin/dask-scheduler", "--host", "127.0.0.1", "--port", "0",
                     "--no-dashboard", "--scheduler-file", str(info)], "scheduler.log")

        def address():
            try:
                return json.loads(info.read_text()).get("address")
            except (OSError, ValueError):
                return None
        wait_for(address, self.timeout_s, "the scheduler's address")
        self.address = address()
        for i in range(self.n_workers):
            self.workers.append(self._spawn(
                ["/usr/bin/dask-worker", self.address, "--nthreads", "1", "--no-nanny",
                 "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{i}",
                 "--local-directory", str(self.folder / f"w{i}")], f"worker{i}.log"))
        wait_for(self._registered, self.timeout_s, f"{self.n_workers} workers at the scheduler")
        return self

    def _registered(self):
        for i, proc in enumerate(self.workers):
            if proc.poll() is not None:
                raise RuntimeError(f"dask-worker {i} exited: "
                                   f"{(self.folder / f'worker{i}.log').read_text()[-2000:]}")
        return all("Registered to" in (self.folder / f"worker{i}.log").read_text()
                   for i in range(self.n_workers))

    def stop(self):
        for proc in self.procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in self.procs:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=10)

    def __enter__(self):
        try:
            return self.start()
        except BaseException:
            self.stop()
            raise

    def __exit__(self, *exc):
        self.stop()
