"""Direct and inverse location against Orekit Rugged (pyrugged): an optional, slow, independent oracle (issue 29).

pyrugged (Apache-2.0) is CS GROUP's Python port of Rugged on Orekit through the ``orekit-jcc`` Java bridge; it needs a
Java runtime and is an optional extra (``python -m pip install ".[rugged]"`` in a checkout). Skipped cleanly where either is missing.

Rugged is given what boresight locates with: the orbit samples (GCRF, 8-point Hermite on P and V), the camera
attitude C_IK at the star tracker's 4 Hz samples (Rugged interpolates them with 2 points, angles only; the
agreement below bounds its difference from boresight's SLERP) as the spacecraft attitude, so Rugged's
spacecraft frame is the camera frame K, and each pixel's K-frame line of sight (``LineSensor.look_direction``
with θ, the chip offsets and the focal scale) as a fixed line-of-sight table; the same linear datation; a
constant 1000 m above WGS84 (``ConstantElevationAlgorithm``). Jitter is left out (Rugged would interpolate it from
attitude samples: a different model, not a check).

DECISION: the epoch is 2021-06-01, inside the Earth-orientation data pyrugged 1.3.0 bundles (its finals2000A.all
ends in March 2023, with predictions; after it Orekit takes UT1 − UTC and polar motion as zero, and the frames
then differ from astropy's by 0.55″ — 17 m on the ground at 2024-06-01). At 2021-06-01 Orekit's ITRF → GCRF and
astropy's ITRS → GCRS differ by 0.35-0.50 mas (1-2 mm on the ground from 580 km).

Measured (the run of 27 Nov 2026, OpenJDK 17, pyrugged 1.3.0, 50 random pixels on a 30° roll strip): boresight and
Rugged agree to ≤ 2.2 mm north, ≤ 1.9 mm east, for each of the four light-time / aberration settings (the
corrections themselves, 0.7 m and 15 m, agree to < 1 µm); the test allows 1 cm (0.005 px of 2.1 m).
"""

import numpy as np
import pytest

pytestmark = pytest.mark.slow

EPOCH = "2021-06-01T03:00:00"
HEIGHT_M = 1000.0


def _rugged_modules():
    pytest.importorskip("orekit_jcc", reason="pyrugged needs orekit-jcc (optional extra 'rugged')")
    pytest.importorskip("pyrugged", reason="optional extra 'rugged' not installed")
    try:
        from pyrugged.configuration.init_orekit import init_orekit

        init_orekit()
    except Exception as exc:  # no Java runtime, or the VM does not start
        pytest.skip(f"pyrugged could not start Orekit's Java VM: {exc}")
    from org.hipparchus.geometry.euclidean.threed import Rotation, Vector3D
    from org.orekit.time import AbsoluteDate, TimeScalesFactory
    from org.orekit.utils import (
        AngularDerivativesFilter,
        CartesianDerivativesFilter,
        TimeStampedAngularCoordinates,
        TimeStampedPVCoordinates,
    )

    return dict(
        Rotation=Rotation,
        Vector3D=Vector3D,
        AbsoluteDate=AbsoluteDate,
        TimeScalesFactory=TimeScalesFactory,
        AngularDerivativesFilter=AngularDerivativesFilter,
        CartesianDerivativesFilter=CartesianDerivativesFilter,
        TimeStampedAngularCoordinates=TimeStampedAngularCoordinates,
        TimeStampedPVCoordinates=TimeStampedPVCoordinates,
    )


def _rugged_model(j, sensor, geo, params, attitude_t_s=None):
    """A pyrugged model of the strip (module docstring): attitude = camera attitude, lines of sight in K."""
    from pyrugged.bodies.body_rotating_frame_id import BodyRotatingFrameId
    from pyrugged.bodies.ellipsoid_id import EllipsoidId
    from pyrugged.line_sensor.line_sensor import LineSensor as RuggedLineSensor
    from pyrugged.line_sensor.linear_line_datation import LinearLineDatation as RuggedDatation
    from pyrugged.los.los_builder import LOSBuilder
    from pyrugged.model.inertial_frame_id import InertialFrameId
    from pyrugged.model.pyrugged_builder import PyRuggedBuilder

    from orbits.pushbroom import camera_attitude
    from orbits.rotations import quat_from_dcm

    V = j["Vector3D"]
    traj = geo.trajectory
    epoch = j["AbsoluteDate"](2021, 6, 1, 3, 0, 0.0, j["TimeScalesFactory"].getUTC())
    pv = [
        j["TimeStampedPVCoordinates"](epoch.shiftedBy(float(t)), V(*map(float, r)), V(*map(float, v)))
        for t, r, v in zip(traj.orbit_t_s, traj.orbit_r_i_m, traj.orbit_v_i_m_s, strict=True)
    ]
    # Hipparchus Rotation(q0, q1, q2, q3).applyTo(u) = A(q) u for our scalar-last q = [q1, q2, q3, q0]: the
    # frame transform inertial → spacecraft, as Orekit's attitude is
    att_t = traj.tracker_t_s if attitude_t_s is None else attitude_t_s
    quat = quat_from_dcm(camera_attitude(traj, att_t, params))
    att = [
        j["TimeStampedAngularCoordinates"](
            epoch.shiftedBy(float(t)), j["Rotation"](*map(float, (q[3], q[0], q[1], q[2])), True), V.ZERO, V.ZERO
        )
        for t, q in zip(att_t, quat, strict=True)
    ]
    b = PyRuggedBuilder()
    b.set_ellipsoid(ellipsoid_id=EllipsoidId.WGS84, body_rotating_frame_id=BodyRotatingFrameId.ITRF)
    lo, hi = traj.span_s
    b.set_time_span(epoch.shiftedBy(lo + 0.5), epoch.shiftedBy(hi - 0.5), 0.01, 5.0)
    b.set_trajectory(
        pv,
        8,
        j["CartesianDerivativesFilter"].USE_PV,
        att,
        2,
        j["AngularDerivativesFilter"].USE_R,
        inertial_frame_id=InertialFrameId.GCRF,
    )
    chips = np.concatenate([np.full(c.n_pixels, k) for k, c in enumerate(sensor.chips)])
    index = np.concatenate([np.arange(c.n_pixels, dtype=float) for c in sensor.chips])
    los = sensor.look_direction(chips, index, params.focal_scale, params.chip_offsets_rad)
    los /= np.linalg.norm(los, axis=1, keepdims=True)
    dat = RuggedDatation(
        epoch.shiftedBy(float(geo.datation.reference_time_s)),
        float(geo.datation.reference_line),
        1.0 / geo.datation.line_period_s,
    )
    b.add_sensor(RuggedLineSensor("line", dat, np.zeros(3), LOSBuilder([V(*map(float, v)) for v in los]).build()))
    return b.build()


def _calibration_truth():
    """θ, chip look-angle offsets and a focal scale: the parameters Rugged's line-of-sight table is built with."""
    from orbits.pushbroom import LineScanParameters

    return LineScanParameters(
        theta_rad=(1e-4, -2e-4, 3e-4), chip_offsets_rad=[[4e-6, -4e-6], [0.0, 3e-6], [-2e-6, 5e-6]], focal_scale=1e-4
    )


def _located_by_both(roll_deg, params, light_time=True, aberration=True, seed=1, attitude_step_s=None):
    """The zy3-like sensor's strip at ``roll_deg``, Rugged's optical location of it at HEIGHT_M (with Rugged's
    light-time and aberration corrections as given; the camera attitude given every ``attitude_step_s`` if
    set, else at the star tracker's samples) and 50 random (line, pixel) of it, integer pixels (Rugged's
    table holds the integer pixels). Returns (sensor, geometry, Rugged's location, lines, pixels)."""
    j = _rugged_modules()
    from pyrugged.intersection.constant_elevation_algorithm import ConstantElevationAlgorithm
    from pyrugged.location.optical import CorrectionsParams, OpticalLocation

    from orbits.strip import StripConfig, strip_geometry, zy3_like_sensor

    sensor = zy3_like_sensor()
    geo = strip_geometry(StripConfig(sensor, roll_deg=roll_deg, epoch=EPOCH))
    attitude_t_s = None if attitude_step_s is None else np.arange(*geo.trajectory.span_s, attitude_step_s)
    rugged = _rugged_model(j, sensor, geo, params, attitude_t_s=attitude_t_s)
    loc = OpticalLocation(rugged, ConstantElevationAlgorithm(HEIGHT_M), CorrectionsParams(light_time, aberration, None))
    rng = np.random.default_rng(seed)
    L = rng.uniform(0, geo.config.n_lines - 1, 50)
    P = rng.integers(0, sensor.n_pixels, 50).astype(float)
    return sensor, geo, loc, L, P


@pytest.mark.parametrize("light_time, aberration", [(True, True), (False, False), (True, False), (False, True)])
def test_direct_location_agrees_with_orekit_rugged(light_time, aberration):
    from orbits.pushbroom import SightCorrections, direct_location, geodetic_from_itrs

    params = _calibration_truth()
    sensor, geo, loc, L, P = _located_by_both(30.0, params, light_time, aberration)
    lon_r, lat_r, h_r = map(np.asarray, loc.direct_location(list(L), list(P), sensor_name="line"))
    g = direct_location(sensor, geo.datation, geo.trajectory, L, P, params, HEIGHT_M, SightCorrections(light_time, aberration))
    lat, lon, h = geodetic_from_itrs(g)
    north_m = (lat_r - lat) * 6_378_137.0
    east_m = (lon_r - lon) * 6_378_137.0 * np.cos(lat)
    assert np.max(np.abs(north_m)) < 0.01 and np.max(np.abs(east_m)) < 0.01
    assert np.max(np.abs(h_r - HEIGHT_M)) < 1e-5 and np.max(np.abs(h - HEIGHT_M)) < 1e-5


def test_inverse_location_agrees_with_orekit_rugged():
    """Rugged's own inverse location (mean-plane crossing, pixel crossing, its line fix) of 50 ground points located
    by boresight at 1000 m: each of Rugged's (line, pixel) is one of boresight's per-chip solutions (a point in a
    chip overlap is seen by two chips; Rugged returns one of them) to ≤ 5e-3 line and pixel. Measured (27 Nov 2026,
    the module's set-up): ≤ 1.03e-3 line, ≤ 7.1e-4 pixel — the 1-2 mm of the two libraries' Earth orientations."""
    from orbits.pushbroom import direct_location, geodetic_from_itrs, inverse_location

    params = _calibration_truth()
    sensor, geo, loc, L, P = _located_by_both(30.0, params)
    g = direct_location(sensor, geo.datation, geo.trajectory, L, P, params, HEIGHT_M)
    lat, lon, h = geodetic_from_itrs(g)
    lines_r, pixels_r = map(
        lambda a: np.asarray(a, float), loc.inverse_location(0, geo.config.n_lines - 1, lat, lon, h, sensor_name="line")
    )
    inv = inverse_location(sensor, geo.datation, geo.trajectory, g, geo.line_range, params)
    gap = np.maximum(np.abs(inv.line - lines_r), np.abs(inv.pixel - pixels_r))  # (chips, points), NaN where not seen
    assert np.all(np.isfinite(lines_r))
    assert np.nanmax(np.nanmin(gap, axis=0)) < 5e-3


def test_direct_location_with_jitter_agrees_with_orekit_rugged():
    """With a 0.65 Hz jitter of ~1 px on every axis, Rugged is given the camera attitude every 10 ms (its 2-point
    interpolation of the sinusoid errs by A (2π f)² Δt² / 8 ≈ 1e-9 rad, 0.6 mm): the jittered direct locations agree
    as the plain ones do. Measured (27 Nov 2026, −30° roll; the jitter moves the points by up to 3.5 m): ≤ 1.0 mm
    north, ≤ 2.7 mm east; the test allows 1 cm."""
    from orbits.pushbroom import LineScanParameters, direct_location, geodetic_from_itrs

    params = LineScanParameters(
        theta_rad=(1e-4, -2e-4, 3e-4),
        jitter_frequency_hz=[0.65],
        jitter_amplitude_rad=[[4e-6, 4e-6, 2e-6]],
        jitter_phase_rad=[[0.1, 1.0, 2.0]],
    )
    sensor, geo, loc, L, P = _located_by_both(-30.0, params, seed=2, attitude_step_s=0.01)
    lon_r, lat_r, _ = map(np.asarray, loc.direct_location(list(L), list(P), sensor_name="line"))
    lat, lon, _ = geodetic_from_itrs(direct_location(sensor, geo.datation, geo.trajectory, L, P, params, HEIGHT_M))
    plain = geodetic_from_itrs(
        direct_location(sensor, geo.datation, geo.trajectory, L, P, LineScanParameters(theta_rad=params.theta_rad), HEIGHT_M)
    )
    assert np.max(np.hypot(lat - plain[0], (lon - plain[1]) * np.cos(lat))) * 6_378_137.0 > 1.0  # the jitter moves points
    assert np.max(np.abs(lat_r - lat)) * 6_378_137.0 < 0.01
    assert np.max(np.abs((lon_r - lon) * np.cos(lat))) * 6_378_137.0 < 0.01
