"""Worker lifetime: a study's worker processes die with the study, whatever kills it.

DECISION: a killed study must not leave workers computing for minutes ("a killed
10⁶-run study leaves … two orphaned worker processes alive minutes later"). Three layers:

* **The kernel** (``die_with_parent``). On Linux each worker calls
  ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (through ctypes), so the kernel kills it when its parent
  dies from any cause — SIGKILL, SIGTERM, a crash. A worker whose parent is already gone when
  it starts exits at once (the race between the fork and the prctl). Elsewhere a daemon thread
  polls the parent's pid every 0.5 s. Workers ignore SIGINT: Ctrl-C goes to the driver, which
  cancels the queued chunks and terminates them.
* **Local processes** (``engines._LocalEngine``): ``die_with_parent`` is the
  ``ProcessPoolExecutor`` initializer.
* **dask** (``engines._DaskEngine`` with a ``LocalCluster`` it starts): dask.distributed's own
  nanny already makes each worker process watch a pipe from the parent and exit when it closes
  (``distributed.process.AsyncProcess._immediate_exit_when_closed``) — a Python thread, which
  has to get the GIL to act. ``dask_plugin.DieWithParent``, a dask ``WorkerPlugin`` (its own module: importing
  dask.distributed costs a second, paid only by the dask engine), adds the kernel's
  guarantee to every worker process, including any the nanny restarts. Workers of a cluster
  given with ``--scheduler`` belong to that cluster, not to the study, and are left alone.

The command line turns the driver's SIGTERM into an orderly stop (``cli.Terminated``): queued
chunks cancelled, workers terminated, temporary files removed, the checkpoint kept for
``--resume``; a second SIGTERM ends it at once (and the kernel then ends the workers).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

__all__ = ["die_with_parent", "exists"]

#: Linux prctl option: the signal a process receives when its parent dies
PR_SET_PDEATHSIG = 1


def _arm_pdeathsig() -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover - exotic libc
        return False


def die_with_parent(parent_pid: int, ignore_sigint: bool = True) -> None:
    """Make this (worker) process die when ``parent_pid`` — its parent — dies.

    ``ignore_sigint`` (our own pool's workers): Ctrl-C is left to the driver, and SIGTERM gets
    its default action back (a forked worker inherits the command line's handler). dask's
    workers keep dask's signal handling (``ignore_sigint=False``).

    Call it first thing in the worker (an initializer). Note: the kernel's "parent" is the
    thread that created the process; the engines create their workers from threads that live
    as long as the pool.
    """
    if ignore_sigint and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        # a forked worker inherits the driver's Python handlers: SIGTERM (the pool's terminate())
        # must end it, not raise the command line's ``Terminated`` inside a chunk
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    armed = _arm_pdeathsig()
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)
    if not armed:  # pragma: no cover - not Linux

        def watch():
            while True:
                time.sleep(0.5)
                if os.getppid() != parent_pid:
                    os._exit(1)

        threading.Thread(target=watch, daemon=True).start()


def exists(pid: int) -> bool:
    """Is there a process ``pid``?"""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # pragma: no cover - someone else's pid
        return True
    return True
