"""The dask side of worker lifetime (``lifetime``): a ``WorkerPlugin`` that makes each worker
process of a ``LocalCluster`` the study started die with the study (PR_SET_PDEATHSIG).

Only ``engines._DaskEngine`` imports this module (it imports dask.distributed).
"""

from __future__ import annotations

import os

from distributed.diagnostics.plugin import WorkerPlugin

from boresight.studies.montecarlo.lifetime import die_with_parent, exists

__all__ = ["DieWithParent"]


class DieWithParent(WorkerPlugin):
    """``die_with_parent(parent_pid)`` in each worker process (``parent_pid`` = the study's
    pid, whose nannies spawn the worker processes), including workers the nanny restarts. A
    worker running in the study's own process (``processes=False``) is left alone."""

    name = "boresight-die-with-parent"

    def __init__(self, parent_pid: int):
        self.parent_pid = int(parent_pid)

    def setup(self, worker):
        if os.getpid() == self.parent_pid:
            return
        if os.getppid() == self.parent_pid or not exists(self.parent_pid):
            die_with_parent(self.parent_pid, ignore_sigint=False)  # exits at once if the study is gone
