"""``boresight reproduce kiev2012``: the report keeps the Algorithm 1 section and adds ours."""

from __future__ import annotations

import pytest

from boresight.reproductions.kiev2012 import report as rp


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("rep")
    return rp.generate("docs/reproduction.md", runs=600, seed=2, kalman_runs=20, workers=1, out_dir=None), out


def test_algorithm1_section_is_reproduced_verbatim(report):
    rep, _ = report
    assert rep.algorithm1_reproduced
    alg1_old = dict(rp.split_sections(open("docs/reproduction.md").read()))[rp.ALG1_HEADING]
    alg1_new = dict(rp.split_sections(rep.text))[rp.ALG1_HEADING]
    assert alg1_new.rstrip() == alg1_old.rstrip()


def test_report_has_eq28_and_kalman_sections_with_the_seminar_numbers(report):
    rep, _ = report
    heads = [h for h, _ in rp.split_sections(rep.text)]
    assert heads.count(rp.EQ28_HEADING) == 1 and heads.count(rp.KALMAN_HEADING) == 1
    eq28 = dict(rp.split_sections(rep.text))[rp.EQ28_HEADING]
    assert "| seminar | (not stated) | 6.09 | 6.09 | 8.36 | 11.98 |" in eq28
    for case in ("| A |", "| B |", "| C |"):
        assert case in eq28
    assert "| 20 | 4.6/4.3/6.4 |" in dict(rp.split_sections(rep.text))[rp.KALMAN_HEADING]


def test_regenerating_from_the_generated_report_is_stable(report, tmp_path):
    """The generated file is a valid template: our sections are replaced, not duplicated."""
    rep, _ = report
    p = tmp_path / "reproduction.md"
    p.write_text(rep.text)
    again = rp.generate(p, runs=600, seed=2, kalman_runs=20, workers=1)
    assert again.algorithm1_reproduced
    assert [h for h, _ in rp.split_sections(again.text)] == [h for h, _ in rp.split_sections(rep.text)]


def test_cli_writes_generated_file_when_alg1_tables_differ(tmp_path, capsys):
    """A template whose Algorithm 1 table was edited is not overwritten."""
    from boresight.cli.main import main

    text = open("docs/reproduction.md").read().replace("| 5 | 20.5 | 16.2 |", "| 5 | 20.5 | 99.9 |", 1)
    (tmp_path / "reproduction.md").write_text(text)
    rc = main(["reproduce", "kiev2012", "--out", str(tmp_path), "--runs", "300", "--kalman-runs", "10", "--workers", "1"])
    assert rc == 0
    assert (tmp_path / "reproduction.generated.md").exists()
    assert (tmp_path / "reproduction.md").read_text() == text
    # what it is doing, on stderr, before the silent part (boresight.cli.heartbeat beats after 2 s)
    assert (
        "reproduce kiev2012: Algorithm 1 tables, eq 28 study (300 runs per case, 7 cases), Kalman table (10 runs)"
        in capsys.readouterr().err
    )


# ---------------------------------------------------------------------------- numbers in the prose


def test_eq28_findings_are_what_the_prose_states(report):
    """The eq 28 bullets are computed (``eq28_findings``); check the quantities are the right ones."""
    import numpy as np

    from boresight.reproductions.kiev2012.published import SEMINAR_EQ28_SIGMA_ARCSEC
    from orbits.rotations import ARCSEC

    cases = rp._eq28_cases(600, 2, 1)
    f = rp.eq28_findings(cases)
    sd = cases["A"].sigma_arcsec
    assert f["sigma_dev_pct"] == pytest.approx(100 * np.max(np.abs(sd / np.asarray(SEMINAR_EQ28_SIGMA_ARCSEC[:3]) - 1)))
    assert f["R_expected"] == pytest.approx(1 / 680e3 / ARCSEC) and f["R_one_image"] == pytest.approx(f["R_expected"], rel=0.01)
    assert f["lever_km"] == pytest.approx(26.0, abs=0.01) and f["landmark_distance_km"] == pytest.approx(13.0)
    # β rows average as 1/√10 with 10 per-image errors; a per-pass bias is not averaged
    assert f["beta_norm_B"] == pytest.approx(1 / np.sqrt(10), rel=0.05)
    assert min(f["sigma_C"][:2]) > 1.5 * f["sigma_B"][1]
    assert len(f["sens_dev_pct"]) == 17  # 18 entries less the seminar's R z = 0
    text = dict(rp.split_sections(report[0].text))[rp.EQ28_HEADING]
    assert f"(to {f['beta_dev_max']:.4f})" in text


def test_sea_sky_prose_claims_hold():
    """The fixed statements of the sea-sky bullets (the others are computed in ``sea_sky_section``)."""
    import numpy as np

    from boresight.pointing import coarse_estimate_deg, grid_search_deg, load_sea_sky
    from boresight.reproductions.usv_sea_sky.published import PAPER_COARSE_DEG, PAPER_FINE_DEG, PAPER_SPECIAL_POINTS_DEG

    # "half a unit of their last digit moves α by up to ±5.5e-4° and β by ±2.4e-4°"
    q1, h2 = PAPER_SPECIAL_POINTS_DEG
    base = np.array(coarse_estimate_deg(q1, h2), float)
    moves = np.array(
        [np.abs(np.array(coarse_estimate_deg(q1 + a, h2 + b), float) - base) for a in (-0.005, 0.005) for b in (-0.0005, 0.0005)]
    ).max(axis=0)
    assert moves[0] == pytest.approx(5.5e-4, abs=0.5e-4) and moves[1] == pytest.approx(2.4e-4, abs=0.5e-4)
    assert np.allclose(base, PAPER_COARSE_DEG, atol=6e-4)  # "the paper's result to the rounding of those points"
    # "one 0.01° step from the paper in α"; "with h′ rounded to 0.01° the grid returns the paper's values exactly"
    scan = load_sea_sky()
    args = (scan.pitch_deg, scan.roll_deg, *PAPER_COARSE_DEG)
    g = grid_search_deg(scan.azimuth_deg, scan.h_meas_deg, *args)
    assert abs(g.alpha_deg - PAPER_FINE_DEG[0]) == pytest.approx(0.01, abs=1e-9) and g.beta_deg == pytest.approx(
        PAPER_FINE_DEG[1], abs=1e-9
    )
    gr = grid_search_deg(scan.azimuth_deg, np.round(scan.h_meas_deg, 2), *args)
    assert (gr.alpha_deg, gr.beta_deg) == pytest.approx(PAPER_FINE_DEG, abs=1e-9)


def test_the_scenario_numbers_in_the_section_intros_are_the_scenarios():
    """The eq 28 and Kalman intros describe the scenario files in words; they must not drift."""
    import numpy as np

    from boresight.reproductions.kiev2012 import kalman_scenario, sensitivity_case

    sc = sensitivity_case(1, "per_image")
    assert (sc.orbit.altitude_km, sc.orbit.inclination_deg, sc.camera.focal_length_m, sc.camera.fov_deg) == (
        680.0,
        98.0,
        2.2,
        3.4,
    )
    assert (tuple(sc.sigma_star_tracker_arcsec), sc.sigma_catalogue_m, sc.sigma_gnss_m, sc.sigma_pixel_m) == (
        (4.0, 4.0, 4.0),
        0.1,
        15.0,
        3e-6,
    )
    assert sc.theta_sigma0_arcsec == 600.0 and len(sc.landmarks.enu_km) == 4
    k = kalman_scenario()
    assert len(k.passes[0].t_s) == 20 and np.allclose(np.diff(k.passes[0].t_s), 5.0) and k.theta_sigma0_arcsec == 10.0
    text = rp.eq28_section.__code__.co_consts  # the intro strings
    intro = " ".join(c for c in text if isinstance(c, str))
    for phrase in (
        "680 km, i = 98°, F = 2.2 m, 3.4° field, σβ = 4″, σP = 0.1 m",
        "σR = 15 m, σK = 3 µm, θ ~ N(0, 10′²)",
        "4 landmarks in a cross 13 km",
    ):
        assert phrase in intro
