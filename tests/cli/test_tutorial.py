"""docs/tutorial-flight-data.md: its commands run on examples/flight-pass and print what the doc shows."""

import re

import numpy as np
from scipy.stats import chi2
from tutorial_doc import DOC, EXACT
from tutorial_doc import console_blocks as _blocks

from boresight.cli.main import main

# no optional package: the tutorial's files are CCSDS KVN, CSV and TOML (read without the flight extra)

# step 4's table rows (axis, reported σ, Monte Carlo σ, interval): compared within 1e-3″ (a sample σ)
AXIS = re.compile(r"^([xyz])\s+([\d.]+)\s+([\d.]+)\s+\[([\d.]+), ([\d.]+)\]\s+(yes|NO)$")


def _axis_rows(lines):
    return {m[1]: ([float(v) for v in m.groups()[1:5]], m[6]) for m in map(AXIS.match, lines) if m}


def test_tutorial_commands_print_what_the_doc_shows(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # an empty folder: --example finds the shipped data set
    blocks = _blocks()
    assert [b[0][0] for b in blocks] == ["ingest", "check", "estimate", "montecarlo"]
    printed = {}
    for argv, expected in blocks:
        assert main(argv) == 0, argv
        got = capsys.readouterr().out.splitlines()
        printed[argv[0]] = got
        want = [ln for ln in expected if EXACT.match(ln)]
        assert want, argv
        assert [ln for ln in got if EXACT.match(ln)] == want, argv
        rows, doc_rows = _axis_rows(got), _axis_rows(expected)
        assert set(rows) == set(doc_rows)
        for ax, (vals, inside) in doc_rows.items():
            assert rows[ax][1] == inside and np.allclose(rows[ax][0], vals, rtol=0, atol=1e-3), (ax, rows[ax], vals)
    assert (tmp_path / "results" / "residuals_image_plane.png").exists()
    # the prose: truth [25, -40, 60]″ within 1σ on x, y and 1.1σ on z
    th = {ln.split()[0]: (float(ln.split()[1]), float(ln.split()[3])) for ln in printed["estimate"] if ln.startswith("theta_")}
    err = [(th[k][0] - t) / th[k][1] for k, t in zip(("theta_x", "theta_y", "theta_z"), (25.0, -40.0, 60.0))]
    assert abs(err[0]) < 1 and abs(err[1]) < 1 and abs(err[2]) < 1.1
    # step 4: a Monte Carlo of the pass (200 runs); the prose's interval widths from the χ² distribution
    mc = _axis_rows(printed["montecarlo"])
    assert set(mc) == set("xyz") and all(r[1] == "yes" for r in mc.values())
    assert "interval spans 0.87–1.17 × the scatter" in DOC.read_text() and "0.95–1.05 ×" in DOC.read_text()
    for n, (lo, hi) in ((200, (0.87, 1.17)), (2000, (0.95, 1.05))):
        w = np.sqrt((n - 1) / chi2.ppf([0.99865, 0.00135], n - 1))
        np.testing.assert_allclose(w, (lo, hi), rtol=0, atol=0.005)
    # the algorithm table quotes unit_vector's θ
    assert main(["estimate", "pass.ecsv", "--algorithm", "unit_vector"]) == 0
    uv = [ln.split()[1] for ln in capsys.readouterr().out.splitlines() if ln.startswith("theta_")]
    assert f"`{' '.join(uv)}`" in DOC.read_text()
    # "kalman … agrees with batch GLS well within σ": within a tenth of σ on every axis
    assert main(["estimate", "pass.ecsv", "--algorithm", "kalman"]) == 0
    ka = [float(ln.split()[1]) for ln in capsys.readouterr().out.splitlines() if ln.startswith("theta_")]
    assert all(abs(k - th[a][0]) < 0.1 * th[a][1] for k, a in zip(ka, ("theta_x", "theta_y", "theta_z")))
