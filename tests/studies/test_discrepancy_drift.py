"""Issue 20 items 5 and the Must-show: a slow alignment drift is a catalogue effect
(``alignment_drift``), named — not ``thermal`` — with θ within 3σ after naming; its look-alikes are
in the identifiability table; effects outside the catalogue never leave a kept name with θ far off;
with nothing hidden nothing is named.

The campaigns are not the docs example: ``drift_campaign`` — site-tracking passes one day apart
(pass 2 nadir), a 1.5″ star tracker and 3 m GNSS per image (a modern platform: the drift's
signature is a rotation per image, so the per-image attitude and position noise set its
detectable size). The default run checks one seed on 5 passes; ``-m slow`` measures rates on 8
passes (docs/discrepancy.md quotes them with their intervals).
"""

import numpy as np
import pytest
from builders import drift_campaign

from boresight import simulate
from boresight.core.disturbances import DisturbanceModel
from boresight.studies.discrepancy import diagnose
from orbits.rotations import ARCSEC

pytest.importorskip("boresight.core.effect_model")


def theta_z(obs, d, truth_arcsec=None):
    """(θ − truth)/σ per axis of the diagnosis' final θ."""
    th = obs.truth["theta_rad"][0] / ARCSEC if truth_arcsec is None else np.asarray(truth_arcsec, float)
    return (np.array(d.theta_arcsec) - th) / np.array(d.theta_sigma_arcsec)


def test_drift_is_named_with_its_look_alikes_in_the_table():
    """3″/day about y on 5 passes (seed 0): the campaign-time probe fails before naming;
    ``alignment_drift`` is named, its rate within 3σ of the truth, θ (the mid-campaign alignment)
    within 3σ; the identifiability entry lists thermal and a per-pass star-tracker bias with
    their canonical correlations."""
    sc = drift_campaign({"alignment_drift": [0.0, 3.0, 0.0]})
    obs = simulate(sc, np.random.default_rng(0))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert any(t.name == "campaign time" and t.rejected for t in d.details["base_tests"]), d.summary()
    assert d.named == ["alignment_drift"], d.summary()
    s = d.steps[0]
    assert np.all(np.abs(np.array(s["estimate"]) - [0.0, 3.0, 0.0]) <= 3 * np.array(s["sigma"]))
    assert np.all(np.abs(theta_z(obs, d)) < 3), d.summary()
    e = next(x for x in d.identifiability if x["effect"] == "alignment_drift")
    assert set(e["look_alikes"]) == {"thermal", "per-pass star-tracker bias"}
    assert all(0 <= v <= 1 for v in e["look_alikes"].values())
    # a linear trend over passes is a per-pass rotation: the look-alike the noise model's per-pass
    # star-tracker errors would absorb
    assert e["look_alikes"]["per-pass star-tracker bias"] > 0.99


def test_drift_and_time_tag_seed_1_no_confident_wrong_answer():
    """Issue 20 item 1, the exact failing case (drift 1″/day + 20 ms time tag on 8 passes, seed 1).
    Both are named (Δχ² 4145 and 138) and the ``pass`` probe still fails, marginally (p 3.5e-4; Δχ²
    45 on 18 dof). ``pass`` holds a free rotation per pass, so it spans both names: it cannot test
    their withdrawal. The engine used to withdraw both as ``untestable``, redo the naming as if
    they were absent, and name a look-alike (``thermal``, later ``gnss_bias``) with θ_y 32–180σ
    off; a name withdrawn in the last round was even reported as named. Now the nested case is
    decided by the one naming rule: what ``pass`` adds beyond the names is not decisive by BIC
    (45.5 ≤ 18 ln 1680 = 134), so both are kept, saying why, and θ is within 3σ."""
    sc = drift_campaign({"alignment_drift": [0.0, 1.0, 0.0], "time_tag": 0.02}, n_passes=8)
    obs = simulate(sc, np.random.default_rng(1))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.named == ["time_tag", "alignment_drift"], d.summary()
    assert d.unexplained_structure and [t.name for t in d.details["final_tests"] if t.rejected] == ["pass"]
    assert np.all(np.abs(theta_z(obs, d)) < 3), d.summary()
    tested = {w["effect"]: w for w in d.details["withdrawal_tests"]}
    assert set(tested) == {"time_tag", "alignment_drift"}
    for w in tested.values():
        assert w["verdict"] == "kept" and w["statistic"] is None and "not decisive by BIC" in w["reason"], w
    assert d.withdrawn == []
    kept = [x for x in d.summary().splitlines() if x.startswith("kept ")]
    assert len(kept) == 2 and all("parsimonious" in x for x in kept)


def test_drift_and_time_tag_on_five_passes_theta_within_3_sigma():
    """Drift 1″/day + 20 ms time tag on 5 passes, seeds 0–3. The old engine named the time tag,
    then tested it against residual structure that was the drift/thermal ambiguous group's (not
    yet floated), called it ``untestable``, renamed without it and ended with nothing named and
    θ_y 140σ off in 3 of the 4 seeds. Now the residual verdict and the withdrawal tests use the
    model θ is quoted from (the ambiguous group floated): the time tag is named in all four,
    θ within 3σ; and whatever the rounds do, a name in ``withdrawn`` is never in ``named`` nor in
    the final model θ is quoted from."""
    sc = drift_campaign({"alignment_drift": [0.0, 1.0, 0.0], "time_tag": 0.02}, n_passes=5)
    model = DisturbanceModel.from_scenario(sc)
    for seed in range(4):
        obs = simulate(sc, np.random.default_rng(seed))
        d = diagnose(obs, model)
        assert "time_tag" in d.named and np.all(np.abs(theta_z(obs, d)) < 3), d.summary()
        gone = {w["effect"] for w in d.withdrawn}
        assert not gone & set(d.named), d.summary()
        assert not gone & set(d.details["final_state"].named)


def rotate_star_tracker(obs, eps_arcsec):
    """The reported attitude of each image n rotated by ε_n (star-tracker axes; ``eps_arcsec``
    (N, 3)): A_rep ← exp(Φ(ε_n)) A_rep, the sign of the Kiev 2012 star-tracker error (orbits.sensors)."""
    import dataclasses

    from orbits.rotations import quat_from_dcm, star_tracker_error_dcm

    A = obs.attitude_st()
    A2 = A.copy()
    eps = np.asarray(eps_arcsec, float) * ARCSEC
    for n in np.flatnonzero(np.any(eps != 0, axis=1)):
        A2[:, n] = star_tracker_error_dcm(eps[n]) @ A[:, n]
    out = dataclasses.replace(obs, q_is=quat_from_dcm(A2))
    assert np.allclose(out.attitude_st(), A2, atol=1e-12)
    return out


def switch_star_tracker(obs, eps_arcsec, from_pass):
    """The reported attitude of passes ≥ ``from_pass`` rotated by ε (star-tracker axes)."""
    sel = obs.pass_index >= from_pass
    return rotate_star_tracker(obs, np.outer(sel, np.asarray(eps_arcsec, float)))


def jitter_star_tracker(obs, amplitude_arcsec, period_s, rng):
    """Outside the catalogue and the noise model: a sinusoidal attitude jitter of the reported
    attitude about the star tracker's x axis, ``amplitude_arcsec`` at ``period_s``, a random phase
    per pass (zero mean over a campaign: θ's truth is unchanged)."""
    phase = rng.uniform(0, 2 * np.pi, obs.pass_index.max() + 1)[obs.pass_index]
    eps = np.zeros((obs.n_images, 3))
    eps[:, 0] = amplitude_arcsec * np.sin(2 * np.pi * obs.t_s / period_s + phase)
    return rotate_star_tracker(obs, eps)


def test_jitter_seed_1028_unexplained_scatter_is_carried_not_named():
    """One seed of the slow jitter rate (10″ at 37 s about the star tracker's x axis, outside the
    catalogue and the noise model) where the first diagnosis left θ > 3σ outside the defensible
    segment (``time_tag`` kept with the 9-effect catalogue, 7σ off): the variance-component step sizes the per-image star-tracker error to
    include the jitter (its rms about x is 10/√2 = 7.1″; a factor of two either way fails), redoes
    the diagnosis with it, names nothing and quotes θ within 3σ."""
    sc = drift_campaign(n_passes=8)
    seed, amp, period = 1028, 10.0, 37.0
    obs = simulate(sc, np.random.default_rng(seed))
    rng = np.random.default_rng(10_000 + seed)
    jit = jitter_star_tracker(obs, amp, period, rng)
    d = diagnose(jit, DisturbanceModel.from_scenario(sc))
    phase = np.random.default_rng(10_000 + seed).uniform(0, 2 * np.pi, jit.pass_index.max() + 1)[jit.pass_index]
    eps = np.array([np.mean(amp * np.sin(2 * np.pi * jit.t_s / period + phase)), 0.0, 0.0])
    th0 = obs.truth["theta_rad"][0] / ARCSEC
    th1 = th0 + np.asarray(jit.C_SK_nominal, float) @ eps
    first = d.details["before_variance_components"]
    # the fault this step mends: under the declared model θ ends > 3σ off (with the 9-effect catalogue the
    # first diagnosis kept time_tag; with 11 it floats an ambiguous datum shift / alignment step group)
    assert np.max(_far_from_segment(first, th0, th1)) > 3
    vc = {c["source"]: c for c in d.variance_components["components"]}
    # the per-image star-tracker σ the data say: the declared one and the jitter's rms about x together
    expected = np.hypot(sc.sigma_star_tracker_arcsec[0], 7.07)
    assert d.variance_components["failed"] is None and expected / 2 < vc["star_tracker_image_x"]["estimate"] < 2 * expected
    assert d.named == [] and np.max(_far_from_segment(d, th0, th1)) < 3


# ---------------------------------------------------------------------------- slow: rates


def _outcome(d):
    if d.named:
        return ",".join(d.named)
    if d.ambiguous:
        return "ambiguous:" + "/".join(d.ambiguous[-1]["effects"])
    if d.not_decisive:
        return "not decisive:" + ",".join(n["effect"] for n in d.not_decisive)
    return "nothing"


#: the slow rates' seeds (docs/discrepancy.md quotes them): 40 per campaign, 100 with nothing hidden
N_RATE_SEEDS = 40
#: a rate claimed ≥ 0.9 is checked as ≥ 32 of 40. Under a true rate 0.95 (what is measured),
#: P(X < 32) = 1.3e-4; under half of it (0.475, a factor-of-two error) P(X ≥ 32) = 2.5e-5.
MIN_GOOD = 32
#: θ within 3σ on all three axes fails with probability 1 − 0.9973³ = 0.8 % per seed when σ is
#: right: over 40 seeds P(≥ 3 failures) = 0.4 %. With σ quoted half its true size a seed fails
#: with probability 1 − (1 − 0.134)³ = 35 %, 14 of 40 expected: caught.
MAX_BAD_THETA = 2


def _rates(sc, seeds, perturb=None, truth=None):
    """Diagnose each seed; returns (outcomes, records) with each record's named set and θ z."""
    model = DisturbanceModel.from_scenario(sc)
    out, recs = {}, []
    for seed in seeds:
        obs = simulate(sc, np.random.default_rng(seed))
        obs2 = obs if perturb is None else perturb(obs, seed)
        d = diagnose(obs2, model)
        k = _outcome(d)
        out[k] = out.get(k, 0) + 1
        recs.append({"seed": seed, "named": set(d.named), "z": theta_z(obs, d, truth), "d": d, "obs": obs2})
    return out, recs


def _interval(k, n):
    from boresight.stats import binomial_interval

    lo, hi = binomial_interval(k, n)
    return f"{k}/{n} [{lo:.2f}, {hi:.2f}]"


@pytest.mark.slow
@pytest.mark.parametrize("rate", [1.0, 3.0])
def test_drift_rates(rate):
    """40 seeds on 8 passes: named ``alignment_drift`` (or ambiguous with a look-alike) in ≥ 32
    (``MIN_GOOD``), ``thermal`` alone never, θ within 3σ after naming in all but ``MAX_BAD_THETA``."""
    sc = drift_campaign({"alignment_drift": [0.0, rate, 0.0]}, n_passes=8)
    out, recs = _rates(sc, range(500, 500 + N_RATE_SEEDS))
    good = sum(v for k, v in out.items() if k == "alignment_drift" or (k.startswith("ambiguous") and "alignment_drift" in k))
    bad_theta = sum(1 for r in recs if "alignment_drift" in r["named"] and not np.all(np.abs(r["z"]) < 3))
    print(
        f"\nRATE drift {rate}″/day: {out}; named/ambiguous with a look-alike {_interval(good, N_RATE_SEEDS)}; "
        f"θ > 3σ after naming {bad_theta}"
    )
    assert good >= MIN_GOOD and out.get("thermal", 0) == 0 and bad_theta <= MAX_BAD_THETA


@pytest.mark.slow
def test_drift_and_time_tag_are_both_named():
    """40 seeds on 8 passes, drift 1″/day + a 20 ms time tag: both named in ≥ 32, θ within 3σ in
    all but ``MAX_BAD_THETA``; the time tag's final joint estimate is unbiased: its mean within
    4 standard errors of 20 ms (the value at its own naming step, before the drift is modelled,
    is not: docs/discrepancy.md)."""
    sc = drift_campaign({"alignment_drift": [0.0, 1.0, 0.0], "time_tag": 0.02}, n_passes=8)
    out, recs = _rates(sc, range(600, 600 + N_RATE_SEEDS))
    both = sum(r["named"] == {"alignment_drift", "time_tag"} for r in recs)
    bad_theta = sum(1 for r in recs if r["named"] and not np.all(np.abs(r["z"]) < 3))
    tt = np.array([r["d"].details["final_state"].named["time_tag"][0] for r in recs if "time_tag" in r["named"]])
    at_step = np.array(
        [next(s["estimate"] for s in r["d"].steps if s["effect"] == "time_tag") for r in recs if "time_tag" in r["named"]]
    )
    se = tt.std(ddof=1) / np.sqrt(tt.size)
    print(
        f"\nRATE drift + time tag: {out}; both named {_interval(both, N_RATE_SEEDS)}; kept a name with θ > 3σ: {bad_theta}; "
        f"time tag final {tt.mean():.5f} ± {se:.5f} s (SE, n = {tt.size}), at its step {at_step.mean():.5f} ± "
        f"{at_step.std(ddof=1) / np.sqrt(at_step.size):.5f} s"
    )
    assert both >= MIN_GOOD and bad_theta <= MAX_BAD_THETA
    assert abs(tt.mean() - 0.02) < 4 * se


def _far_from_segment(d, th0, th1):
    """(distance of θ outside the segment [θ0, θ1] per axis)/σ."""
    lo, hi = np.minimum(th0, th1), np.maximum(th0, th1)
    th = np.array(d.theta_arcsec)
    return np.maximum(np.maximum(lo - th, th - hi), 0.0) / np.array(d.theta_sigma_arcsec)


def _kept_far_off(recs, eps_of):
    """Seeds whose diagnosis kept a name with θ more than 3σ outside the segment [θ, θ + C_SK ε]
    between the two defensible alignments, ε = ``eps_of(record)`` (star-tracker axes, arcsec);
    each one is printed with its summary."""
    bad = 0
    for r in recs:
        th0 = r["obs"].truth["theta_rad"][0] / ARCSEC
        th1 = th0 + np.asarray(r["obs"].C_SK_nominal, float) @ eps_of(r)
        if r["named"] and np.any(_far_from_segment(r["d"], th0, th1) > 3):
            bad += 1
            print(r["seed"], r["d"].summary())
    return bad


@pytest.mark.slow
def test_star_tracker_switch_never_leaves_a_name_with_theta_far_off():
    """Outside the catalogue: the star tracker's error jumps by 5″ about its x axis at mid-campaign
    (passes 4–7 of 8). Over 40 seeds, a kept catalogue name comes with θ more than 3σ outside the
    segment between the two halves' effective alignments (θ and θ + C_SK ε: any value between is
    a defensible mean alignment) in at most ``MAX_BAD_THETA``."""
    sc = drift_campaign(n_passes=8)
    eps = np.array([5.0, 0.0, 0.0])
    out, recs = _rates(sc, range(700, 700 + N_RATE_SEEDS), perturb=lambda obs, seed: switch_star_tracker(obs, eps, 4))
    bad = _kept_far_off(recs, lambda r: eps)
    print(f"\nRATE star-tracker switch: {out}; kept a name with θ > 3σ off {_interval(bad, N_RATE_SEEDS)}")
    assert bad <= MAX_BAD_THETA


@pytest.mark.slow
def test_jitter_never_leaves_a_name_with_theta_far_off():
    """Outside the catalogue: a 10″ sinusoidal attitude jitter (period 37 s, random phase per pass)
    about the star tracker's x axis, on 8 passes (3″ is not even detected: the residual tests pass
    in 4 of 4 seeds). Zero mean in expectation, but a 90 s pass holds 2.4 periods, so its realised
    campaign mean ε̄ is not zero: as for the switch, any θ between θ and θ + C_SK ε̄ is defensible.
    Over 40 seeds, a kept catalogue name with θ more than 3σ outside that segment in at most
    ``MAX_BAD_THETA``."""
    sc = drift_campaign(n_passes=8)
    amp, period = 10.0, 37.0
    out, recs = _rates(
        sc,
        range(1000, 1000 + N_RATE_SEEDS),
        perturb=lambda obs, seed: jitter_star_tracker(obs, amp, period, np.random.default_rng(10_000 + seed)),
    )

    def eps_bar(r):  # the realised campaign mean of the jitter, as drawn in jitter_star_tracker
        obs = r["obs"]
        phase = np.random.default_rng(10_000 + r["seed"]).uniform(0, 2 * np.pi, obs.pass_index.max() + 1)[obs.pass_index]
        return np.array([np.mean(amp * np.sin(2 * np.pi * obs.t_s / period + phase)), 0.0, 0.0])

    bad = _kept_far_off(recs, eps_bar)
    print(f"\nRATE jitter: {out}; kept a name with θ > 3σ off {_interval(bad, N_RATE_SEEDS)}")
    assert bad <= MAX_BAD_THETA


@pytest.mark.slow
def test_nothing_hidden_nothing_named():
    """100 seeds on 5 passes with nothing hidden: a name in ≤ 1 (≥ 99 % name nothing)."""
    sc = drift_campaign()
    out, recs = _rates(sc, range(800, 900))
    named = sum(1 for r in recs if r["named"])
    print(f"\nRATE nothing hidden: {out}; named {_interval(named, 100)}")
    assert named <= 1
