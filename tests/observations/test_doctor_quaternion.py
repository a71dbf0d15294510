"""The convention doctor's quaternion-order slips, both ways (boresight/observations/doctor.py, ``_quat_variants``).

With P = ``np.roll(·, 1)`` (scalar-last → scalar-first) and C the conjugation, a file written from an attitude
source whose order was declared wrong holds P q (scalar-first data read as scalar-last: ``quaternion_scalar_first``)
or P⁻¹ q (scalar-last data read as scalar-first: ``quaternion_read_as_scalar_first``) — or, when the source was
star tracker → inertial and the reader conjugated it after the reordering, C P C q or C P⁻¹ C q (the same two slips,
their second variant). Until the doctor tried P⁻¹ q both ways, ``boresight check`` called it a bare "large
rotation" (66° on the flight example, 159° on the pushbroom one), and C P⁻¹ C q was named
``quaternion_scalar_first`` with a 180° rotation left: undoing the wrong slip fits such a file as well, turned by a
fixed 180°. Here each form is written into a file of each shipped example kind (the flight pass, the star
calibration, the pushbroom strip) and ``boresight check`` must exit 4 naming exactly that slip; the clean files
pass. The order and the direction both wrong (C P^±1, P^±1 C) were "large rotation" too; the doctor tries them once
the declared conventions fail, and names them. A hypothesis test draws θ, the tracker mount and the pass and asserts
the same on simulated sets.
"""

from __future__ import annotations

import dataclasses

import builders
import numpy as np
import pytest
from cli_argv import flight_pass_argv
from cli_run import run_cli
from hypothesis import given, settings
from hypothesis import strategies as st

import boresight
from boresight.observations.doctor import BODY_TO_INERTIAL, SLIPS, diagnose_conventions

CONJ = np.array([-1.0, -1.0, -1.0, 1.0])


def _roll(q, k):
    return np.roll(q, k, axis=-1)


#: the quaternions a file holds after the slip, from the true ones (scalar last, inertial → star tracker)
ORDER_SLIPS = {
    "P": lambda q: _roll(q, 1),
    "P^-1": lambda q: _roll(q, -1),
    "CPC": lambda q: _roll(q * CONJ, 1) * CONJ,
    "CP^-1C": lambda q: _roll(q * CONJ, -1) * CONJ,
}
#: the slip the doctor must name for each, and whether its message carries the star tracker → inertial note
NAMED = {
    "P": ("quaternion_scalar_first", False),
    "P^-1": ("quaternion_read_as_scalar_first", False),
    "CPC": ("quaternion_scalar_first", True),
    "CP^-1C": ("quaternion_read_as_scalar_first", True),
}
#: the order and the direction both wrong, tried when the declared conventions fail (``doctor._double_quat_variants``)
DOUBLE_SLIPS = {
    "CP": lambda q: _roll(q, 1) * CONJ,
    "PC": lambda q: _roll(q * CONJ, 1),
    "CP^-1": lambda q: _roll(q, -1) * CONJ,
    "P^-1C": lambda q: _roll(q * CONJ, -1),
}
DOUBLE_NAMED = {
    "CP": "quaternion_scalar_first_conjugated",
    "PC": "quaternion_scalar_first_conjugated",
    "CP^-1": "quaternion_read_as_scalar_first_conjugated",
    "P^-1C": "quaternion_read_as_scalar_first_conjugated",
}


@pytest.fixture(scope="module")
def example_files(tmp_path_factory):
    """The three shipped example kinds as the tutorials write them: the flight pass (ingest), the star calibration
    (simulate) and the pushbroom strip (ingest)."""
    d = tmp_path_factory.mktemp("examples")
    argvs = {
        "frame": flight_pass_argv(d / "pass.ecsv"),
        "stars": ["simulate", "star-calibration", "--out", str(d)],
        "pushbroom": [
            "ingest",
            "--example",
            "pushbroom-pass",
            "--sigma-pixel-px",
            "0.3",
            "--sigma-star-tracker-arcsec",
            "0.3",
            "--out",
            str(d / "strip.ecsv"),
        ],
    }
    for argv in argvs.values():
        code, _, err = run_cli(argv)
        assert code == 0, (argv, err)
    return {"frame": d / "pass.ecsv", "stars": d / "star-calibration.ecsv", "pushbroom": d / "strip.ecsv"}


def _write_slipped(kind, path, slip, out):
    """``path`` with its quaternions replaced by ``slip(q)``: the frame and star files' ``q_is``, the pushbroom
    file's tracker samples (its lines SLERP them, and SLERP commutes with a signed permutation of the components)."""
    if kind == "pushbroom":
        from astropy.table import Table

        t = Table.read(path, format="ascii.ecsv")
        tracker = t.meta["pushbroom"]["tracker"]
        tracker["quat"] = slip(np.asarray(tracker["quat"], float)).tolist()
        t.write(out, format="ascii.ecsv")
        return out
    from boresight.observations.ecsv import read_ecsv

    obs = read_ecsv(path, geometry_checks=False)
    return dataclasses.replace(obs, q_is=slip(obs.q_is), check_geometry=False).write(out)


KINDS = ("frame", "stars", "pushbroom")


@pytest.mark.parametrize("kind", KINDS)
def test_clean_example_files_pass(example_files, kind):
    code, out, err = run_cli(["check", example_files[kind]])
    assert code == 0, err
    assert "quaternion_read_as_scalar_first" in out  # the new row is in the table
    assert "first_conjugated" not in out  # the double slips are tried only when the declared conventions fail


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("form", list(ORDER_SLIPS))
def test_check_names_the_order_slip_on_a_written_file(example_files, tmp_path, kind, form):
    """``boresight check`` exits 4 naming exactly the slip (its message head, the variant's note only on the star
    tracker → inertial variant), not "large rotation" nor the opposite order."""
    from boresight.cli.exit_codes import EXIT_CONVENTION

    bad = _write_slipped(kind, example_files[kind], ORDER_SLIPS[form], tmp_path / f"{form}.ecsv")
    code, out, err = run_cli(["check", bad])
    slip, b2i = NAMED[form]
    assert code == EXIT_CONVENTION == 4, (out, err)
    assert "ConventionError" in err and "LargeRotationError" not in err and "large rotation" not in err, err
    assert SLIPS[slip] in err, err
    other = "quaternion_read_as_scalar_first" if slip == "quaternion_scalar_first" else "quaternion_scalar_first"
    assert SLIPS[other] not in err, err
    assert (BODY_TO_INERTIAL in err) == b2i, err


@pytest.mark.parametrize("kind", KINDS)
def test_order_and_direction_both_wrong_are_named(example_files, tmp_path, kind):
    """C P^±1 and P^±1 C (two slips at once) were "large rotation" (118°, 109°, 109°, 116° on the flight example); the
    doctor now names them, each pair of 180° twins (C P, P⁻¹ C) apart by the smallest rotation."""
    from boresight.observations.ecsv import read_ecsv
    from boresight.observations.strip_file import read_strip_file

    for form, slip in DOUBLE_SLIPS.items():
        bad = _write_slipped(kind, example_files[kind], slip, tmp_path / f"{form}.ecsv")
        obs = read_strip_file(bad, geometry_checks=False).obs if kind == "pushbroom" else read_ecsv(bad, geometry_checks=False)
        dg = diagnose_conventions(obs)
        assert dg.verdict == DOUBLE_NAMED[form], (form, dg.message)
        assert dg.message.startswith(SLIPS[DOUBLE_NAMED[form]]) and dg.rotation_deg[dg.verdict] < 1.0, (form, dg.message)


THETA = st.floats(-1500.0, 1500.0)  # arcsec, each axis: |θ| < 0.73°, under the doctor's 1° rotation rule


@settings(max_examples=25, deadline=None)
@given(
    theta=st.tuples(THETA, THETA, THETA),
    mount=st.tuples(st.floats(-180, 180), st.floats(-90, 90), st.floats(-180, 180)),
    law=st.sampled_from(["nadir", "site_tracking"]),
    site=st.integers(0, len(builders.SMALL_CAMPAIGN_SITES) - 1),
    seed=st.integers(0, 2**32 - 1),
)
def test_order_slips_named_and_never_on_clean_data(theta, mount, law, site, seed):
    """Over random θ, tracker mounts and passes (one pass of ``builders.small_campaign``: nadir, 24 landmarks in
    9 s, or site tracking, 10 in 90 s; Kiev noise): the clean set passes and names no slip, and each order-slip
    form is named as ``NAMED`` and ``DOUBLE_NAMED`` say."""
    sc = builders.small_campaign(passes=(law,))
    lat, lon, direction = builders.SMALL_CAMPAIGN_SITES[site]
    sc = dataclasses.replace(
        sc,
        theta_true_arcsec=theta,
        star_tracker_mount_deg=mount,
        passes=(dataclasses.replace(sc.passes[0], site_lat_deg=lat, site_lon_deg=lon, direction=direction),),
    )
    obs = boresight.simulate(sc, np.random.default_rng(seed))
    dg = diagnose_conventions(obs)
    assert dg.verdict is None, dg.message
    for form, slip in ORDER_SLIPS.items():
        dg = diagnose_conventions(dataclasses.replace(obs, q_is=slip(obs.q_is), check_geometry=False))
        assert dg.verdict == NAMED[form][0], (form, dg.message)
        assert (BODY_TO_INERTIAL in dg.message) == NAMED[form][1], (form, dg.message)
    for form, slip in DOUBLE_SLIPS.items():
        dg = diagnose_conventions(dataclasses.replace(obs, q_is=slip(obs.q_is), check_geometry=False))
        assert dg.verdict == DOUBLE_NAMED[form], (form, dg.message)
