"""A cluster started the Dask way for the benchmarks: ``dask scheduler`` and ``dask
worker`` processes, the workers in private mount namespaces (``unshare -m``, root only)
where the given client folders are hidden under empty tmpfs mounts."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def namespaces_available() -> bool:
    """True if ``unshare -m`` and tmpfs mounts work here (root)."""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return False
    probe = ["unshare", "-m", "--propagation", "private", "sh", "-c", "mount -t tmpfs none /mnt"]
    return subprocess.run(probe, capture_output=True).returncode == 0


class DaskCluster:
    """Scheduler and ``n`` workers (one process, one thread each); a context manager that
    SIGKILLs every process group on exit."""

    def __init__(self, n: int, hidden: list[Path]):
        self.n, self.hidden, self.procs = n, [Path(h) for h in hidden], []
        self.namespaced = namespaces_available()
        self._tmp = tempfile.TemporaryDirectory(prefix="glider-bench-cluster-")
        self.base = Path(self._tmp.name)

    def __enter__(self) -> DaskCluster:
        try:
            self._start_all()
        except BaseException:
            self.__exit__()
            raise
        return self

    def _start_all(self) -> None:
        sched_file = self.base / "scheduler.json"
        self.scheduler = self._start([sys.executable, "-m", "distributed.cli.dask_scheduler",
                                      "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                      "--scheduler-file", str(sched_file)])  # fmt: skip
        deadline = time.time() + 30
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.05)
        time.sleep(0.1)
        self.address = json.loads(sched_file.read_text())["address"]
        for i in range(self.n):
            scratch = self.base / f"scratch-w{i}"
            scratch.mkdir()
            worker = (f'TMPDIR="{scratch}" exec "{sys.executable}" -m distributed.cli.dask_worker '
                      f"{self.address} --name w{i} --nworkers 1 --nthreads 1 --no-dashboard "
                      f'--local-directory "{scratch}"')  # fmt: skip
            if self.namespaced:
                mounts = 'for d in "$@"; do mount -t tmpfs none "$d" || exit 97; done; '
                dirs = [str(d) for d in [*self.hidden, scratch] if d.is_dir()]
                cmd = ["unshare", "-m", "--propagation", "private", "sh", "-c", mounts + worker,
                       "sh", *dirs]  # fmt: skip
            else:
                cmd = ["sh", "-c", worker]
            self._start(cmd)

    def _start(self, cmd: list[str]) -> subprocess.Popen:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)  # fmt: skip
        self.procs.append(p)
        return p

    def cpu_seconds(self, pid: int) -> float:
        """User + system CPU time of a process, s."""
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def __exit__(self, *exc: object) -> None:
        for p in self.procs:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        for p in self.procs:
            p.wait(timeout=10)
        self._tmp.cleanup()
