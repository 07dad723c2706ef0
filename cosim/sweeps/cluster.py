"""The Dask side of sweeps: clients, the version check at connect, FMUs sent to workers.

Workers share nothing with the client but the network:

- the FMUs travel through Dask: the client reads each file once and scatters its bytes
  under a key named by its SHA-256 (``glider-fmu-<sha256>-<tag>``, replicated to every
  worker; a worker that joins later gets them from a peer); each worker writes them once
  into its own local directory (``<worker local dir>/glider-cosim-fmus/<sha256>/``);
- trajectories come back in the task results and are written by the client;
- a worker never opens a path of the client.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import os
import tempfile
import uuid
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: the distribution whose version workers must share with the client
DIST = "glider-cosim"


class SweepClusterError(ValueError):
    """The cluster cannot run the sweep (the message names the worker and what differs)."""


def package_version(dist: str = DIST) -> str | None:
    """Installed version of ``dist`` in this process (None if not installed)."""
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


#: Dask starts its worker processes with ``MALLOC_TRIM_THRESHOLD_=65536``
#: (``distributed.nanny.pre-spawn-environ``): glibc then returns freed memory at once and
#: stops adapting its mmap threshold, and a sweep's runs allocate and free their arrays
#: thousands of times: 13-20 % more CPU a run here (``bench/sweep.py``,
#: ``worker_cpu_ms_per_run_1_worker_dask_trim``). The local workers start without it
#: (glibc's own behaviour); a value in the environment still wins.
NO_TRIM = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


def make_client(workers: int = 2, scheduler: str | None = None, dashboard: bool = False) -> Any:
    """A Dask client: an existing cluster, or a local one of worker processes.

    Parameters
    ----------
    workers : int
        Worker processes of the local cluster (one thread each).
    scheduler : str, optional
        Address of an existing scheduler (``tcp://host:8786``); ``workers`` is then unused.
    dashboard : bool
        Serve the dashboard of the local cluster (port 8787, another one if taken). Without
        it the scheduler's HTTP server takes a free port and serves no dashboard, so no
        "Port 8787 is already in use" warning appears when another cluster runs.
    """
    from ..extras import require

    require("sweep")
    import dask
    from distributed import Client, LocalCluster

    from ..inputs.tempdirs import new_temp_dir

    if scheduler:
        return Client(scheduler, timeout="20s")
    # workers inherit GLIDER_COSIM_TMP: their extractions and Dask's scratch space are
    # removed with this process's temporary folder
    scratch = str(new_temp_dir("dask_"))
    dask.config.set({"temporary-directory": scratch})
    with warnings.catch_warnings(), dask.config.set(NO_TRIM):  # read by each nanny here
        warnings.filterwarnings("ignore", message=r"Port \d+ is already in use")
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":8787" if dashboard else ":0",
                               scheduler_kwargs={"dashboard": dashboard},
                               silence_logs=50, local_directory=scratch)  # fmt: skip
    return Client(cluster)


def check_workers(
    client: Any, version: str | None = None, dist: str = DIST, timeout: float = 30.0
) -> dict[str, str]:
    """Check that every worker and the scheduler have ``dist`` at the client's version,
    before any run (the scheduler unpickles the tasks, so it needs the package too).

    Parameters
    ----------
    client : distributed.Client
    version : str, optional
        Version wanted (default: the client's installed one).
    dist : str
        Distribution name.
    timeout : float
        How long to wait for a first worker, s.

    Returns
    -------
    dict
        Worker address -> version.

    Raises
    ------
    SweepClusterError
        One line naming the first worker (or the scheduler) that differs and both
        versions.
    """
    want = version or package_version(dist) or "not installed"
    try:
        client.wait_for_workers(1, timeout=timeout)
    except TimeoutError:
        raise SweepClusterError(
            f"no worker joined the scheduler {client.scheduler.address} within {timeout:g} s"
        ) from None
    found = client.run(importlib.metadata.version, dist, on_error="return")
    bad = {a: v for a, v in found.items() if v != want}
    if bad:
        addr, got = sorted(bad.items())[0]
        more = f" (and {len(bad) - 1} more worker(s))" if len(bad) > 1 else ""
        raise SweepClusterError(
            f"worker {addr} {_has(dist, got)}, the client {dist} {want}{more}: install "
            f"{dist} {want} on every worker"
        )
    try:
        got = client.run_on_scheduler(importlib.metadata.version, dist)
    except importlib.metadata.PackageNotFoundError as err:
        got = err
    if got != want:
        raise SweepClusterError(
            f"scheduler {client.scheduler.address} {_has(dist, got)}, the client {dist} "
            f"{want}: the scheduler unpickles the tasks, install {dist} {want} there too"
        )
    return found


def _has(dist: str, got: object) -> str:
    if isinstance(got, importlib.metadata.PackageNotFoundError):
        return f"has no {dist} installed"
    if isinstance(got, str):
        return f"has {dist} {got}"
    return f"cannot report its {dist} version ({got!r})"


# ------------------------------------------------------------------ FMUs on workers
@dataclass(frozen=True)
class FmuBlob:
    """An FMU file's bytes, named by their SHA-256."""

    name: str  # file name, e.g. GliderPlant.fmu
    sha256: str
    data: bytes

    @classmethod
    def read(cls, path: str | Path) -> FmuBlob:
        data = Path(path).read_bytes()
        return cls(Path(path).name, hashlib.sha256(data).hexdigest(), data)


def scatter_fmus(client: Any, paths: Mapping[str, Path]) -> dict[str, Any]:
    """Send the FMUs to every worker once: instance -> future of its :class:`FmuBlob`."""
    blobs = {inst: FmuBlob.read(p) for inst, p in paths.items()}
    # one key per call: a key released by the previous sweep and scattered again at once
    # can be dropped by the scheduler's late release ("lost dependencies")
    tag = uuid.uuid4().hex[:12]
    by_key = {f"glider-fmu-{b.sha256}-{tag}": b for b in blobs.values()}
    futures = client.scatter(by_key, broadcast=True, hash=False)
    return {inst: futures[f"glider-fmu-{b.sha256}-{tag}"] for inst, b in blobs.items()}


_CACHE: dict[str, Path] = {}  # sha256 -> local file, in this process
_OWN_CACHE_DIR: list[tempfile.TemporaryDirectory] = []


def _cache_root() -> Path:
    """The worker's local directory, or a folder of this process outside a worker."""
    with contextlib.suppress(ImportError, ValueError):
        from distributed import get_worker

        return Path(get_worker().local_directory) / "glider-cosim-fmus"
    if not _OWN_CACHE_DIR:
        _OWN_CACHE_DIR.append(tempfile.TemporaryDirectory(prefix="glider-cosim-fmus-"))
    return Path(_OWN_CACHE_DIR[0].name)


def local_fmu(blob: FmuBlob | str | Path) -> Path:
    """The FMU as a file of this process: a blob is written once into the local cache
    (checked against its hash); a path is used as it is."""
    if not isinstance(blob, FmuBlob):
        return Path(blob)
    path = _CACHE.get(blob.sha256)
    if path is not None and path.exists():
        return path
    if hashlib.sha256(blob.data).hexdigest() != blob.sha256:
        raise SweepClusterError(f"{blob.name}: the received bytes do not match their SHA-256")
    path = _cache_root() / blob.sha256 / blob.name
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{blob.name}.{os.getpid()}.tmp")
        tmp.write_bytes(blob.data)
        os.replace(tmp, path)
    _CACHE[blob.sha256] = path
    return path


__all__ = [
    "FmuBlob",
    "SweepClusterError",
    "check_workers",
    "local_fmu",
    "make_client",
    "package_version",
    "scatter_fmus",
]
