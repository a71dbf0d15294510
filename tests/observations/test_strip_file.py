"""The pushbroom observation file (``boresight/observations/strip_file.py``): a simulated strip written and read back
is the same set of lines (its estimate equal to round-off), and a file that names a chip the sensor lacks, a pixel off
its chip or a line dated outside the samples is refused naming the file, the column and the row."""

import numpy as np
import pytest

from boresight.core.line_scan import estimate_line_scan
from boresight.observations.model import ObservationError
from boresight.observations.strip import simulate_strip_scenario, strip_noise_model
from boresight.observations.strip_file import is_strip_file, read_strip_file, strip_file_model, write_strip_file
from orbits.strip import load_strip_scenario


@pytest.fixture(scope="module")
def strip():
    sc = load_strip_scenario("pushbroom-strip")
    (obs,) = simulate_strip_scenario(sc, np.random.default_rng(7))
    return sc, obs


@pytest.fixture(scope="module")
def written(strip, tmp_path_factory):
    sc, obs = strip
    path = tmp_path_factory.mktemp("strip") / "s.ecsv"
    write_strip_file(obs, path, dict(sigma_pixel_px=0.3, sigma_star_tracker_arcsec=0.3), {"focal_scale": True}, dict(seed=7))
    return path


def test_a_written_strip_reads_back_to_the_same_estimate(strip, written):
    """Every float is written with all its digits and the Earth's orientation samples are stored, so the lines read
    back are the ones written: the estimate (θ and a focal scale, the file's ``estimate``) equal to 1e-12 relative
    (measured: equal to the last bit on this machine)."""
    sc, obs = strip
    assert is_strip_file(written) and not is_strip_file(written.with_suffix(".toml"))
    sf = read_strip_file(written)
    assert sf.estimate == {"focal_scale": True} and sf.meta["seed"] == 7
    model = strip_file_model(sf)
    assert model.sigma_pixel_m == strip_noise_model(sc).sigma_pixel_m
    from boresight.observations.strip import line_unknowns

    unknowns = line_unknowns(sf.estimate, 3, "test")
    a = estimate_line_scan(obs, unknowns, strip_noise_model(sc))
    b = estimate_line_scan(sf.obs, unknowns, model)
    np.testing.assert_allclose(b.x, a.x, rtol=1e-12)
    np.testing.assert_allclose(b.sigma, a.sigma, rtol=1e-12)
    assert sf.obs.n_observations == obs.n_observations and sf.obs.n_samples == obs.n_samples


def _edit(src, dst, column, row, value):
    """Copy the ECSV ``src`` to ``dst`` with ``column`` of data row ``row`` (0-based) set to ``value``."""
    from astropy.table import Table

    t = Table.read(src, format="ascii.ecsv")
    t[column][row] = value
    t.write(dst, format="ascii.ecsv", overwrite=True)
    return dst


@pytest.mark.parametrize(
    "column, value, match",
    [
        ("chip", 7, r"column 'chip' row 5: 7 is not a chip of the sensor \(0 … 2\)"),
        ("pixel", 1e6, r"column 'pixel' row 5: 1000000.0 is not a column of chip"),
        ("line", 90000.0, r"column 'line' row 5: line 90000.0 is dated .* outside the orbit, tracker and Earth samples"),
    ],
)
def test_a_bad_row_is_refused_naming_file_column_row_and_value(written, tmp_path, column, value, match):
    bad = _edit(written, tmp_path / "bad.ecsv", column, 4, value)
    with pytest.raises(ObservationError, match=match) as exc:
        read_strip_file(bad)
    assert str(bad) in str(exc.value)


def test_a_missing_key_or_column_is_refused(written, tmp_path):
    from astropy.table import Table

    t = Table.read(written, format="ascii.ecsv")
    del t.meta["pushbroom"]["tracker"]
    t.write(tmp_path / "nokey.ecsv", format="ascii.ecsv")
    with pytest.raises(ObservationError, match="metadata key 'tracker' is missing"):
        read_strip_file(tmp_path / "nokey.ecsv")
    t = Table.read(written, format="ascii.ecsv")
    t.remove_column("chip")
    t.write(tmp_path / "nocol.ecsv", format="ascii.ecsv")
    with pytest.raises(ObservationError, match=r"missing column\(s\) 'chip'"):
        read_strip_file(tmp_path / "nocol.ecsv")


@pytest.mark.parametrize(
    "argv",
    [
        ["check", "{file}"],
        ["estimate", "{file}"],
        ["diagnose", "{file}", "--out", "{out}"],
        ["montecarlo", "{file}", "--runs", "3"],
        ["sensitivity", "{file}", "--runs", "0", "--out", "{out}"],
    ],
)
def test_every_command_refuses_a_pushbroom_file_over_the_memory_budget(written, tmp_path, capsys, monkeypatch, argv):
    """As every file command (``tests/project/test_budget_every_command.py``): a budget of half the reader's estimate
    (``observations.ecsv.read_bytes``) refuses the file before it is read, naming it and the estimate."""
    from boresight.cli.main import main
    from boresight.observations.ecsv import read_bytes

    need = read_bytes(written)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", repr(0.5 * need / 2**30))
    rc = main([a.format(file=written, out=tmp_path / "o") for a in argv])
    err = capsys.readouterr().err
    assert rc != 0 and f"reading {written}" in err and f"would need about {need / 2**30:.3g} GiB" in err, err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").rglob("*.*"))


def _as_text(t, column, row, value):
    t[column] = t[column].astype(str)
    t[column][row] = value
    return t


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda t: _as_text(t, "chip", 3, "x"), r"column 'chip' row 4: 'x' is not a number"),
        (lambda t: _as_text(t, "line", 1, "abc"), r"column 'line' row 2: 'abc' is not a number"),
        (lambda t: _as_text(t, "x_g_m", 0, "nan"), r"column 'x_g_m' row 1: non-finite value nan"),
        (lambda t: t[:0], r"no detections \(the table has no rows\)"),
    ],
)
def test_hostile_cells_are_refused_naming_column_row_and_value(written, tmp_path, edit, match):
    from astropy.table import Table

    t = edit(Table.read(written, format="ascii.ecsv"))
    t.write(tmp_path / "h.ecsv", format="ascii.ecsv")
    with pytest.raises(ObservationError, match=match):
        read_strip_file(tmp_path / "h.ecsv")
