"""Must-show of issue 9 on the effects catalogue: each catalogue effect hidden in a simulated
campaign in which it is separable is named with no hint; an effect in a single nadir pass is
``not_separable``; look-alikes are ``ambiguous``, never a wrong name; two effects are named in
turn; an effect outside the catalogue is ``unexplained_structure``; with no effect nothing is named.

Sizes are stated per effect: about 4× the minimum detectable size the diagnosis itself reports on
the test campaign (level α/K = 0.01/7, power 80 %), so the naming test has power > 99.9 %.
The default run checks one seed per case; ``-m slow`` runs ≥ 40 seeds per effect and ≥ 100 with
no effect, and asserts the rates.
"""

import dataclasses

import numpy as np
import pytest
from builders import discrepancy_campaign as campaign
from builders import small_campaign
from paths import ROOT

import orbits
from boresight import simulate
from boresight.core.disturbances import DisturbanceModel
from boresight.studies.discrepancy import diagnose
from orbits.rotations import ARCSEC

pytest.importorskip("boresight.core.effect_model")

#: hidden sizes (~4× the minimum detectable size on the campaign used)
SIZES = {
    "time_tag": {"dt_s": 0.02},
    "focal_scale": 1e-4,
    "radial_distortion": 0.15,
    "thermal": {"sin_x_arcsec": 30.0, "cos_y_arcsec": -30.0},
    "gnss_bias": {"along_track_m": 150.0},
    "aberration": 1.0,
}


def truth_vector(name, spec):
    eff = orbits.effects.EFFECTS[name]
    v = np.zeros(eff.n_params)
    if isinstance(spec, dict):
        for k, x in spec.items():
            v[eff.param_names.index(k)] = x
    else:
        v[:] = spec
    return v


def run(name, seed):
    sc = campaign({name: SIZES[name]}, low_star_tracker_noise=(name == "aberration"))
    obs = simulate(sc, np.random.default_rng(seed))
    return obs, diagnose(obs, DisturbanceModel.from_scenario(sc))


def check_named(name, obs, d):
    """The must-show checks; returns a dict of booleans (the slow test counts them)."""
    out = {"named": d.named == [name], "nothing_else": not d.ambiguous and not d.unexplained_structure}
    if not d.steps or d.steps[0]["effect"] != name:
        return out
    s = d.steps[0]
    truth = truth_vector(name, SIZES[name])
    est, sig = np.atleast_1d(s["estimate"]), np.atleast_1d(s["sigma"])
    out["within_3_sigma"] = bool(np.all(np.abs(est - truth) <= 3 * sig))
    out["chi2_consistent"] = not next(t for t in d.details["final_tests"] if t.name == "chi2").rejected
    th = obs.truth["theta_rad"][0] / ARCSEC
    cov = d.details["final_state"].cov[:3, :3] / ARCSEC**2
    e1 = np.array(d.theta_arcsec) - th
    e0 = np.array(s["theta_before_arcsec"]) - th
    m1, m0 = e1 @ np.linalg.solve(cov, e1), e0 @ np.linalg.solve(cov, e0)
    out["theta_within_covariance"] = bool(m1 < 16.27)  # χ²(3) 99.9 %
    out["theta_closer"] = bool(m1 <= m0)
    return out


@pytest.mark.parametrize("name", sorted(SIZES))
def test_hidden_effect_is_named(name):
    obs, d = run(name, seed=0)
    c = check_named(name, obs, d)
    assert c["named"] and c["nothing_else"], d.summary()
    assert c["within_3_sigma"] and c["chi2_consistent"] and c["theta_within_covariance"], (c, d.summary())
    if name in ("time_tag", "thermal", "aberration"):  # effects that bias θ (|ρ| with θ > 0.2 on this campaign)
        assert c["theta_closer"], d.summary()


def test_time_tag_in_a_single_nadir_pass_is_not_separable():
    sc = small_campaign(passes=("nadir",))
    sc = dataclasses.replace(sc, effects=orbits.effects.effect_sizes({"time_tag": {"dt_s": 0.05}}))
    obs = simulate(sc, np.random.default_rng(1))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    ns = {e["effect"]: e for e in d.not_separable}
    assert "time_tag" in ns and d.named == [], d.summary()
    assert "site-tracking" in ns["time_tag"]["would_separate"]
    # under nadir pointing ω is the orbit rate n about the orbit normal: dt = 0.01 s (the typical
    # size) turns the camera by n dt = 2.2″ (680 km) — the θ shift the report quotes
    n = np.sqrt(3.986004418e14 / (6371e3 + 680e3) ** 3)
    assert np.isclose(np.linalg.norm(ns["time_tag"]["theta_shift_arcsec"]), n * 0.01 / ARCSEC, rtol=0.03)


def test_landmark_height_bias_and_radial_gnss_bias_are_ambiguous():
    """A catalogue height bias h and a radial GNSS bias −h move the line of sight alike (their
    canonical correlation with θ free is 1.000 on every campaign we tried): never one name alone."""
    sc = campaign({"landmark_height_bias": 60.0})
    obs = simulate(sc, np.random.default_rng(2))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.named == [] and len(d.ambiguous) == 1, d.summary()
    assert set(d.ambiguous[0]["effects"]) == {"landmark_height_bias", "gnss_bias"}
    assert not d.unexplained_structure  # the floated group explains the structure


def test_two_effects_are_named_in_turn():
    sc = campaign({"time_tag": {"dt_s": 0.02}, "radial_distortion": 0.15})
    obs = simulate(sc, np.random.default_rng(3))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert sorted(d.named) == ["radial_distortion", "time_tag"], d.summary()
    assert d.steps[1]["chi2_dof_after"] < d.steps[0]["chi2_dof_after"] < d.steps[0]["chi2_dof_before"]
    assert not d.unexplained_structure


def test_tangential_distortion_is_unexplained_and_nothing_is_named():
    sc = campaign(unmodelled=(("tangential_distortion", {"p1": 3e-3, "p2": -2e-3}),))
    obs = simulate(sc, np.random.default_rng(4))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.unexplained_structure and d.named == [], d.summary()
    assert d.details["collocation"] is not None and d.details["collocation"].explained > 0.5


# ---------------------------------------------------------------------------- slow: rates


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SIZES))
def test_naming_rate(name):
    """≥ 40 seeds: the effect is named (alone) in ≥ 95 % and every must-show check holds in ≥ 95 %."""
    n = 40
    counts = {}
    for seed in range(100, 100 + n):
        obs, d = run(name, seed)
        for k, v in check_named(name, obs, d).items():
            counts[k] = counts.get(k, 0) + int(v)
    print(name, counts)
    assert counts["named"] >= 0.95 * n
    assert counts.get("within_3_sigma", 0) >= 0.95 * n and counts.get("theta_within_covariance", 0) >= 0.95 * n


@pytest.mark.slow
def test_no_effect_nothing_named():
    """100 seeds without a hidden effect: nothing named in ≥ 97 (issue 30's Must-show, after the
    catalogue grew to 11 effects; the design level is 1 % family-wise, so 3 or more names in 100
    has probability 8 % at that level, 1.4 % at half of it)."""
    sc = campaign()
    model = DisturbanceModel.from_scenario(sc)
    named = 0
    for seed in range(200, 300):
        d = diagnose(simulate(sc, np.random.default_rng(seed)), model)
        named += bool(d.named)
    print("named with no effect:", named, "of 100")
    assert named <= 3


@pytest.mark.slow
def test_gnss_bias_is_never_called_focal_scale():
    """The issue's look-alike: a constant 20 m radial GNSS bias. Over 40 seeds: ``gnss_bias`` named
    or ``ambiguous`` (or nothing: 20 m is about the minimum detectable size here) — never
    ``focal_scale`` alone."""
    sc = campaign({"gnss_bias": {"radial_m": 20.0}})
    model = DisturbanceModel.from_scenario(sc)
    outcomes = {"gnss_bias": 0, "ambiguous": 0, "nothing": 0, "focal_scale": 0, "other": 0}
    for seed in range(300, 340):
        d = diagnose(simulate(sc, np.random.default_rng(seed)), model)
        if d.named[:1] == ["focal_scale"]:
            outcomes["focal_scale"] += 1
        elif d.named[:1] == ["gnss_bias"]:
            outcomes["gnss_bias"] += 1
        elif d.ambiguous:
            outcomes["ambiguous"] += 1
        elif not d.named:
            outcomes["nothing"] += 1
        else:
            outcomes["other"] += 1
    print("20 m radial GNSS bias:", outcomes)
    assert outcomes["focal_scale"] == 0


def test_docs_example(tmp_path, capsys):
    """docs/discrepancy.md's worked example: the one command and the numbers the page quotes."""

    from boresight.cli.main import main

    root = ROOT
    assert (
        main(["diagnose", str(root / "scenarios/diagnose-example.toml"), "--seed", "1", "--out", str(tmp_path), "--no-plots"])
        == 0
    )
    printed = capsys.readouterr().out
    doc = (root / "docs/discrepancy.md").read_text()
    for line in printed.splitlines():
        if line.startswith(("base fit", "step 1", "step 2", "θ ")):
            assert line in doc, line
    import json

    js = json.loads((tmp_path / "diagnosis.json").read_text())
    assert js["named"] == ["radial_distortion", "time_tag"]


def test_named_model_equals_estimate_float():
    """The diagnosis's joint fit of θ and a named effect is ``estimate(..., effects=[name])``
    (fastfit's block-sparse GLS; skipped until ``effects=`` is on main)."""
    from boresight import estimate

    obs, d = run("time_tag", 0)
    model = DisturbanceModel.from_scenario(campaign({"time_tag": SIZES["time_tag"]}))
    try:
        est = estimate(obs, weighting="gls", model=model, effects=["time_tag"])
    except (TypeError, ValueError) as exc:
        if "float" in str(exc) or "option" in str(exc):
            pytest.skip(f"estimate(effects=...) not available: {exc}")
        raise
    assert np.allclose(est.theta.value, d.theta_arcsec, atol=1e-3)  # σθ ≈ 1″
    value, sigma = est.effects["time_tag"]
    assert np.isclose(np.ravel(value.value)[0], d.steps[0]["estimate"], rtol=1e-3)
    assert np.isclose(np.ravel(sigma.value)[0], d.steps[0]["sigma"], rtol=1e-2)


def test_velocity_dependent_candidates_without_velocity():
    """No GNSS velocity and one image per pass (nothing to derive it from): thermal, aberration and
    gnss_bias are reported "needs velocity", not tested, and nothing fails."""
    sc = campaign()
    obs = simulate(sc, np.random.default_rng(5))
    one = np.r_[[np.flatnonzero(obs.pass_index == p)[len(np.flatnonzero(obs.pass_index == p)) // 2] for p in range(4)]]
    sub = dataclasses.replace(obs.images(one), v_sc_i_m_s=None) if hasattr(obs, "v_sc_i_m_s") else obs.images(one)
    d = diagnose(sub, DisturbanceModel.from_scenario(sc))
    status = {e["effect"]: e["status"] for e in d.identifiability}
    for name in ("thermal", "aberration", "gnss_bias"):
        assert status[name] == "needs velocity", status
    assert d.named == []
