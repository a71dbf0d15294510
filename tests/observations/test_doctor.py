"""Convention doctor (boresight.observations.doctor): each slip injected into a simulated file is named; clean files pass.

Decision rule under test (boresight/observations/doctor.py): a slip is reported when it fits 100× better than the
declared conventions (RMS focal-plane residual), or removes a rotation above 1° at no worse fit.
"""

from dataclasses import replace

import numpy as np
import pytest

import boresight
from boresight.observations.doctor import (
    ConventionError,
    LargeRotationError,
    check,
    diagnose_conventions,
    read_checked,
)


@pytest.fixture(scope="module")
def obs(wgs84_kalman20):
    # WGS-84: real Earth rotation, ITRS and GCRS differ by the sidereal angle (the conftest fixture)
    return boresight.simulate(wgs84_kalman20, np.random.default_rng(np.random.SeedSequence(11)), runs=1)


def _slip(o, **kw):
    # a slipped set fails the in-memory geometry check (behind the camera): the doctor inspects it
    return replace(o, check_geometry=False, **kw)


SLIPS = {
    "x axis looks mirrored": lambda o: _slip(o, xy_m=o.xy_m * [-1.0, 1.0]),
    "y axis looks mirrored": lambda o: _slip(o, xy_m=o.xy_m * [1.0, -1.0]),
    r"quaternions look scalar-first \(q1": lambda o: _slip(o, q_is=np.roll(o.q_is, 1, axis=-1)),  # [w, x, y, z] in q1..q4
    # scalar-last data read as scalar-first upstream: [y, z, w, x] in q1..q4 (doctor._quat_variants)
    r"read as scalar-first upstream \(q1": lambda o: _slip(o, q_is=np.roll(o.q_is, -1, axis=-1)),
    "conjugated": lambda o: _slip(o, q_is=o.q_is * [-1.0, -1.0, -1.0, 1.0]),
    "C_SK_nominal looks transposed": lambda o: _slip(o, C_SK_nominal=o.C_SK_nominal.T),
    "cgi columns look transposed": lambda o: _slip(o, C_GI=np.swapaxes(o.C_GI, -1, -2)),
    "GNSS positions look Earth-fixed": lambda o: _slip(o, r_sc_i_m=np.einsum("nji,rnj->rni", o.C_GI, o.r_sc_i_m)),
}


@pytest.mark.parametrize("text", list(SLIPS))
def test_each_slip_is_named(obs, text):
    bad = SLIPS[text](obs)
    with pytest.raises(ConventionError, match=text):
        check(bad)
    assert diagnose_conventions(obs).verdict is None


def test_slip_in_a_file_that_the_reader_refuses(obs, tmp_path):
    """GNSS in ITRS puts landmarks 'behind the camera': the doctor still names the slip."""
    p = SLIPS["GNSS positions look Earth-fixed"](obs).write(tmp_path / "gnss.ecsv")
    with pytest.raises(ConventionError, match="GNSS positions look Earth-fixed"):
        read_checked(p)
    assert read_checked(obs.write(tmp_path / "ok.ecsv")).n_images == obs.n_images


def test_cli_exit_codes(obs, tmp_path):
    from boresight.cli.main import main

    good = obs.write(tmp_path / "good.ecsv")
    bad = SLIPS["y axis looks mirrored"](obs).write(tmp_path / "bad.ecsv")
    assert main(["check", str(good)]) == 0
    assert main(["check", str(bad)]) == 4
    assert main(["estimate", str(bad)]) == 4
    assert main(["estimate", str(bad), "--no-check"]) in (0, 3)


def test_every_command_that_runs_the_doctor_exits_4_with_the_same_message(obs, tmp_path, capsys):
    """check, estimate and diagnose stop on a slip with the same status (boresight.cli.exit_codes.EXIT_CONVENTION)
    and the same one-line message, `boresight CMD: ConventionError: FILE: <the doctor's finding> (...)`."""
    from boresight.cli.exit_codes import EXIT_CONVENTION
    from boresight.cli.main import main

    bad = SLIPS["y axis looks mirrored"](obs).write(tmp_path / "bad.ecsv")
    finding = diagnose_conventions(SLIPS["y axis looks mirrored"](obs)).message
    capsys.readouterr()
    for argv in (["check", str(bad)], ["estimate", str(bad)], ["diagnose", str(bad), "--out", str(tmp_path / "d"), "--no-plots"]):
        assert main(argv) == EXIT_CONVENTION == 4, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"boresight {argv[0]}: ConventionError: {bad}: {finding} ("), (argv, err)
    assert not (tmp_path / "d").exists()


def test_slip_message_reads_declared_first(obs):
    """The finding reads forward: the declared conventions' residual (large) 'as declared', then the
    slip's (small) 'with it undone' — it used to read 'residuals <small> instead of <large>'."""
    import re

    dg = diagnose_conventions(SLIPS["y axis looks mirrored"](obs))
    m = re.search(r"residuals (.+?) as declared, (.+?) with it undone", dg.message)
    assert m, dg.message
    unit = {"nm": 1e-9, "µm": 1e-6, "mm": 1e-3, "m": 1.0}
    val = [float(x.split()[0]) * unit[x.split()[1]] for x in m.groups()]
    assert np.isclose(val[0], dg.rms_m["declared"], rtol=0.01) and np.isclose(val[1], dg.rms_m[dg.verdict], rtol=0.01)
    assert val[0] > 100 * val[1]


def test_every_run_is_checked(wgs84_kalman20):
    """A damaged image (x and y swapped) in run 2 of a 3-run set is found and named with its run —
    the doctor used to look at run 0 only; the clean set says all runs were checked."""
    import dataclasses

    from oracles import dense_grid

    from boresight import simulate

    clean = simulate(wgs84_kalman20, np.random.default_rng(5), runs=3)
    dg = diagnose_conventions(clean)
    assert dg.verdict is None and dg.disagreeing is None and "all 3 runs checked" in dg.message
    grid = dense_grid(clean)  # the images × landmarks grid (tests/oracles.py)
    xy = grid.xy_m.copy()
    xy[2, 4] = xy[2, 4][..., ::-1]
    bad = dataclasses.replace(grid, xy_m=xy).to_rows()
    dg = diagnose_conventions(bad)
    assert dg.verdict is None and list(dg.disagreeing) == [4] and "of run 2" in dg.message, dg.message


def test_large_rotation_without_a_known_slip(obs):
    from orbits.rotations import axis_dcm

    bad = _slip(obs, C_SK_nominal=axis_dcm(0, np.radians(5.0)) @ obs.C_SK_nominal)
    with pytest.raises(LargeRotationError, match="5 ?°|5°"):
        check(bad)


def test_no_false_alarm_over_200_seeds(wgs84_kalman20):
    """200 noisy runs (σK 3 µm, σβ 4″, σR 15 m, σP 0.1 m): no alarm. The margin is recorded: the best
    alternative's RMS over the declared one is ≥ 0.99 (the alarm needs ≤ 0.01), and the declared
    rotation stays < 0.05° (the alarm needs > 1°; θ here is drawn with σ 10″)."""
    many = boresight.simulate(wgs84_kalman20, np.random.default_rng(np.random.SeedSequence(2026)), runs=200)
    ratios, angles = [], []
    for k in range(many.runs):
        dg = diagnose_conventions(many.run(k))
        assert dg.verdict is None, (k, dg.message)
        ratios.append(min(v for h, v in dg.rms_m.items() if h != "declared") / dg.rms_m["declared"])
        angles.append(dg.rotation_deg["declared"])
    assert min(ratios) > 0.99 and max(angles) < 0.05


@pytest.mark.parametrize("name", ["kiev2012-sensitivity", "kiev2012-algorithm1", "campaign-6pass"])
def test_every_slip_named_on_other_shipped_scenarios(name):
    """One image (sensitivity: a conjugated quaternion is a fixed rotation there, caught by the
    rotation rule), a wide field with the identity mount (algorithm1: a transposed mount is not
    testable and is not claimed), six passes (campaign)."""
    import orbits

    obs = boresight.simulate(orbits.load_scenario(name), np.random.default_rng(np.random.SeedSequence(7)), runs=3)
    for k in range(3):
        assert diagnose_conventions(obs.run(k)).verdict is None
    o = obs.run(0)
    for text, slip in SLIPS.items():
        if text.startswith("C_SK_nominal") and np.allclose(o.C_SK_nominal, o.C_SK_nominal.T):
            assert diagnose_conventions(slip(o)).verdict is None  # the identity is its own transpose
            continue
        with pytest.raises(ConventionError, match=text):
            check(slip(o))
