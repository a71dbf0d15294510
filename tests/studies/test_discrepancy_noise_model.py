"""Issue 30: the discrepancy workflow when the noise model is wrong, and for effects just past the
old catalogue. The default run checks one seed per case; ``-m slow`` measures the Must-show rates
(docs/discrepancy.md quotes them with Clopper–Pearson intervals, ``boresight.stats.binomial_interval``).

Campaigns: ``discrepancy_campaign`` (4 passes, 40 images, Kiev noise per image; the issue's class 1
gave χ²/dof 2.2–2.4 on it with every source 1.5×) for the noise-model cases, ``drift_campaign``
(one pass a day, ascending and descending at eight latitudes, 1.5″ star tracker) for the step (6
passes) and the datum shift (8 passes).
"""

import dataclasses

import numpy as np
import pytest
from builders import discrepancy_campaign, drift_campaign

from boresight import simulate
from boresight.core.disturbances import DisturbanceModel
from boresight.studies.discrepancy import diagnose
from orbits.rotations import ARCSEC

pytest.importorskip("boresight.core.effect_model")


def scaled(sc, f):
    """The scenario with every noise source f× (the declared model stays the unscaled one)."""
    return dataclasses.replace(
        sc,
        sigma_pixel_m=sc.sigma_pixel_m * f,
        sigma_star_tracker_arcsec=tuple(np.asarray(sc.sigma_star_tracker_arcsec, float) * f),
        sigma_gnss_m=sc.sigma_gnss_m * f,
        sigma_catalogue_m=sc.sigma_catalogue_m * f,
    )


class StudentT:
    """A ``numpy.random.Generator`` whose normal draws are Student-t with ``nu`` degrees of freedom
    scaled to the same standard deviation (``t √((ν−2)/ν)``): every noise source of the simulator
    (pixel, star tracker, GNSS, catalogue; ``orbits.sensors``, ``orbits.landmarks``) heavy-tailed
    at its declared size. Everything else is the wrapped generator's."""

    def __init__(self, rng, nu):
        self._rng, self._nu = rng, nu

    def normal(self, loc=0.0, scale=1.0, size=None):
        t = self._rng.standard_t(self._nu, size=size) * np.sqrt((self._nu - 2.0) / self._nu)
        return loc + scale * t

    def __getattr__(self, name):
        return getattr(self._rng, name)


#: the step's boundary in the images' time axis: between the second and third pass (one a day)
def step_campaign(size_arcsec=8.0, n_passes=6):
    sc = drift_campaign(n_passes=n_passes)
    obs = simulate(sc, np.random.default_rng(0))
    tb = 0.5 * (obs.t_s[obs.pass_index == 1].max() + obs.t_s[obs.pass_index == 2].min())
    return drift_campaign({"alignment_step": {"step_y_arcsec": size_arcsec, "at_s": float(tb)}}, n_passes=n_passes)


def z_scores(obs, d):
    th = obs.truth["theta_rad"][0] / ARCSEC
    return (np.array(d.theta_arcsec) - th) / np.array(d.theta_sigma_arcsec)


# ---------------------------------------------------------------------------- default run: one seed each


def test_noise_1_5x_sizes_every_source_and_inflates_sigma():
    """Seed 3001, every source 1.5× the declared: nothing named, the variance components say so
    (pixel 4.5 µm for 3 declared: within 3 of its σ), θ's σ inflated (≥ 1.25× the base fit's under
    the declared model, where the truth is 1.5×; without the step it is 1.0×) and θ within 3σ."""
    sc = discrepancy_campaign()
    obs = simulate(scaled(sc, 1.5), np.random.default_rng(3001))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    vc = d.variance_components
    assert d.named == [] and vc is not None and vc["failed"] is None, d.summary()
    pix = next(c for c in vc["components"] if c["source"] == "pixel")
    assert abs(pix["estimate"] - 4.5) < 3 * pix["sigma"] and pix["declared"] == pytest.approx(3.0)
    declared = d.details["before_variance_components"].details["base_state"].theta_sigma_arcsec()
    assert np.all(np.array(d.theta_sigma_arcsec) >= 1.25 * declared)
    assert np.all(np.abs(z_scores(obs, d)) < 3)
    text = d.summary()
    assert "noise model     rejected by χ²" in text and "pixel noise: declared 3 µm, the data say" in text


def test_estimate_offers_variance_components(tmp_path, capsys):
    """``boresight estimate --variance-components``: the scales beside the declared ones in the
    terminal and in estimate.json, θ's σ from the estimated model (inflated here: 1.5× noise)."""
    import json

    from boresight.cli.main import main

    sc = discrepancy_campaign()
    obs = simulate(scaled(sc, 1.5), np.random.default_rng(3001))
    obs = dataclasses.replace(obs, noise=DisturbanceModel.from_scenario(sc).to_noise())
    f = tmp_path / "obs.ecsv"
    obs.write(f)
    assert main(["estimate", str(f), "--json", str(tmp_path / "plain.json")]) == 0
    assert main(["estimate", str(f), "--variance-components", "--json", str(tmp_path / "vc.json")]) == 0
    out = capsys.readouterr().out
    assert "pixel noise: declared 3 µm, the data say" in out
    plain, vc = (json.loads((tmp_path / n).read_text()) for n in ("plain.json", "vc.json"))
    assert "variance_components" in vc and "variance_components" not in plain
    assert {c["source"] for c in vc["variance_components"]["components"]} >= {"pixel", "gnss", "catalogue"}
    s0 = np.sqrt(
        np.diag(plain["covariance_arcsec2"][0] if np.ndim(plain["covariance_arcsec2"]) == 3 else plain["covariance_arcsec2"])
    )
    s1 = np.sqrt(np.diag(vc["covariance_arcsec2"][0] if np.ndim(vc["covariance_arcsec2"]) == 3 else vc["covariance_arcsec2"]))
    assert np.all(s1 > 1.2 * s0)


def test_a_failed_estimate_is_said_and_inflates_sigma(monkeypatch):
    """No silent fallback: when the variance components cannot be estimated the terminal and the
    JSON say so and θ's σ is the first diagnosis' times √(χ²/dof)."""
    from boresight.errors import BoresightError
    from boresight.studies.discrepancy.campaign import CampaignProblem

    def boom(self, *a, **k):
        raise BoresightError("a singular fit (test)")

    monkeypatch.setattr(CampaignProblem, "variance_components", boom)
    sc = discrepancy_campaign()
    obs = simulate(scaled(sc, 1.5), np.random.default_rng(3001))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    vc = d.variance_components
    assert vc["failed"].startswith("the estimate failed") and vc["sigma_inflation"] > 1.2
    assert np.allclose(d.theta_sigma_arcsec, np.array(vc["theta_sigma_before_arcsec"]) * vc["sigma_inflation"])
    assert "NOISE MODEL     the variance components could not be estimated" in d.summary()


def test_heavy_tails_are_a_loss_question_said_not_a_rotation():
    """Student-t noise (ν = 4) of the declared size, seed 3100: the outlier test fails, the χ² test
    does not; nothing is named, no scale is re-estimated (the variance is the declared one), the
    tails are reported heavy with least squares kept, and θ's σ is the declared model's."""
    sc = discrepancy_campaign()
    obs = simulate(sc, StudentT(np.random.default_rng(3100), 4.0))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.named == [] and d.variance_components is None
    assert d.tails["heavy"] and d.tails["loss"] == "least squares" and d.tails["excess_kurtosis"] > 2
    assert "tails           excess kurtosis" in d.summary()
    assert np.allclose(d.theta_sigma_arcsec, d.details["base_state"].theta_sigma_arcsec())


def test_alignment_step_is_named_at_its_boundary():
    """An 8″ step about y after the second of six passes (seed 4000): ``alignment_step`` named,
    after pass 2, its size within 3σ; the scan's size (5 boundaries) in the step record."""
    sc = step_campaign()
    obs = simulate(sc, np.random.default_rng(4000))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.named == ["alignment_step"], d.summary()
    s = d.steps[0]
    assert s["after_pass"] == 2 and s["boundaries_scanned"] == 5
    assert abs(s["estimate"][1] - 8.0) < 3 * s["sigma"][1]


def test_a_floated_not_decisive_candidate_does_not_hide_failing_probes():
    """The 8″ step of six passes diagnosed without ``alignment_step`` among the candidates (the old
    catalogue), seed 6: ``thermal`` is significant but not decisive and floated, and the ``pass``
    probe that failed at the base fit is still significant beyond it (p ≈ 0.007 at α = 0.01):
    ``unexplained_structure`` is set and "more data would name it" is not printed."""
    from orbits.effects import EFFECTS

    sc = step_campaign()
    d = diagnose(
        simulate(sc, np.random.default_rng(6)),
        DisturbanceModel.from_scenario(sc),
        effects=[n for n in EFFECTS if n != "alignment_step"],
    )
    nd = {n["effect"]: n for n in d.not_decisive}
    assert "thermal" in nd and nd["thermal"]["explains_structure"] is False and "pass" in nd["thermal"]["structure_left"]
    assert d.unexplained_structure
    text = d.summary()
    assert "more data would name it" not in text and "it leaves the structure the base fit showed" in text


def test_landmark_datum_shift_is_named():
    """A 15 m east datum shift on 8 passes, ascending and descending (seed 5000): named, east
    within 3σ of 15 m, north within 3σ of 0."""
    sc = drift_campaign({"landmark_datum_shift": {"east_m": 15.0}}, n_passes=8)
    obs = simulate(sc, np.random.default_rng(5000))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.named == ["landmark_datum_shift"], d.summary()
    est, sig = np.array(d.steps[0]["estimate"]), np.array(d.steps[0]["sigma"])
    assert np.all(np.abs(est - [15.0, 0.0]) < 3 * sig)


# ---------------------------------------------------------------------------- slow: the Must-show rates

N = 40


def _interval(k, n):
    from boresight.stats import binomial_interval

    lo, hi = binomial_interval(k, n)
    return f"{k}/{n} [{lo:.2f}, {hi:.2f}]"


def _noise_rates(make_obs, model, seeds):
    """(named count, per-seed z (n, 3), reported σ (n, 3), θ errors (n, 3))."""
    named, zs, sig, err = 0, [], [], []
    for seed in seeds:
        obs = make_obs(seed)
        d = diagnose(obs, model)
        named += bool(d.named)
        th = obs.truth["theta_rad"][0] / ARCSEC
        err.append(np.array(d.theta_arcsec) - th)
        sig.append(np.array(d.theta_sigma_arcsec))
        zs.append(err[-1] / sig[-1])
    return named, np.array(zs), np.array(sig), np.array(err)


@pytest.mark.slow
def test_noise_1_5x_rates():
    """Every source 1.5× the declared, nothing hidden, seeds 3000–3039: nothing named in ≥ 38; θ
    within 3σ in ≥ 38; the reported σ within 15 % of θ's Monte Carlo scatter, measured as the RMS
    of θ's errors over the reported σ on the three axes pooled (1 when σ is right; 120 values give
    it a standard error of 1/√240 = 6.5 %, so a right σ fails the 15 % band with probability ≈ 2 %
    and the uninflated σ — RMS 1.5 — always fails)."""
    sc = discrepancy_campaign()
    model = DisturbanceModel.from_scenario(sc)
    sc15 = scaled(sc, 1.5)
    named, z, sig, err = _noise_rates(lambda s: simulate(sc15, np.random.default_rng(s)), model, range(3000, 3000 + N))
    within = int(np.sum(np.all(np.abs(z) < 3, axis=1)))
    rms = float(np.sqrt(np.mean(z**2)))
    ratio_axes = sig.mean(axis=0) / err.std(axis=0, ddof=1)
    print(
        f"\nRATE noise 1.5x: nothing named {_interval(N - named, N)}; θ within 3σ {_interval(within, N)}; "
        f"RMS(error/σ) {rms:.3f}; mean σ / scatter per axis {np.round(ratio_axes, 3).tolist()}"
    )
    assert N - named >= 38 and within >= 38 and abs(rms - 1) <= 0.15


@pytest.mark.slow
def test_student_t_rates():
    """Student-t noise (ν = 4) of the declared size on every source, seeds 3100–3139: the reported σ
    within 30 % of θ's scatter (RMS of error/σ pooled over the axes: standard error ≈ 9 % with the
    heavy tails) and never 2× above it (per axis, the mean reported σ over the scatter ≤ 2 in
    every seed's own σ: max σ / scatter ≤ 2)."""
    sc = discrepancy_campaign()
    model = DisturbanceModel.from_scenario(sc)
    named, z, sig, err = _noise_rates(
        lambda s: simulate(sc, StudentT(np.random.default_rng(s), 4.0)), model, range(3100, 3100 + N)
    )
    rms = float(np.sqrt(np.mean(z**2)))
    scatter = err.std(axis=0, ddof=1)
    worst = float(np.max(sig / scatter))
    print(
        f"\nRATE Student-t: named in {named}/{N}; RMS(error/σ) {rms:.3f}; mean σ / scatter per axis "
        f"{np.round(sig.mean(axis=0) / scatter, 3).tolist()}; largest σ / scatter {worst:.2f}"
    )
    assert abs(rms - 1) <= 0.3 and worst <= 2.0


@pytest.mark.slow
def test_alignment_step_rates():
    """8″ step after pass 2 of six, seeds 4000–4039: ``alignment_step`` named at the right boundary
    in ≥ 32 (a rate of 0.95 fails this with probability 1.3e-4, test_discrepancy_drift.MIN_GOOD);
    a wrong name kept with no flag (named, not the step at its boundary, and neither
    ``unexplained_structure`` nor ``ambiguous``) in 0."""
    sc = step_campaign()
    model = DisturbanceModel.from_scenario(sc)
    right, wrong, out = 0, 0, {}
    for seed in range(4000, 4000 + N):
        d = diagnose(simulate(sc, np.random.default_rng(seed)), model)
        ok = d.named == ["alignment_step"] and d.steps[0].get("after_pass") == 2
        right += ok
        wrong += bool(d.named) and not ok and not d.unexplained_structure and not d.ambiguous
        k = ",".join(d.named) or ("ambiguous" if d.ambiguous else "nothing")
        out[k] = out.get(k, 0) + 1
    print(f"\nRATE step 8″ after pass 2: {out}; right boundary {_interval(right, N)}; wrong name unflagged {wrong}")
    assert right >= 32 and wrong == 0


@pytest.mark.slow
def test_landmark_datum_shift_rates():
    """15 m east datum shift, 8 passes ascending and descending at eight latitudes, seeds
    5000–5039: ``landmark_datum_shift`` named or ``ambiguous`` with thermal in ≥ 36; ``thermal``
    alone named in ≤ 2."""
    sc = drift_campaign({"landmark_datum_shift": {"east_m": 15.0}}, n_passes=8)
    model = DisturbanceModel.from_scenario(sc)
    good, thermal, out = 0, 0, {}
    for seed in range(5000, 5000 + N):
        d = diagnose(simulate(sc, np.random.default_rng(seed)), model)
        amb = d.ambiguous[-1]["effects"] if d.ambiguous else []
        good += "landmark_datum_shift" in d.named or {"landmark_datum_shift", "thermal"} <= set(amb)
        thermal += d.named[:1] == ["thermal"] and "landmark_datum_shift" not in d.named
        k = ",".join(d.named) or ("ambiguous:" + "/".join(amb) if amb else "nothing")
        out[k] = out.get(k, 0) + 1
    print(f"\nRATE datum shift 15 m east: {out}; named or ambiguous with thermal {_interval(good, N)}; thermal alone {thermal}")
    assert good >= 36 and thermal <= 2
