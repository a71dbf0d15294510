"""``boresight pointing sea-sky``: exit code, printed numbers, the PNG."""

from __future__ import annotations

import re

import numpy as np

from boresight.cli.main import main
from boresight.pointing import load_sea_sky, sea_sky_data_path
from boresight.pointing.sea_sky_analysis import analyse_sea_sky


def test_cli_sea_sky_on_paper_data(tmp_path, capsys):
    rc = main(["pointing", "sea-sky", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert "grid (eq 24" in out and "alpha = 0.9433, beta = 0.3732 deg" in out
    assert "paper: alpha = 0.9533, beta = 0.3732 deg" in out
    m = re.search(r"least squares \(huber\): alpha = ([\d.]+) ± ([\d.]+), beta = ([\d.]+) ± ([\d.]+)", out)
    assert m, out
    a, sa, b, sb = map(float, m.groups())
    assert abs(a - 0.9574) < 2e-4 and abs(b - 0.3885) < 2e-4 and 0 < sa < 0.05 and 0 < sb < 0.05
    png = tmp_path / "sea_sky_fit.png"
    assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_cli_bad_file_exit_code_and_message(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(sea_sky_data_path().read_text().splitlines()[:50]).replace("0.925416667", "nan"))
    rc = main(["pointing", "sea-sky", str(bad), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 1
    assert "column 'h_meas_deg' line 2: non-finite value nan" in err
    assert main(["pointing", "sea-sky", str(tmp_path / "missing.csv")]) == 1


def test_real_data_residual_findings():
    d = analyse_sea_sky(load_sea_sky())
    # surge-blocked frames: all outliers put the sea-sky line *above* the fit, in two sectors
    assert list(d.outlier_frames) == [9, 15, 16, 87, 93, 94, 95, 96]
    assert np.all(d.outlier_residuals_deg > 0.5)
    # hull attitude at these small angles moves h' by < 0.005 deg, far below the 0.12 deg scatter
    assert d.attitude_effect_max_deg < 0.005 < 0.1 < d.inlier_rms_deg
    assert abs(d.fit.alpha_deg - d.fit_no_attitude.alpha_deg) < 0.005
    assert d.attitude_test.p_value > 0.05  # k = 0 is not rejected
    # no significant structure left against azimuth once the outliers are out
    assert d.by_azimuth.p_value > 0.05 and np.all(d.harmonics.p_value > 0.05)
    # but residuals are serially correlated along the scan
    assert d.fit.acf[1] > 0.2 and d.fit.n_eff < 0.8 * d.fit.n
