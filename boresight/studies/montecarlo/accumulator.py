"""The driver's side of a study: submit chunks with a bounded window, collect their per-run errors,
complete blocks and merge them into the totals in block order (checkpointing each block first)."""

from __future__ import annotations

import numpy as np

from boresight.errors import StudyError
from boresight.studies.montecarlo.chunks import UNCONVERGED, run_chunk
from boresight.studies.montecarlo.moments import Moments
from boresight.studies.montecarlo.seeding import block_size


class Accumulator:
    """Collects chunk results, completes blocks, merges them into the totals in block order
    (and checkpoints each block before merging it, when a ``Checkpoint`` is attached)."""

    def __init__(self, algs, runs, block_runs, keep_runs):
        self.algs, self.runs, self.block_runs, self.keep_runs = algs, runs, block_runs, keep_runs
        self.n_blocks = -(-runs // block_runs)
        self.totals, self.unconverged = {}, {}
        self.samples = {a: [] for a in algs}
        self.kept = 0
        self.next_block = 0
        self.done_runs = 0
        self.pending = {}  # block -> list of (start, {key: rows})
        self.checkpoint = None

    def add(self, segments, errs) -> int:
        off = 0
        for b, a, z in segments:
            self.pending.setdefault(b, []).append((a, {k: v[off : off + z - a] for k, v in errs.items()}))
            off += z - a
        while self.next_block < self.n_blocks:
            parts = self.pending.get(self.next_block, [])
            size = block_size(self.runs, self.next_block, self.block_runs)
            if sum(len(p[1][self.algs[0]]) for p in parts) < size:
                break
            parts.sort(key=lambda p: p[0])
            block = {name: np.concatenate([p[1][name] for p in parts]) for name in parts[0][1]}
            del self.pending[self.next_block]
            self._complete(self.next_block, block)
        return off

    def _complete(self, b, block):
        moments, unconverged, samples = {}, {}, {}
        for name, x in block.items():
            if name.endswith(UNCONVERGED):
                unconverged[name[: -len(UNCONVERGED)]] = x.sum(axis=0).astype(np.int64)
                continue
            if not np.all(np.isfinite(x)):
                row = int(np.argwhere(~np.isfinite(x))[0][0])
                raise StudyError(
                    f"{name}: a non-finite θ̂ in run {b * self.block_runs + row} (block {b}); its geometry or draws make the "
                    "estimate singular — no NaN is written. Check the scenario's noise levels and landmarks"
                )
            moments[name] = Moments.from_samples(x)
            if name in self.samples and self.kept < self.keep_runs:
                samples[name] = x[: self.keep_runs - self.kept]
        if self.checkpoint is not None:
            self.checkpoint.save(b, moments, unconverged, samples)
        self.merge_block(b, moments, unconverged, samples)

    def merge_block(self, b, moments, unconverged, samples):
        if b != self.next_block:
            raise StudyError(f"internal: block {b} merged out of order (expected {self.next_block})")
        for name, mo in moments.items():
            self.totals[name] = mo if name not in self.totals else self.totals[name].merge(mo)
        for name, n in unconverged.items():
            self.unconverged[name] = n if name not in self.unconverged else self.unconverged[name] + n
        size = block_size(self.runs, b, self.block_runs)
        if self.kept < self.keep_runs:
            for name, x in samples.items():
                self.samples[name].append(x)
            self.kept += min(size, self.keep_runs - self.kept)
        self.next_block += 1
        self.done_runs += size


def drive(eng, job, chunks, acc, progress):
    """Submit the chunks with a bounded window of tasks in flight; feed results, in
    completion-of-submission order, to the accumulator."""
    window = 2 * max(1, getattr(eng, "workers", 1))
    done = acc.done_runs
    futures = []
    it = iter(chunks)
    for c in it:
        futures.append(eng.submit(run_chunk, job, c))
        if len(futures) >= window:
            break
    while futures:
        segments, errs = futures.pop(0).result()
        nxt = next(it, None)
        if nxt is not None:
            futures.append(eng.submit(run_chunk, job, nxt))
        done += acc.add(segments, errs)
        if progress is not None:
            progress(done, job.runs)
