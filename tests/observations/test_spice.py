"""SPICE kernels as flight inputs (boresight ingest --spk/--ck/--fk, optional extra `spice`): kernels
written with spiceypy from a simulated pass → ingest → estimate equal to the OEM/AEM route."""

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from cli_argv import KIEV2012_NOISE, ingest_argv

import boresight
from boresight.cli.main import main
from boresight.observations import flight as bio

pytest.importorskip("spiceypy")
pytest.importorskip("oem")


from flight_camera import camera

CAMERA = camera(k1=-0.05, k2=0.01)


def test_spice_round_trip_equals_the_oem_aem_route(flight_obs, tmp_path, capsys):
    from boresight.observations.flight.spice import write_spice_kernels

    p = bio.export_flight_files(flight_obs, tmp_path / "ccsds", CAMERA)
    t = Time(Time(flight_obs.epoch_utc, scale="utc") + flight_obs.t_s * u.s, precision=6)
    t = Time(t.isot, scale="utc", precision=6)  # the detections' image times, as written
    k = write_spice_kernels(tmp_path / "spice", t, flight_obs.r_sc_i_m[0], flight_obs.v_sc_i_m_s[0], flight_obs.q_is[0])
    spice = [
        "--spk",
        str(k["spk"]),
        "--ck",
        str(k["ck"]),
        "--fk",
        str(k["fk"]),
        "--spice-kernel",
        str(k["lsk"]),
        "--spice-kernel",
        str(k["sclk"]),
        "--spice-target",
        "BORESIGHT-SIM",
        "--spice-frame",
        "BS_STAR_TRACKER",
    ]
    sight = ["--landmark-sight", flight_obs.landmark_sight]  # what the simulated rows carry (geometric)
    assert main(ingest_argv(p, tmp_path / "ccsds.ecsv", *KIEV2012_NOISE, *sight)) == 0
    assert main(ingest_argv(p, tmp_path / "spice.ecsv", *KIEV2012_NOISE, *sight, orbit_attitude=spice)) == 0
    out = capsys.readouterr().out
    assert "SPICE J2000 → GCRS: identity (J2000 read as ICRF axes)" in out and "boresight has no error estimate" in out
    e1 = boresight.estimate(boresight.ObservationSet.read(tmp_path / "ccsds.ecsv"))
    e2 = boresight.estimate(boresight.ObservationSet.read(tmp_path / "spice.ecsv"))
    assert np.max(np.abs((e1.theta - e2.theta).to_value(u.arcsec))) < 1e-6
    np.testing.assert_allclose(e2.sigma.value, e1.sigma.value, rtol=1e-9)
    # refusals: one line naming the kernel / option
    with pytest.raises(bio.IngestError, match=r"sc.bsp: no state of NOPE relative to EARTH at image time"):
        bio.spice.read_spice(t, spk=[k["spk"]], kernels=[k["lsk"]], target="NOPE")
    only_spk = ["--spk", str(k["spk"]), "--aem", str(p["attitude"])]
    assert main(ingest_argv(p, tmp_path / "x.ecsv", *KIEV2012_NOISE, orbit_attitude=only_spk)) == 1
    assert "--spk needs --spice-target" in capsys.readouterr().err
