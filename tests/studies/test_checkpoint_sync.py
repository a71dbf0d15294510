"""Block checkpoints are flushed to disk as a group, not one fsync per block (issue 19), without
losing crash safety: a block file a power cut left empty or torn is never loaded — the resume
redoes it and gives the numbers of an uninterrupted study."""

from __future__ import annotations

import os

import numpy as np
import pytest
from paths import SCENARIOS

from boresight.studies import montecarlo as mc
from boresight.studies.montecarlo import checkpoint as ck

SENS = SCENARIOS / "kiev2012-sensitivity.toml"
ARGS = dict(algorithms=["image_plane"], runs=50, seed=3, block_runs=10, chunk_runs=10, workers=1)


def _fsyncs(monkeypatch) -> list:
    calls = []
    real = os.fsync

    def counting(fd):
        calls.append(fd)
        real(fd)

    monkeypatch.setattr(os, "fsync", counting)
    return calls


def test_blocks_are_not_flushed_one_by_one_but_as_a_group(tmp_path, monkeypatch):
    calls = _fsyncs(monkeypatch)
    mc.montecarlo_study(SENS, checkpoint=tmp_path / "a", **ARGS)
    assert len(list((tmp_path / "a").glob("block-*.npz"))) == 5
    assert len(calls) == 1  # study.json only; the 5 blocks wait for the group flush (SYNC_INTERVAL_S)
    monkeypatch.setattr(ck, "SYNC_INTERVAL_S", 0.0)  # a flush due at every block: each file, then the folder
    calls.clear()
    mc.montecarlo_study(SENS, checkpoint=tmp_path / "b", **ARGS)
    assert len(calls) == 1 + 5 * 2


def test_an_interrupted_study_flushes_its_finished_blocks(tmp_path, monkeypatch):
    from boresight.studies.montecarlo import accumulator

    calls = _fsyncs(monkeypatch)
    real = accumulator.Accumulator.merge_block

    def interrupt_at_block_3(self, b, *a):
        if b == 3:
            raise KeyboardInterrupt
        real(self, b, *a)

    monkeypatch.setattr(accumulator.Accumulator, "merge_block", interrupt_at_block_3)
    with pytest.raises(KeyboardInterrupt):
        mc.montecarlo_study(SENS, checkpoint=tmp_path, **ARGS)
    # study.json, then blocks 0..3 (block 3 is saved before its merge) and the folder at the interruption
    assert len(calls) == 1 + 4 + 1


@pytest.mark.parametrize("damage", ["empty", "torn"])
def test_a_block_a_power_cut_left_unreadable_is_redone_not_loaded(tmp_path, damage):
    whole = mc.montecarlo_study(SENS, **ARGS)
    mc.montecarlo_study(SENS, checkpoint=tmp_path, **ARGS)
    block2 = tmp_path / "block-000000002.npz"
    data = block2.read_bytes()
    # a renamed but unflushed file after a power cut: empty, or its length and zip directory
    # intact but a stretch of its data lost (zeros)
    n = len(data)
    block2.write_bytes(b"" if damage == "empty" else data[: n // 4] + bytes(n // 4) + data[n // 2 :])
    assert ck.Checkpoint(tmp_path).finished_blocks() == 2
    again = mc.montecarlo_study(SENS, checkpoint=tmp_path, resume=True, **ARGS)
    assert again.resumed_blocks == 2
    for k in ("count", "mean", "m2", "max_abs"):
        assert np.array_equal(getattr(again.moments["image_plane"], k), getattr(whole.moments["image_plane"], k))
    assert ck.Checkpoint(tmp_path).finished_blocks() == 5  # block 2 rewritten whole
