"""Where campaign runs execute: a ``concurrent.futures`` executor (the one module using Dask).

* :func:`local_executor`: a :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers``
  processes (the default);
* :func:`dask_executor` with ``"local"``: a :class:`distributed.LocalCluster` on this
  machine, ``workers`` processes of one thread each, its scheduler and workers listening
  on 127.0.0.1 only and no dashboard;
* :func:`dask_executor` with an address (``tcp://host:8786``): an existing cluster
  (dask-ssh, dask-jobqueue, Kubernetes...), whose workers must see the campaign folder.

Local workers (processes or a LocalCluster) get ``env`` (``PYTHONPATH``...) in their
environment and ignore SIGINT: Ctrl-C is the campaign's, which stops them
(:func:`stop_local`, or closing the LocalCluster). Local worker processes also end with
the campaign's process when it is killed (SIGKILL: on Linux the kernel sends them SIGTERM,
``PR_SET_PDEATHSIG``), as a LocalCluster's workers do by themselves, so that no worker of a
killed campaign goes on writing into its folder. The workers of an existing cluster are
left as they were set up.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
from collections.abc import Iterator, Mapping
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures import as_completed as cf_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any

__all__ = [
    "local_executor", "dask_executor", "open_executor", "stop_local", "scheduler_addresses", "completed", "LOOPBACK",
    "pool_broken", "worker_killed",
]

LOOPBACK = "127.0.0.1"


def _init_worker(env: Mapping[str, str], parent: int | None = None) -> None:
    os.environ.update(env)
    with contextlib.suppress(ValueError):  # only a process's main thread sets handlers
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent is not None:
        _end_with(parent)


_PR_SET_PDEATHSIG = 1


def _end_with(parent: int) -> None:
    """Have the kernel send this process SIGTERM (what :func:`stop_local` sends) when its
    parent ``parent`` dies, however it dies (Linux; elsewhere nothing)."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0) != 0:
            return
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # it died before the request was made
        os.kill(os.getpid(), signal.SIGTERM)


@contextlib.contextmanager
def local_executor(workers: int, env: Mapping[str, str] | None = None) -> Iterator[Executor]:
    """Local worker processes (spawned: no state inherited from the campaign's process)."""
    ex = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_init_worker, initargs=(dict(env or {}), os.getpid()))
    try:
        yield ex
    except BaseException:
        stop_local(ex)
        raise
    else:
        ex.shutdown(wait=True)


def stop_local(ex: Executor) -> None:
    """End the worker processes of a local executor and cancel what has not started
    (the processes are taken before shutdown, which forgets them)."""
    procs = list((getattr(ex, "_processes", None) or {}).values())
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(5)
    ex.shutdown(wait=False, cancel_futures=True)


@contextlib.contextmanager
def dask_executor(scheduler: str, workers: int, env: Mapping[str, str] | None = None) -> Iterator[Executor]:
    """A Dask cluster as an executor: ``"local"`` starts a loopback-only LocalCluster of
    ``workers`` processes (1 thread each); otherwise ``scheduler`` is an existing one's address."""
    import dask.config
    from distributed import Client, LocalCluster

    env = dict(env or {})
    with contextlib.ExitStack() as stack:
        if scheduler == "local":
            # Dask's nannies set MALLOC_TRIM_THRESHOLD_=65536 in their workers (and in this
            # process): glibc then returns memory at every free, and a bench run's numpy
            # work is markedly slower (benchmarks/campaign_scaling.py, docs/campaigns.md)
            stack.enter_context(dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}))
            cluster = stack.enter_context(LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, host=LOOPBACK,
                dashboard_address=None, worker_dashboard_address=None, env=env, silence_logs=40,
            ))
            client = stack.enter_context(Client(cluster))
            client.run(_init_worker, {})  # Ctrl-C is the campaign's, not the workers'
        else:
            client = stack.enter_context(Client(scheduler))
        ex = client.get_executor(pure=False)
        try:
            yield ex
        finally:
            ex.shutdown(wait=False)


def scheduler_addresses(ex: Executor) -> list[str]:
    """The scheduler's and the workers' addresses behind a Dask executor (for checks)."""
    client = ex._client  # type: ignore[attr-defined]
    info = client.scheduler_info()
    return [client.scheduler.address, *info.get("workers", {}).keys()]


@contextlib.contextmanager
def open_executor(scheduler: str | None, workers: int, env: Mapping[str, str] | None = None) -> Iterator[Executor]:
    """Local processes when ``scheduler`` is None, else :func:`dask_executor`."""
    cm = local_executor(workers, env) if scheduler is None else dask_executor(scheduler, workers, env)
    with cm as ex:
        yield ex


def completed(futures: list[Any]) -> Iterator[Any]:
    """The futures of :func:`open_executor` as they finish (Dask's or concurrent.futures')."""
    if futures and not isinstance(futures[0], Future):
        from distributed import as_completed as dask_completed

        yield from dask_completed(futures)
        return
    yield from cf_completed(futures)


def pool_broken(exc: BaseException) -> bool:
    """Whether a run's exception is its local pool breaking (a worker process died: every
    run not finished fails with it)."""
    return isinstance(exc, BrokenProcessPool)


def worker_killed(exc: BaseException) -> bool:
    """Whether a run's exception is Dask giving up on it after its workers died under it
    (``KilledWorker``, after the scheduler's ``allowed-failures`` retries on other workers)."""
    return type(exc).__name__ == "KilledWorker"
