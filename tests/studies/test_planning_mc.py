"""The planner's predictions against Monte Carlo on the Kiev 680 km case (issue 12 Must-show), ``slow``.

* the worked example of docs/planning.md (its numbers are the command's output);
* predicted σθ vs the sample σ of GLS fits of simulated campaigns, for the chosen campaign and
  two others on the Pareto front (95 % χ² interval of a sample σ, Bonferroni over the nine axes);
* the detection rate of an effect hidden at its predicted minimum detectable size vs the stated
  power (Clopper–Pearson interval);
* ``boresight.diagnose`` on the chosen campaign and on one the planner rejects, and the planner's
  predicted naming probability against the naming rate on two more campaigns.

Every test draws from fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest

from boresight.studies.planning import plan

pytestmark = pytest.mark.slow

PLAN = "plans/kiev680.toml"


@pytest.fixture(scope="module")
def kiev():
    """The shipped plan with every candidate scored in full (the pruned search leaves dominated
    candidates' naming scores NaN; these tests look at some of them: the detectability-only and
    coin-flip choices, the best η of the whole search). Its front and choice are checked equal."""
    import dataclasses

    from boresight.studies.planning.fisher import NOT_SEPARABLE_RATIO
    from boresight.studies.planning.search import choose, pareto_front

    r = plan(PLAN)
    s = r.score_every_candidate()
    tr, worst = r.theta_ratio, s.name_ratio.max(axis=1)
    feasible = (tr <= 1) & (worst <= 1)
    assert np.array_equal(pareto_front(s.cost, tr, np.minimum(worst, NOT_SEPARABLE_RATIO)), r.front)
    assert choose(s, feasible, tr, worst) == r.chosen
    return dataclasses.replace(r, scores=s, feasible=feasible)


def test_worked_example_numbers(kiev):
    """The figures quoted in docs/planning.md's worked example."""
    r = kiev
    c = r.chosen
    s = r.scores
    assert r.space_size == 74612 and r.enumerated_in_full and len(r.options) == 16
    assert s.cost[c] == pytest.approx(7.1)
    labels = [(p.site, p.direction, p.attitude) for p in r.passes(c)]
    assert labels == [
        ("Nairobi", "ascending", "nadir"),
        ("Nairobi", "ascending", "nadir"),
        ("Nairobi", "ascending", "site_tracking"),
        ("Nairobi", "descending", "nadir"),
        ("Nairobi", "descending", "nadir"),
        ("CapeTown", "descending", "site_tracking"),
    ]
    assert np.round([p.u_deg for p in r.passes(c)], 1).tolist() == [358.7, 358.7, 358.7, 181.3, 181.3, 214.3]
    assert np.round(s.sigma_theta_arcsec[c], 2).tolist() == [2.88, 3.35, 2.05]
    assert np.round(s.sigma_theta_only_arcsec[c], 2).tolist() == [2.43, 2.32, 1.76]
    assert np.round(s.detect_ratio[c], 3).tolist() == [0.774, 0.992]
    assert np.round(s.name_ratio[c], 3).tolist() == [0.837, 0.957]
    assert np.round(s.name_probability[c], 3).tolist() == [0.994, 0.977]
    assert np.round(s.canonical_rho[c], 3).tolist() == [0.983, 0.978]
    assert round(float(r.detectable_size(c, "time_tag")[0]) * 1e3, 1) == 15.5
    assert round(float(r.detectable_size(c, "thermal")[0]), 1) == 19.8
    # thermal at 15″: no campaign of the search is nameable; the best is 1.09 × 15″ = 16.4″
    assert round(float(np.min(s.name_ratio[:, 1]) * 20 / 15), 2) == 1.09
    from boresight.studies.planning.report import theta_only_choice, why

    w = why(r, c)
    tt, th = w["effects"]["time_tag"], w["effects"]["thermal"]
    assert tt["binding_rival"] == "thermal" and th["binding_rival"] == "landmark_datum_shift"
    # thermal's binding look-alike: with the datum shift floated ρ 0.694 → 0.992 (issue 30)
    assert th["binding_lookalike"] == "landmark_datum_shift"
    assert round(th["rho_theta_and_required_floated"], 3) == 0.694 and round(th["rho_with_binding_lookalike"], 3) == 0.992
    wo = np.array([p["rho_without"] for p in w["passes"]])
    assert np.round(wo[2, 0], 2) == 2.14 and np.round(wo[5, 0], 3) == 0.960
    assert np.round(wo[[0, 1, 3, 4], 0].min(), 2) == 0.85 and np.round(wo[[0, 1, 3, 4], 0].max(), 2) == 0.93
    assert np.round(wo[:, 1].min(), 2) == 1.03 and np.round(wo[:, 1].max(), 2) == 1.31
    assert th["separating_alone"] == [] and tt["separating_alone"] == []
    d = _detectability_choice(r)
    assert s.cost[d] == pytest.approx(6.85)
    assert [(p.site, p.direction, p.attitude) for p in r.passes(d)] == [
        ("CapeTown", "ascending", "nadir"),
        ("CapeTown", "ascending", "nadir"),
        ("CapeTown", "descending", "nadir"),
        ("Reykjavik", "ascending", "nadir"),
        ("Reykjavik", "ascending", "site_tracking"),
        ("Reykjavik", "descending", "nadir"),
    ]
    assert np.round(s.detect_ratio[d], 3).tolist() == [0.918, 0.916]
    assert np.round(s.name_probability[d], 2).tolist() == [0.96, 0.91] and np.round(s.name_ratio[d], 2).tolist() == [0.97, 1.04]
    t0 = theta_only_choice(r)
    assert s.cost[t0] == pytest.approx(5.75) and t0 != d
    assert np.round(s.name_ratio[t0], 2).tolist() == [1.22, 1.16]
    assert np.round(s.name_probability[t0], 2).tolist() == [0.76, 0.70]


def test_sigma_theta_agrees_with_monte_carlo_for_three_campaigns(kiev):
    """Chosen + the cheapest and the most accurate other feasible campaigns of the front."""
    from boresight.stats import sigma_interval
    from boresight.studies.planning.checks import sigma_check

    r = kiev
    front_ok = [int(f) for f in r.front if r.feasible[f] and f != r.chosen]
    rest = [f for f in front_ok[1:]]
    others = [front_ok[0]] + ([min(rest, key=lambda f: r.theta_ratio[f])] if rest else [])
    assert len(set([r.chosen] + others)) == 3
    for c in [r.chosen] + others:
        chk = sigma_check(r, c, runs=120, seed=11 + c, floated=r.spec.effect_names)
        s = np.array(chk.sample_sigma_arcsec)
        lo, hi = sigma_interval(s, chk.runs, level=1 - 0.05 / 9)
        pred = np.array(chk.predicted_arcsec)
        print(f"campaign {c} ({r.describe(c)}): {chk.text()}")  # the figures of docs/planning.md (pytest -s)
        assert np.all((pred >= lo) & (pred <= hi)), (c, chk.text())


def test_detection_rate_at_the_predicted_detectable_size(kiev):
    """Hide time_tag at its predicted minimum detectable size: the Wald test at α/K (time_tag,
    thermal and its binding look-alike floated — landmark_datum_shift since issue 30, gnss_bias before)
    detects it at the stated power (95 %)
    within the 99 % binomial interval of 100 runs (a factor-of-two error in σ puts the rate near
    the 30 % of λ*/4, outside it)."""
    from boresight.stats import binomial_interval
    from boresight.studies.planning.checks import detection_check

    r = kiev
    chk = detection_check(r, r.chosen, "time_tag", runs=100, seed=5)
    print(chk.text())
    assert chk.expected == pytest.approx(r.spec.power, abs=1e-6)
    lo, hi = binomial_interval(chk.detected, chk.runs, level=0.99)
    assert lo <= r.spec.power <= hi, chk.text()


def _nadir_only_campaign(r):
    """The cheapest nadir-only campaign meeting the σθ target with nothing floated: the planner
    rejects it (time_tag not separable)."""
    att = np.array([o.attitude for o in r.options] + ["none"])
    kinds = att[np.where(r.candidates < 0, len(r.options), r.candidates)]
    nadir_only = np.all((kinds == "nadir") | (kinds == "none"), axis=1)
    ok = np.flatnonzero(
        nadir_only & (np.max(r.scores.sigma_theta_only_arcsec / np.asarray(r.spec.sigma_theta_arcsec), axis=1) <= 1.0)
    )
    return int(ok[np.lexsort((r.theta_ratio[ok], r.scores.cost[ok]))][0])


def _detectability_choice(r):
    """What the planner chose when it scored detectability only (ρ ≤ 1 with each look-alike
    floated, no naming model): the cheapest such campaign meeting the σθ target."""
    ok = np.flatnonzero((r.theta_ratio <= 1.0) & np.all(r.scores.detect_ratio <= 1.0, axis=1))
    margin = np.maximum(r.theta_ratio[ok], r.scores.detect_ratio[ok].max(axis=1))
    return int(ok[np.lexsort((margin, r.scores.cost[ok]))][0])


def _coin_flip_campaign(r):
    """The cheapest campaign meeting the σθ target on which the planner predicts time_tag is named
    with probability 0.4–0.7: where a wrong naming model shows most."""
    p = r.scores.name_probability[:, 0]
    ok = np.flatnonzero((r.theta_ratio <= 1.0) & (p > 0.4) & (p < 0.7))
    return int(ok[np.lexsort((r.theta_ratio[ok], r.scores.cost[ok]))][0])


def test_rejected_campaign_does_not_name_time_tag(kiev):
    """40 seeds, time_tag hidden at the required 20 ms in a nadir-only campaign the planner rejects
    (not separable): boresight.diagnose never names it and reports it not separable."""
    from boresight.studies.planning.checks import naming_check
    from boresight.studies.planning.fisher import NOT_SEPARABLE_RATIO

    r = kiev
    c = _nadir_only_campaign(r)
    assert r.scores.detect_ratio[c, 0] >= NOT_SEPARABLE_RATIO
    assert np.isinf(r.scores.name_ratio[c, 0]) and r.scores.name_probability[c, 0] == 0.0
    chk = naming_check(r, c, "time_tag", seeds=range(40))
    print(f"rejected campaign {r.describe(c)}: {chk.text()}")
    assert chk.named == 0 and chk.not_separable == 40, chk.text()


def test_chosen_campaign_names_time_tag(kiev):
    """40 seeds, time_tag hidden at 20 ms in the chosen campaign: named in ≥ 95 % (the issue's
    Must-show), as the planner predicts."""
    from boresight.studies.planning.checks import naming_check

    r = kiev
    chk = naming_check(r, r.chosen, "time_tag", seeds=range(40))
    print(f"chosen campaign {r.describe(r.chosen)}: {chk.text()}")
    assert chk.predicted >= r.spec.power
    assert chk.named >= 38, chk.text()


@pytest.mark.parametrize(
    "which",
    [
        "detectability_only",
        pytest.param(
            "coin_flip",
            marks=pytest.mark.xfail(
                strict=True,
                raises=AssertionError,
                reason="the shipped plan does not score alignment_step (opt-in: spec.scanned_rivals), a rival of "
                "time_tag here: diagnose finds time_tag ambiguous with it in 22 of seeds 100-139 and names it in "
                "16/40 (95 % CI 0.25-0.57) against the predicted 0.690 (docs/planning.md, Checks); with the step "
                "scored the prediction is 0.256 (test_alignment_step_rival_predicts_the_coin_flip_campaign)",
            ),
        ),
    ],
)
def test_predicted_naming_rate_agrees_with_diagnose_on_two_other_campaigns(kiev, which):
    """The planner's P_name of time_tag at 20 ms against boresight.diagnose's naming rate over 40
    seeds on the campaign a detectability-only planner chose and on a 'coin-flip' campaign
    (predicted 0.4–0.7): each prediction inside the Clopper–Pearson interval of the observed rate
    (95 %, Bonferroni over the two). Halving every λ_sep moves the detectability-only prediction from
    0.963 to 0.739, below the interval of its 39/40 (0.85–1.00).

    Since issue 30 the coin-flip campaign fails (strict xfail, so that it is noticed when it passes):
    alignment_step, which the planner leaves out of the rivals, makes time_tag ambiguous there."""
    from boresight.stats import binomial_interval
    from boresight.studies.planning.checks import naming_check

    r = kiev
    campaigns = {"detectability_only": _detectability_choice(r), "coin_flip": _coin_flip_campaign(r)}
    assert r.chosen not in campaigns.values() and campaigns["detectability_only"] != campaigns["coin_flip"]
    c = campaigns[which]
    chk = naming_check(r, c, "time_tag", seeds=range(100, 140))
    lo, hi = binomial_interval(chk.named, chk.runs, level=1 - 0.05 / 2)
    print(f"campaign {r.describe(c)} (cost {r.scores.cost[c]:g}): {chk.text()}")
    assert lo <= chk.predicted <= hi, chk.text()


def test_alignment_step_rival_predicts_the_coin_flip_campaign(kiev):
    """The coin-flip campaign of docs/planning.md (Kiev descending nadir, Nairobi descending nadir, Cape
    Town ascending nadir twice, Cape Town descending site tracking, flown in that order) with
    alignment_step scored as a rival (``spec.scanned_rivals``, ``fisher.step_terms``): the planner's
    P_name of time_tag at 20 ms falls inside the Clopper–Pearson interval (95 %, Bonferroni over two as
    above) of diagnose's naming rate over seeds 100–139, where without the step it predicts 0.690 against
    16/40 (the strict xfail above). It must also be below that 0.690 (the step's last boundary isolates
    the one site-tracking pass)."""
    import dataclasses

    from boresight.stats import binomial_interval
    from boresight.studies.planning.checks import naming_check, predicted_naming_probability

    r = dataclasses.replace(kiev, spec=dataclasses.replace(kiev.spec, scanned_rivals=("alignment_step",)), step=True)
    want = [
        ("Kiev", "descending", "nadir"),
        ("Nairobi", "descending", "nadir"),
        ("CapeTown", "ascending", "nadir"),
        ("CapeTown", "ascending", "nadir"),
        ("CapeTown", "descending", "site_tracking"),
    ]
    ids = [next(o.index for o in r.options if (o.site, o.direction, o.attitude) == w) for w in want]
    c = int(np.flatnonzero((r.candidates[:, :5] == ids).all(axis=1) & (r.candidates[:, 5:] < 0).all(axis=1))[0])
    assert r.scores.cost[c] == pytest.approx(5.75)
    assert predicted_naming_probability(kiev, c, "time_tag") == pytest.approx(0.690, abs=5e-4)
    chk = naming_check(r, c, "time_tag", seeds=range(100, 140))
    lo, hi = binomial_interval(chk.named, chk.runs, level=1 - 0.05 / 2)
    print(f"coin-flip campaign {r.describe(c)} with alignment_step scored: {chk.text()}")
    assert chk.predicted < 0.6
    assert lo <= chk.predicted <= hi, chk.text()
