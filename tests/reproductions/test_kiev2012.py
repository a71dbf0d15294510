"""Each paper's published numbers are defined once, in its reproduction package
(``boresight/reproductions/kiev2012/published.py``, ``boresight/reproductions/usv_sea_sky/published.py``)."""

from __future__ import annotations

import re

import pytest
from paths import ROOT

PUBLISHED = {ROOT / "boresight" / "reproductions" / paper / "published.py" for paper in ("kiev2012", "usv_sea_sky")}


def _fingerprints():
    """Runs of consecutive published values (three, or the two of a USV pair), as they would be
    written in source."""
    from boresight.reproductions.kiev2012 import published as p
    from boresight.reproductions.usv_sea_sky import published as usv

    rows = [p.SEMINAR_EQ28_SIGMA_ARCSEC[:3]]
    rows += [v[:3] for v in p.SEMINAR_EQ28.values() if len(set(v[:3])) > 1]
    rows += [v[:3] for k, v in p.SEMINAR_ALGORITHM1_TABLE.items() if k != "t_s"]
    rows += [r[1:4] for r in p.SEMINAR_KALMAN_ROWS]
    rows += [usv.PAPER_SPECIAL_POINTS_DEG, usv.PAPER_COARSE_DEG, usv.PAPER_FINE_DEG]
    return [r"\W*".join(re.escape(f"{x:g}") for x in row) for row in rows]


def test_the_published_numbers_are_not_restated_in_the_code():
    pats = [re.compile(r"(?<![\d.])" + f + r"(?![\d])") for f in _fingerprints()]
    offenders = []
    for path in sorted((ROOT / "boresight").rglob("*.py")) + sorted((ROOT / "orbits").rglob("*.py")):
        if path in PUBLISHED:
            continue
        text = path.read_text()
        offenders += [f"{path.relative_to(ROOT)}: {p.pattern}" for p in pats if p.search(text)]
    assert offenders == []


def test_the_fingerprints_find_a_restatement(tmp_path):
    """The check above can fail: the eq 28 σθ written out again is caught."""
    pats = [re.compile(r"(?<![\d.])" + f + r"(?![\d])") for f in _fingerprints()]
    assert any(p.search("SIGMA = (6.09, 6.09, 8.36)") for p in pats)
    assert any(p.search("rows = [(4, 1.7, 1.9, 10.6, 5.3)]") for p in pats)
    assert any(p.search('print("paper (its points 70.28, 1.076)")') for p in pats)


def test_published_tables_are_consistent():
    import numpy as np

    from boresight.reproductions.kiev2012 import published as p

    # the eq 28 rows add in quadrature to the seminar's σθ (its own consistency, 2-digit rounding)
    sig = {"K": 3e-6, "R": 15.0, "P": 0.1, "beta1": 4.0, "beta2": 4.0, "beta3": 4.0}
    total = np.sqrt(sum((np.asarray(p.SEMINAR_EQ28[s][:3]) * sig[s]) ** 2 for s in sig))
    np.testing.assert_allclose(total, p.SEMINAR_EQ28_SIGMA_ARCSEC[:3], rtol=0.02)
    # its total 11.98″ is the norm of its axes (12.00″ from the rounded 6.09/6.09/8.36) to its rounding
    assert p.SEMINAR_EQ28_SIGMA_ARCSEC[3] == pytest.approx(np.linalg.norm(p.SEMINAR_EQ28_SIGMA_ARCSEC[:3]), abs=0.03)
    assert [r[0] for r in p.SEMINAR_KALMAN_ROWS] == [1, 2, 4, 8, 12, 20] == list(p.SEMINAR_IMAGE_COUNTS)
    # the Monte Carlo study's default grid is chosen to line up with the seminar's rows
    from boresight.studies.montecarlo import DEFAULT_IMAGE_COUNTS

    assert DEFAULT_IMAGE_COUNTS == p.SEMINAR_IMAGE_COUNTS
    assert all(len(v) == 10 for v in p.SEMINAR_ALGORITHM1_TABLE.values())
