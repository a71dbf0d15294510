"""Observation format 1.1: velocity columns, the noise model, derived velocity; 1.0 still read."""

from dataclasses import replace

import numpy as np
import pytest
from astropy.table import Table

import boresight
import orbits
from boresight import DisturbanceModel, ObservationFileError, ObservationSet
from boresight.observations.velocity import MAX_TRUNCATION_M_S, derive_velocity

KALMAN20 = "scenarios/kiev2012-kalman20.toml"


@pytest.fixture(scope="module")
def obs():
    return boresight.simulate(KALMAN20, np.random.default_rng(5), runs=2)


def test_simulated_set_carries_velocity_and_noise(obs):
    sc = orbits.load_scenario(KALMAN20)
    assert obs.v_sc_i_m_s.shape == (2, 20, 3)
    speed = np.linalg.norm(obs.v_sc_i_m_s, axis=-1)
    r = np.linalg.norm(obs.truth["r_sc_i_m"], axis=-1)
    # circular orbit: |v| = sqrt(mu/|r|) (independent of the simulator's own state function)
    assert np.allclose(speed, np.sqrt(3.986004418e14 / r)[None], rtol=1e-9)
    assert obs.noise["gnss"] == {"sigma_m": sc.sigma_gnss_m, "error_mode": sc.gnss_error_mode}
    assert obs.noise["star_tracker"]["sigma_arcsec"] == list(sc.sigma_star_tracker_arcsec)
    assert DisturbanceModel.from_observations(obs) == DisturbanceModel.from_scenario(sc)
    assert obs.velocity_status == "given"


def test_write_read_round_trip_1_1(obs, tmp_path):
    path = obs.write(tmp_path / "a.ecsv")
    t = Table.read(path)
    assert str(t["v_x"].unit) == "m / s" and t.meta["format_version"] == "1.1"
    assert set(t.meta["noise"]) == {"pixel", "star_tracker", "gnss", "catalogue"}
    back = ObservationSet.read(path)
    assert np.array_equal(back.v_sc_i_m_s, obs.v_sc_i_m_s)
    assert back.noise == obs.noise
    assert DisturbanceModel.from_observations(back) == DisturbanceModel.from_observations(obs)


def test_format_1_0_file_still_read(obs, tmp_path):
    path = obs.write(tmp_path / "old.ecsv")
    t = Table.read(path)
    t.remove_columns(["v_x", "v_y", "v_z"])
    for k in ("noise", "n_rows"):
        del t.meta[k]
    t.meta["format_version"] = "1.0"
    t.write(path, overwrite=True)
    back = ObservationSet.read(path)
    assert back.v_sc_i_m_s is None and back.noise is None
    assert DisturbanceModel.from_observations(back) is None
    assert np.array_equal(back.xy_m, obs.xy_m)
    # no velocity in the file: derived from the GNSS positions (20 images over 95 s qualify)
    assert back.velocity_status.startswith("derived")
    assert np.abs(back.velocity_i_m_s() - obs.v_sc_i_m_s).max() < 10.0  # σ_R = 15 m: a few m/s


def test_noise_mapping_round_trip_and_validation():
    m = DisturbanceModel(3e-6, (4.8e-6, 4.8e-6, 9.6e-6), "both", 15.0, "per_pass", 0.1)
    back = DisturbanceModel.from_noise(m.to_noise())
    assert back.star_tracker_mode == "both" and back.gnss_mode == "per_pass"
    assert np.allclose(back.sigma_star_tracker_rad, m.sigma_star_tracker_rad, rtol=1e-15)
    assert DisturbanceModel.from_noise({"star_tracker": {"sigma_arcsec": 2.0}}).sigma_star_tracker_rad[2] == pytest.approx(
        2.0 * orbits.rotations.ARCSEC
    )
    for bad, msg in (
        ({"pixel": {"sigma_m": True}}, r"noise.pixel.sigma_m must be a finite number ≥ 0, got True"),
        ({"pixel": {"sigma_m": "3e-6"}}, r"noise.pixel.sigma_m must be a finite number"),
        ({"gnss": {"sigma_m": -1.0}}, r"noise.gnss.sigma_m must be a finite number ≥ 0, got -1.0"),
        ({"gnss": {"error_mode": "daily"}}, r"noise.gnss.error_mode must be one of"),
        ({"gps": {"sigma_m": 1.0}}, r"unknown table\(s\) \['gps'\]"),
        ({"pixel": {"sigma": 1.0}}, r"noise.pixel: unknown key 'sigma' — did you mean 'sigma_m'"),
        ({"star_tracker": {"sigma_arcsec": [1.0, 2.0]}}, r"one number or three"),
    ):
        with pytest.raises(ValueError, match=msg):
            DisturbanceModel.from_noise(bad)


def test_bad_noise_metadata_names_the_file_and_key(obs, tmp_path):
    path = obs.write(tmp_path / "n.ecsv")
    t = Table.read(path)
    t.meta["noise"]["gnss"]["sigma_m"] = "fifteen"
    t.write(path, overwrite=True)
    with pytest.raises(
        ObservationFileError, match=r"n.ecsv: metadata 'noise'.gnss.sigma_m must be a finite number ≥ 0, got 'fifteen'"
    ):
        ObservationSet.read(path)


def test_velocity_columns_in_km_per_s_are_converted(obs, tmp_path):
    path = obs.write(tmp_path / "k.ecsv")
    t = Table.read(path)
    for c in ("v_x", "v_y", "v_z"):
        t[c] = t[c] / 1000.0
        t[c].unit = "km / s"
    t.write(path, overwrite=True)
    back = ObservationSet.read(path)
    assert np.allclose(back.v_sc_i_m_s, obs.v_sc_i_m_s, rtol=1e-15, atol=0)


@pytest.mark.parametrize(
    "t_s",
    [
        np.arange(0.0, 96.0, 5.0),  # the Kalman table: 20 images over 95 s
        np.arange(-300.0, 301.0, 10.0),  # a 10-minute pass
        np.arange(-600.0, 601.0, 60.0),  # 20 minutes, one image a minute
        np.array([0.0, 1.0, 2.0, 3.0]),  # the minimum: 4 images
    ],
)
def test_derived_velocity_accuracy_noise_free(t_s):
    """Noise-free positions: the derived velocity is within the stated truncation bound of the truth."""
    sc = orbits.load_scenario(KALMAN20)
    p = replace(sc.passes[0], t_s=tuple(t_s), attitude="nadir")
    sim = boresight.simulate(replace(sc, passes=(p,), sigma_gnss_m=0.0), np.random.default_rng(0))
    d = derive_velocity(sim.t_s, sim.pass_index, sim.r_sc_i_m)
    err = np.abs(d.v_i_m_s - sim.v_sc_i_m_s).max()
    assert err <= MAX_TRUNCATION_M_S, (d.status, err)
    # and the derivative is not trivially right: a plain first difference is far worse
    fd = np.diff(sim.r_sc_i_m[0], axis=0) / np.diff(sim.t_s)[:, None]
    assert np.abs(fd - sim.v_sc_i_m_s[0, :-1]).max() > 10 * max(err, 1e-6)


def test_derived_velocity_noise_sigma_is_honest():
    """With GNSS noise σ_R, the error scatter over runs matches the propagated σ_v (χ² test)."""
    sc = orbits.load_scenario(KALMAN20)
    sim = boresight.simulate(replace(sc, gnss_error_mode="per_image"), np.random.default_rng(7), runs=400)
    d = derive_velocity(sim.t_s, sim.pass_index, sim.r_sc_i_m, gnss_sigma_m=sc.sigma_gnss_m)
    z = (d.v_i_m_s - sim.v_sc_i_m_s) / d.sigma_m_s[None, :, None]
    # mean of z² over 400 runs × 3 axes per image: ~1 ± sqrt(2/1200) = ±0.04; 0.8..1.2 is ≥ 4.9σ,
    # and a factor-2 error in σ_v gives 4 or 0.25
    ms = np.mean(z**2, axis=(0, 2))
    assert np.all((ms > 0.8) & (ms < 1.2)), ms


def test_derived_velocity_refused_when_images_too_sparse(obs):
    t = np.array([0.0, 400.0, 800.0, 1200.0, 1600.0])
    r = np.zeros((1, 5, 3)) + 7e6
    d = derive_velocity(t, np.zeros(5, int), r)
    assert d.v_i_m_s is None and d.status.startswith("unavailable: pass 0 has 5 images over 1600 s")
    d = derive_velocity(t[:3], np.zeros(3, int), r[:, :3])
    assert d.v_i_m_s is None and "3 image(s), need ≥ 4" in d.status
    one = replace(obs.images(slice(0, 3)), v_sc_i_m_s=None)
    assert one.velocity_i_m_s() is None and "need ≥ 4" in one.velocity_status


def test_constructor_checks_velocity_and_noise(obs):
    from boresight import ObservationError

    with pytest.raises(ObservationError, match=r"v_sc_i_m_s: expected shape \(2, 20, 3\)"):
        replace(obs, v_sc_i_m_s=np.zeros((2, 20)))
    with pytest.raises(ObservationError, match=r"ObservationSet.noise.pixel.sigma_m must be a finite number ≥ 0, got nan"):
        replace(obs, noise={"pixel": {"sigma_m": float("nan")}})


def test_simulate_cli_writes_velocity_and_noise(tmp_path):
    from boresight.cli.main import main

    assert main(["simulate", KALMAN20, "--out", str(tmp_path)]) == 0
    back = ObservationSet.read(tmp_path / "kiev2012-kalman20.ecsv")
    assert back.v_sc_i_m_s is not None and back.noise["pixel"]["sigma_m"] == 3e-6
