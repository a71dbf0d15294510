"""Seeding by blocks and the chunk plan: why a study's numbers do not depend on the chunking.

Runs are grouped in fixed blocks of ``block_runs``; block b draws from its own generator
``default_rng(block_seed(seed, b))``. A chunk is any run range, a list of block segments
``(block, start, stop)`` (``plan_chunks``); see the package docstring.
"""

from __future__ import annotations

import numpy as np

from boresight.errors import InputValueError

#: runs per random-number block (part of the result's identity, like the seed)
BLOCK_RUNS = 1000


def block_seed(seed: int, block: int) -> np.random.SeedSequence:
    """The seed sequence of run block ``block``: child ``block`` of ``SeedSequence(seed)``.

    >>> block_seed(1, 3).spawn_key == np.random.SeedSequence(1).spawn(4)[3].spawn_key
    True
    """
    return np.random.SeedSequence(seed, spawn_key=(int(block),))


def plan_chunks(runs: int, chunk_runs: int, block_runs: int = BLOCK_RUNS, start_block: int = 0) -> list:
    """Split runs ``start_block·block_runs``..runs−1 into chunks of ``chunk_runs``; each chunk is
    a list of block segments ``(block, start, stop)`` (run offsets inside the block).

    >>> plan_chunks(5, 3, block_runs=2)
    [[(0, 0, 2), (1, 0, 1)], [(1, 1, 2), (2, 0, 1)]]
    >>> plan_chunks(5, 3, block_runs=2, start_block=1)
    [[(1, 0, 2), (2, 0, 1)]]
    """
    for name, v in (("runs", runs), ("chunk_runs", chunk_runs), ("block_runs", block_runs)):
        if not (isinstance(v, (int, np.integer)) and v >= 1):
            raise InputValueError(f"{name} must be an integer ≥ 1, got {v!r}")
    chunks = []
    for a in range(int(start_block) * block_runs, runs, chunk_runs):
        b = min(a + chunk_runs, runs)
        segs, k = [], a
        while k < b:
            blk = k // block_runs
            stop = min(b, (blk + 1) * block_runs)
            segs.append((blk, k - blk * block_runs, stop - blk * block_runs))
            k = stop
        chunks.append(segs)
    return chunks


#: a block's draws hold at most about this many landmark observations (see ``default_block_runs``)
BLOCK_OBSERVATIONS = 2_000_000


def default_block_runs(observations_per_run: int) -> int:
    """Runs per random-number block: ``BLOCK_RUNS``, fewer when a block's draws would hold more
    than ``BLOCK_OBSERVATIONS`` landmark observations.

    DECISION: a worker draws a whole block to use any part of it (the draws are sequential), so
    a block of a 120-image campaign (15 360 observations per run) at 1000 runs is ~0.5 GB of
    draws per worker; capped at 2·10⁶ observations (≤ 64 MB of pixel noise) it is 130 runs. The
    Kiev scenarios (≤ 80 observations per run) keep 1000, so their numbers are unchanged.

    >>> default_block_runs(4), default_block_runs(15360)
    (1000, 130)
    """
    return int(max(1, min(BLOCK_RUNS, BLOCK_OBSERVATIONS // max(1, int(observations_per_run)))))


def block_size(runs, block, block_runs):
    return min(block_runs, runs - block * block_runs)


def draw_block(scenario, arrays, seed: int, block: int, runs: int, block_runs: int = BLOCK_RUNS) -> dict:
    """All random draws of block ``block`` (θ and sensor errors, ``orbits.draw_scenario_errors``)."""
    import orbits

    rng = np.random.default_rng(block_seed(seed, block))
    return orbits.draw_scenario_errors(scenario, rng, block_size(runs, block, block_runs), arrays)
