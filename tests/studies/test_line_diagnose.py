"""``diagnose_line_scan`` (boresight.studies.discrepancy.line_scan) on one seed per case, and the line-scanner
catalogue in docs/effects.md. The rates over 40/100 seeds are tests/studies/test_pushbroom_mc.py's (slow)."""

import numpy as np
import pytest

from boresight.core.disturbances import DisturbanceModel
from boresight.observations.strip import strip_observations
from boresight.studies.discrepancy.line_scan import diagnose_line_scan
from orbits.effects import line_catalogue_markdown, line_scan_truth
from orbits.strip import GcpLayout, StripConfig, TrackerNoise, simulate_strip, strip_geometry, zy3_like_sensor

ARCSEC = np.pi / 180 / 3600
PX = 7e-6 / 1.7 / ARCSEC
MODEL = DisturbanceModel(sigma_pixel_m=0.3 * 7e-6, sigma_star_tracker_rad=(0.3 * ARCSEC,) * 3, star_tracker_mode="per_image")


@pytest.fixture(scope="module")
def geometry():
    return strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=10.0))


@pytest.mark.parametrize(
    "effects, named",
    [
        ({}, []),
        ({"jitter": {"frequency_hz": 0.65, "amplitude_x_arcsec": PX, "amplitude_y_arcsec": PX, "phase_y_rad": 1.0}}, ["jitter"]),
        ({"chip_offset": {"chip": 2, "along_track_arcsec": 0.5 * PX, "across_track_arcsec": 0.5 * PX}}, ["chip_offset[2]"]),
    ],
    ids=["clean", "jitter", "chip"],
)
def test_one_seed_names_what_was_hidden(geometry, effects, named):
    truth = line_scan_truth(np.array([20.0, -35.0, 50.0]) * ARCSEC, effects, 3)
    sim = simulate_strip(geometry, truth, np.random.default_rng(5), GcpLayout(n_gcps=250), TrackerNoise(0.3), sigma_pixel=0.3)
    d = diagnose_line_scan(strip_observations(sim), MODEL)
    assert d.named == named, d.text()
    if named == ["jitter"]:
        (j,) = [c for c in d.candidates if c.label == "jitter"]
        step = d.jitter_grid_hz[1] - d.jitter_grid_hz[0]
        assert abs(j.frequency_hz - 0.65) <= step and j.k == 6
    assert "named:" in d.text()


def test_docs_list_the_current_line_catalogue():
    """docs/effects.md holds the generated line-scanner catalogue between its markers."""
    text = open("docs/effects.md", encoding="utf-8").read()
    begin = "tests/studies/test_line_diagnose.py checks it is current -->\n"
    block = text.split(begin, 1)[1].split("<!-- end: line-scanner effects -->", 1)[0]
    assert block == line_catalogue_markdown()
