"""Where chunks run: local processes (fork, workers die with the parent) or a dask cluster.
An engine has ``submit(fn, *args)`` returning an object with ``result()``, ``workers`` and
``close(abort)``."""

from __future__ import annotations

import os

import numpy as np

from boresight.errors import InputValueError
from boresight.studies.montecarlo.lifetime import die_with_parent


class _LocalEngine:
    def __init__(self, workers):
        self.workers = workers
        self.pool = None
        if workers > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            # DECISION: fork where available — workers inherit the imported numpy/scipy/astropy
            # (a spawned worker spends ~1 s importing them, a fifth of the eq-28 study budget).
            methods = multiprocessing.get_all_start_methods()
            ctx = multiprocessing.get_context("fork" if "fork" in methods else None)
            self.pool = ProcessPoolExecutor(
                max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(),)
            )

    def submit(self, fn, *args):
        if self.pool is None:
            return _Done(fn(*args))
        return self.pool.submit(fn, *args)

    def close(self, abort: bool = False):
        """Shut the pool down; ``abort`` (an error or Ctrl-C in the driver) cancels queued
        chunks and terminates the workers instead of waiting for them."""
        if self.pool is None:
            return
        if abort:
            procs = list(getattr(self.pool, "_processes", {}).values())  # private, but the only handle
            self.pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join(timeout=5)
        else:
            self.pool.shutdown(wait=True)


# DECISION: workers die with their parent, whatever kills it (``lifetime``: PR_SET_PDEATHSIG).
_worker_init = die_with_parent


class _Done:
    def __init__(self, value):
        self._value = value

    def result(self):
        return self._value


def require_dask() -> None:
    """Raise ``MissingExtraError`` (naming the extra) unless dask.distributed can be imported:
    called before a study writes anything, so a missing extra leaves no half-made folder."""
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        from boresight.errors import MissingExtraError, extra_hint

        raise MissingExtraError(
            f"the dask engine needs dask.distributed, which is not installed: {extra_hint('dask')} (or use --engine local)"
        ) from None


class _DaskEngine:
    def __init__(self, workers, scheduler=None, processes=True):
        require_dask()
        from dask.distributed import Client, LocalCluster

        self.cluster = None
        if scheduler:
            self.client = Client(scheduler)
        else:
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes, dashboard_address=None)
            self.client = Client(self.cluster)
            from boresight.studies.montecarlo.dask_plugin import DieWithParent

            self.client.register_plugin(DieWithParent(os.getpid()))  # our cluster's workers die with the study
        self.workers = workers

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def close(self, abort: bool = False):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_engine(engine: str = "local", workers: int | None = None, scheduler: str | None = None, processes: bool = True):
    """A reusable engine (``close()`` it), to share one worker pool among several ``montecarlo_study`` calls."""
    workers = default_workers() if workers is None else workers
    if not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise InputValueError(f"workers must be an integer ≥ 1, got {workers!r}")
    if engine == "local":
        return _LocalEngine(int(workers))
    if engine == "dask":
        return _DaskEngine(int(workers), scheduler, processes)
    raise InputValueError(f"engine must be 'local' or 'dask', got {engine!r}")


def default_workers() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1
