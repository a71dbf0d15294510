"""The campaign planner (issue 12): plan file validation, the Fisher blocks against the dense
Cramér–Rao route, degeneracies the physics predicts, the search, the outputs, and a small Monte
Carlo check of the predicted σθ (the large ones are in tests/studies/test_planning_mc.py, ``slow``)."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest
from paths import ROOT
from scipy import stats

from boresight.stats import minimum_detectable_noncentrality
from boresight.studies.planning import PlanError, pareto_front, plan, plan_from_dict
from boresight.studies.planning.fisher import design_columns, noise_free_observations
from boresight.studies.planning.toml_out import dumps
from orbits.errors import BoresightError
from orbits.rotations import ARCSEC
from orbits.scenario import scenario_from_dict

BASE = {
    "name": "tplan",
    "earth_model": "spherical",
    "orbit": {"altitude_km": 680.0, "inclination_deg": 98.0},
    "camera": {"focal_length_m": 2.2, "fov_deg": 3.4},
    "star_tracker": {"mount_deg": [59.0, 19.0, 132.2], "sigma_arcsec": [4.0, 4.0, 4.0], "error_mode": "both"},
    "gnss": {"sigma_m": 15.0, "error_mode": "both"},
    "pixel": {"sigma_m": 3e-6},
    "catalogue": {"sigma_m": 0.1},
    "sites": [
        {"name": "Kiev", "lat_deg": 50.45, "lon_deg": 30.52},
        {"name": "Nairobi", "lat_deg": -1.29, "lon_deg": 36.82},
    ],
    "requirements": {"sigma_theta_arcsec": [6.0, 6.0, 6.0]},
    "search": {
        "passes": [1, 3],
        "images_per_pass": [8],
        "landmarks_per_image": [6],
        "image_interval_s": {"nadir": 1.0, "site_tracking": 10.0},
    },
}

#: campaigns of exactly two passes, site-tracking or nadir, of 5 images of 5 landmarks: small enough to simulate
#: and fit in a test (the Monte Carlo checks' fits against the estimator's)
TWO_PASS_SEARCH = {
    "passes": [2, 2],
    "attitudes": ["site_tracking", "nadir"],
    "images_per_pass": [5],
    "landmarks_per_image": [5],
    "image_interval_s": {"site_tracking": 10.0, "nadir": 1.0},
}


def _doc(**changes):
    d = copy.deepcopy(BASE)
    for k, v in changes.items():
        d[k] = copy.deepcopy(v)  # a shared change (TWO_PASS_SEARCH) stays as written
    return d


# ---------------------------------------------------------------------------- the plan file


@pytest.mark.parametrize(
    "change, match",
    [
        (
            {"requirements": {"sigma_theta_arcsec": [1.0, -2.0, 1.0]}},
            r"\[requirements\] sigma_theta_arcsec\[1\] = -2.0: must be > 0",
        ),
        (
            {"requirements": {"sigma_theta_arcsec": [1.0, 1.0]}},
            r"sigma_theta_arcsec = \[1.0, 1.0\]: must be a number or an array of three",
        ),
        ({"requirements": {"sigma_theta_arcsec": 1.0, "power": 1.5}}, r"\[requirements\] power = 1.5: must be ≤"),
        ({"requirements": {"sigma_theta_arcsec": 1.0, "effects": {"tangential": 1e-6}}}, r"requirements.effects.tangential"),
        (
            {"requirements": {"sigma_theta_arcsec": 1.0, "effects": {"time_tag": {"dt": 0.02}}}},
            r"requirements.effects.time_tag.*unknown parameter",
        ),
        ({"requirements": {"sigma_theta_arcsec": 1.0, "effects": {"focal_scale": 0.0}}}, r"focal_scale.*must not be zero"),
        (
            {"requirements": {"sigma_theta_arcsec": 1.0, "effects": {"alignment_drift": [0.0, 1.0, 0.0]}}},
            r"\[requirements.effects\] alignment_drift = .*cannot be planned",
        ),
        (
            {"requirements": {"sigma_theta_arcsec": 1.0, "effects": {"time_tag": 0.02}, "lookalikes": ["alignment_drift"]}},
            r"lookalikes = 'alignment_drift': cannot be scored",
        ),
        ({"search": {"passes": [3, 2]}}, r"\[search\] passes\[1\] = 2: must be ≥ 3"),
        ({"search": {"attitudes": ["inertial"]}}, r"\[search\] attitudes\[0\] = 'inertial': must be one of"),
        ({"search": {"images_per_pass": [2.5]}}, r"images_per_pass\[0\] = 2.5: must be a whole number"),
        ({"search": {"imags_per_pass": [20]}}, r"\[search\].imags_per_pass.*unknown key"),
        ({"cost": {"per_pass": -1}}, r"\[cost\] per_pass = -1: must be ≥ 0"),
        ({"cost": {"per_pass": 2.0}}, r"\[cost\] unit is not given, and \[cost\] per_pass = 2"),
        ({"cost": {"unit": " "}}, r"\[cost\] unit = ' ': must be a non-empty string"),
        ({"sites": [{"name": "Pole", "lat_deg": 89.0, "lon_deg": 0.0}]}, r"sites\[0\].lat_deg = 89.0: is never overflown"),
        ({"sites": [{"name": "A", "lat_deg": 10.0}]}, r"sites\[0\] is missing lon_deg"),
        (
            {"sites": [{"name": "A", "lat_deg": 10.0, "lon_deg": 0.0}, {"name": "A", "lat_deg": 20.0, "lon_deg": 0.0}]},
            r"sites\[1\].name = 'A': repeats",
        ),
        ({"orbit": {"altitude_km": -680.0, "inclination_deg": 98.0}}, r"plan.toml: \[orbit\] altitude_km = -680.0"),
        ({"pixel": {"sigma_m": "3e-6"}}, r"\[pixel\] sigma_m = '3e-6': must be a number"),
        ({"extra_table": {}}, r"extra_table = \{\}: unknown key"),
    ],
)
def test_plan_file_errors_name_the_key(change, match):
    with pytest.raises(BoresightError, match=match) as info:
        plan_from_dict(_doc(**change), source="plan.toml")
    assert isinstance(info.value, ValueError)
    assert "plan.toml" in str(info.value)


def test_cost_unit_defaults_to_pass_equivalents_and_is_kept_as_written():
    assert plan_from_dict(_doc(), source="p.toml").cost_unit == "pass-equivalents"
    spec = plan_from_dict(_doc(cost={"per_pass": 3.0, "unit": "hours of ground-station time"}), source="p.toml")
    assert spec.cost_unit == "hours of ground-station time"


def test_missing_required_table():
    d = _doc()
    del d["requirements"]
    with pytest.raises(PlanError, match=r"missing required table \[requirements\]"):
        plan_from_dict(d, source="p.toml")


def test_shipped_plan_file_loads():
    from boresight.studies.planning import load_plan

    spec = load_plan("plans/kiev680.toml")
    assert spec.effect_names == ["time_tag", "thermal"]
    assert spec.effects["thermal"].tolist() == [20.0, 0.0, 0.0, 0.0, 20.0, 0.0]
    # K of the naming level α/K defaults to diagnose's: every catalogue effect
    from orbits.effects import EFFECTS

    assert spec.passes_max == 6 and spec.n_candidates == len(EFFECTS) == 11


# ---------------------------------------------------------------------------- statistics


@pytest.mark.parametrize("level, power", [(0.05, 0.8), (0.01 / 8, 0.95), (0.001, 0.5)])
def test_noncentrality_one_dof_matches_the_normal_formula(level, power):
    lam = minimum_detectable_noncentrality(1, level, power)
    z = stats.norm.isf(level / 2)
    # |Z + √λ| > z has probability Φ(√λ − z) + Φ(−√λ − z)
    got = stats.norm.cdf(np.sqrt(lam) - z) + stats.norm.cdf(-np.sqrt(lam) - z)
    assert got == pytest.approx(power, abs=1e-8)


def test_pareto_front_matches_brute_force():
    rng = np.random.default_rng(3)
    cost = rng.integers(1, 6, 400).astype(float)
    a = rng.uniform(0, 1, 400)
    b = rng.uniform(0, 1, 400)
    front = set(pareto_front(cost, a, b).tolist())
    brute = set()
    for i in range(400):
        dom = (cost <= cost[i]) & (a <= a[i]) & (b <= b[i]) & ((cost < cost[i]) | (a < a[i]) | (b < b[i]))
        if not dom.any():
            brute.add(i)
    assert front == brute


# ---------------------------------------------------------------------------- Fisher blocks


@pytest.fixture(scope="module")
def small_pruned():
    """The plan as ``plan`` returns it: only the candidates that may matter scored in full."""
    d = _doc(requirements={"sigma_theta_arcsec": [6.0, 6.0, 6.0], "effects": {"time_tag": {"dt_s": 0.05}}})
    return plan(plan_from_dict(d, source="small.toml"))


@pytest.fixture(scope="module")
def small_result(small_pruned):
    """The same plan with every candidate scored in full: the tests of the scoring model look at
    candidates the pruned search leaves out (dominated ones)."""
    import dataclasses

    return dataclasses.replace(small_pruned, scores=small_pruned.score_every_candidate())


def _dense_information(result, c, names):
    """Xᵀ Σ⁻¹ X of the whole campaign with the dense residual covariance (boresight.core.crlb)."""
    from boresight.core.crlb import full_residual_covariance

    sc = scenario_from_dict(result.scenario_document(c))
    obs, model = noise_free_observations(sc)
    X, _ = design_columns(obs, names)  # (1, 2K, P): the rows' two components in order
    S = full_residual_covariance(obs, np.zeros(3), model)[0]  # (2K, 2K) over the rows, in the same order
    return X[0].T @ np.linalg.solve(S, X[0])


def test_block_sum_equals_dense_bound_of_the_campaign(small_result):
    r = small_result
    # a 3-pass campaign mixing a nadir and a site-tracking pass over two sites
    kinds = {(o.site, o.attitude) for o in r.options}
    assert ("Kiev", "nadir") in kinds and ("Nairobi", "site_tracking") in kinds
    want = [
        next(o.index for o in r.options if o.site == s and o.attitude == a)
        for s, a in (("Kiev", "nadir"), ("Nairobi", "site_tracking"), ("Kiev", "site_tracking"))
    ]
    c = int(np.flatnonzero((np.sort(r.candidates, axis=1) == np.sort(want)).all(axis=1))[0])
    names = list(r.spec.effect_names) + list(r.spec.lookalikes)
    assert names[0] == "time_tag" and "gnss_bias" in names  # the look-alikes ride along
    dense = _dense_information(r, c, names)
    assert np.allclose(r.information(c), dense, rtol=1e-8, atol=1e-10 * np.abs(dense).max())
    # θ-only part against the project's own Cramér–Rao route (crlb.fisher_information)
    from boresight.core.crlb import fisher_information

    sc = scenario_from_dict(r.scenario_document(c))
    obs, model = noise_free_observations(sc)
    info = fisher_information(obs, model)[0] * ARCSEC**2
    assert np.allclose(r.information(c)[:3, :3], info, rtol=1e-8)
    # and the scored σθ is the inverse's diagonal with θ and the required effect floated
    cov = np.linalg.inv(dense[:4, :4])
    assert np.allclose(r.scores.sigma_theta_arcsec[c], np.sqrt(np.diag(cov)[:3]), rtol=1e-6)
    # ρ with a look-alike floated is never below the joint ρ
    assert np.all(r.scores.detect_ratio >= r.scores.detect_ratio_joint * (1 - 1e-9))


def test_step_gram_from_pass_blocks_equals_the_dense_gram(small_result):
    """alignment_step at the gap before the b-th pass (flight order = the candidate's option order) has θ's
    columns over passes b… and none before: its Gram with [θ, effects] from suffix sums of the per-pass θ
    rows (``fisher.step_terms``) equals Xᵀ Σ⁻¹ X of the whole campaign with the step's columns assembled
    directly (θ's Jacobian masked to the rows of those passes, the dense Σ of ``crlb``), to 1e-9."""
    from boresight.core.crlb import full_residual_covariance
    from boresight.studies.planning.fisher import _augment, step_terms

    r = small_result
    want = [
        next(o.index for o in r.options if o.site == s and o.attitude == a)
        for s, a in (("Kiev", "nadir"), ("Nairobi", "site_tracking"), ("Kiev", "site_tracking"))
    ]
    c = int(np.flatnonzero((np.sort(r.candidates, axis=1) == np.sort(want)).all(axis=1))[0])
    sc = scenario_from_dict(r.scenario_document(c))
    obs, model = noise_free_observations(sc)
    names = list(r.spec.effect_names) + list(r.spec.lookalikes)
    X, _ = design_columns(obs, names)
    S = full_residual_covariance(obs, np.zeros(3), model)[0]
    row_pass = np.repeat(obs.pass_index[obs.image_index], 2)  # the rows' two components
    T, _, B = step_terms(r.blocks, r.candidates[c : c + 1])
    assert T.shape[1] == 2 and B[0] == 2  # three passes: two gaps
    for b in (1, 2):
        Xs = np.concatenate([X[0], X[0][:, :3] * (row_pass >= b)[:, None]], axis=1)
        dense = Xs.T @ np.linalg.solve(S, Xs)
        got = _augment(r.information(c)[None], T[:, b - 1])[0]
        assert np.allclose(got, dense, rtol=1e-9, atol=1e-9 * np.abs(dense).max())


def test_alignment_step_as_a_rival_only_lowers_the_naming_probability(small_result):
    """``[requirements] lookalikes`` naming alignment_step: it is scored (``spec.scanned_rivals``) as the
    last look-alike and rival. One more rival multiplies P_name by a factor ≤ 1 and one more look-alike
    can only raise ρ, so on every candidate P_name(with) ≤ P_name(without) and ρ(with) ≥ ρ(without); the
    step's look-alike ρ is the largest over its boundaries (the worst one, from ``step_terms`` directly);
    and somewhere the step binds (a test that the rival is live, not a zero column). A one-pass campaign
    has no gap: nothing changes there. A look-alike list naming alignment_drift is still refused."""
    import dataclasses

    from boresight.studies.planning.fisher import _augment, _rho, covariance_batch, step_terms

    r = small_result
    look = list(r.spec.lookalikes)
    spec = dataclasses.replace(r.spec, scanned_rivals=("alignment_step",))
    on = dataclasses.replace(r, spec=spec, step=True)
    s = on.score_every_candidate()
    assert on.rival_names()[-1] == "alignment_step" and s.lookalike_ratio.shape[-1] == len(look) + 1
    p0, p1 = r.scores.name_probability, s.name_probability
    assert np.all(p1 <= p0 + 1e-9) and np.any(p1 < p0 - 0.05)
    assert np.all(s.detect_ratio >= r.scores.detect_ratio * (1 - 1e-9))
    assert np.any(s.binding_rival == len(on.rival_names()) - 1)
    one = (r.candidates >= 0).sum(axis=1) == 1
    np.testing.assert_allclose(p1[one], p0[one], rtol=1e-12)
    # the step's look-alike ρ: the worst boundary, from the augmented information inverted whole
    ids = np.flatnonzero((r.candidates >= 0).sum(axis=1) == 3)
    T, _, _ = step_terms(r.blocks, r.candidates[ids])
    nb = 3 + sum(sl.stop - sl.start for sl in r.effect_slices)
    P = r.blocks.shape[-1]
    info = np.stack([r.information(int(c)) for c in ids])
    want = np.zeros((ids.size, len(r.effect_slices)))
    for b in range(T.shape[1]):
        keep = np.r_[0:nb, P : P + 3]
        aug = _augment(info, T[:, b])[:, keep[:, None], keep[None, :]]
        cov, _ = covariance_batch(aug)
        want = np.maximum(want, _rho(cov, r.effect_slices, r.required, r.lam_star))
    got = s.lookalike_ratio[ids, :, -1]
    ok = want < 1e3
    assert ok.sum() > 10
    np.testing.assert_allclose(got[ok], want[ok], rtol=1e-6)


def test_time_tag_needs_a_site_tracking_pass(small_result):
    """Under nadir pointing the attitude rate is constant in the body, so −ω dt is a constant
    rotation absorbed into θ: nadir-only campaigns cannot separate it; one site-tracking pass can."""
    r = small_result
    att = np.array([o.attitude for o in r.options] + ["none"])
    kinds = att[np.where(r.candidates < 0, len(r.options), r.candidates)]
    nadir_only = np.all((kinds == "nadir") | (kinds == "none"), axis=1)
    with_track = np.any(kinds == "site_tracking", axis=1) & ((r.candidates >= 0).sum(axis=1) >= 2)
    rho = r.scores.detect_ratio[:, 0]
    assert np.all(rho[nadir_only] > 100), rho[nadir_only].min()
    assert np.median(rho[with_track]) < 10


def test_thermal_needs_different_arguments_of_latitude():
    """θ(u) = θ0 + a sin u + b cos u: passes at one u see a constant (absorbed into θ)."""
    d = _doc(
        requirements={"sigma_theta_arcsec": 6.0, "effects": {"thermal": [15.0, 0, 0, 0, 15.0, 0]}},
        search={
            "passes": [1, 4],
            "attitudes": ["nadir"],
            "images_per_pass": [8],
            "landmarks_per_image": [6],
            "image_interval_s": {"nadir": 1.0},
        },
    )
    d["sites"] = [
        {"name": "Kiev", "lat_deg": 50.45, "lon_deg": 30.52},
        {"name": "Nairobi", "lat_deg": -1.29, "lon_deg": 36.82},
        {"name": "Cape", "lat_deg": -33.9, "lon_deg": 18.4},
    ]
    r = plan(plan_from_dict(d, source="thermal.toml"))
    u = np.array([o.u_deg for o in r.options])
    ids = r.candidates
    n = (ids >= 0).sum(axis=1)
    uu = np.where(ids >= 0, u[np.maximum(ids, 0)], np.nan)
    one_u = np.nanmax(uu, axis=1) - np.nanmin(uu, axis=1) < 1.0
    rho = r.score_every_candidate().detect_ratio[:, 0]  # every candidate, dominated ones too
    assert np.all(rho[one_u] > 100)
    spread = (n == 4) & ~one_u
    assert rho[spread].min() < rho[one_u].min() / 10


def test_no_pixel_noise_is_refused():
    with pytest.raises(PlanError, match=r"\[pixel\] sigma_m = 0.0"):
        plan(plan_from_dict(_doc(pixel={"sigma_m": 0.0}), source="p.toml"))


# ---------------------------------------------------------------------------- outputs


def test_toml_writer_round_trip(small_result):
    doc = small_result.scenario_document(int(small_result.front[-1]))
    assert tomllib.loads(dumps(doc, header="a\nb")) == doc


def test_cli_writes_outputs_and_the_chosen_scenario_simulates(tmp_path):
    from astropy.table import Table

    from boresight.cli.main import main

    p = tmp_path / "p.toml"
    d = _doc(requirements={"sigma_theta_arcsec": [6.0, 6.0, 6.0], "effects": {"time_tag": 0.05}})
    p.write_text(
        dumps({k: v for k, v in d.items() if k not in ("sites", "requirements", "search")})
        + "\n"
        + "\n".join(f'[[sites]]\nname = "{s["name"]}"\nlat_deg = {s["lat_deg"]}\nlon_deg = {s["lon_deg"]}\n' for s in d["sites"])
        + "\n[requirements]\nsigma_theta_arcsec = [6.0, 6.0, 6.0]\n[requirements.effects]\ntime_tag = 0.05\n"
        + "[search]\npasses = [1, 3]\nimages_per_pass = [8]\nlandmarks_per_image = [6]\nimage_interval_s = { nadir = 1.0, site_tracking = 10.0 }\n"
    )
    out = tmp_path / "out"
    assert main(["plan", str(p), "--out", str(out)]) == 0
    t = Table.read(out / "front.ecsv")
    assert t["sigma_theta_x"].unit == "arcsec" and t["chosen"].sum() == 1
    assert np.all(np.diff(t["cost"]) >= 0)
    md = (out / "summary.md").read_text()
    assert "## Why this campaign" in md and "time_tag" in md
    assert (out / "plan.png").stat().st_size > 1000
    # the chosen campaign is a scenario `boresight simulate` runs as is
    sim = tmp_path / "sim"
    assert main(["simulate", str(out / "chosen.toml"), "--out", str(sim)]) == 0
    assert list(sim.glob("*.ecsv"))
    # the chosen campaign is the cheapest that meets the requirements
    chosen = t[t["chosen"]][0]
    assert chosen["meets_requirements"]
    assert not np.any(t["meets_requirements"] & (t["cost"] < chosen["cost"]))


def test_cli_exit_status_when_nothing_meets_the_requirements(tmp_path, capsys):
    from boresight.cli.exit_codes import EXIT_NO_CAMPAIGN
    from boresight.cli.main import main

    p = tmp_path / "p.toml"
    p.write_text(
        dumps({k: v for k, v in BASE.items() if k not in ("sites", "requirements", "search")})
        + '\n[[sites]]\nname = "Kiev"\nlat_deg = 50.45\nlon_deg = 30.52\n'
        + '\n[requirements]\nsigma_theta_arcsec = 0.01\n[search]\npasses = 2\nimages_per_pass = [5]\nlandmarks_per_image = [5]\nattitudes = ["site_tracking"]\n'
    )
    assert main(["plan", str(p), "--out", str(tmp_path / "o"), "--no-plot"]) == EXIT_NO_CAMPAIGN
    assert "NONE" in capsys.readouterr().out
    assert "No campaign in the search space meets every requirement" in (tmp_path / "o" / "summary.md").read_text()


# ---------------------------------------------------------------------------- Monte Carlo (small)


def test_predicted_sigma_theta_agrees_with_monte_carlo_small():
    """One site-tracking pass: sample σ of θ̂ − θ over 300 GLS fits vs the prediction.

    Tolerance from the sampling distribution: the 99.9 % χ² interval of σ for n = 300 is
    ±~12 %, so a factor-of-two error (or forgetting the per-pass star-tracker error, which
    halves σθ) fails."""
    from boresight.stats import sigma_interval
    from boresight.studies.planning.checks import sigma_check

    d = _doc(
        search={
            "passes": [1, 1],
            "attitudes": ["site_tracking"],
            "images_per_pass": [6],
            "landmarks_per_image": [5],
            "image_interval_s": {"site_tracking": 10.0},
        }
    )
    d["sites"] = [d["sites"][0]]
    d["sites"][0]["directions"] = ["ascending"]
    r = plan(plan_from_dict(d, source="mc.toml"))
    assert r.candidates.shape[0] == 1
    chk = sigma_check(r, 0, runs=300, seed=7, chunk=150)
    s = np.array(chk.sample_sigma_arcsec)
    lo, hi = sigma_interval(s, chk.runs, level=0.999)
    pred = np.array(chk.predicted_arcsec)
    assert np.all((pred >= lo) & (pred <= hi)), (s, pred)


def test_front_door_boresight_plan():
    import boresight
    from boresight.studies.planning import PlanResult

    d = _doc(search={"passes": [1, 1], "attitudes": ["site_tracking"], "images_per_pass": [4], "landmarks_per_image": [4]})
    r = boresight.plan(d, max_candidates=10)
    assert isinstance(r, PlanResult) and r.candidates.shape == (4, 1)  # 2 sites × 2 directions


def test_linear_gls_is_the_estimators_gls():
    """The Monte Carlo checks' fast fit equals boresight.estimate's GLS linearised once about 0."""
    import boresight
    from boresight.core.disturbances import DisturbanceModel
    from boresight.observations.simulate import simulate
    from boresight.studies.planning.fisher import linear_gls

    d = _doc(search=TWO_PASS_SEARCH)
    r = plan(plan_from_dict(d, source="lin.toml"))
    c = int(np.argmin(r.theta_ratio))
    sc = scenario_from_dict(r.scenario_document(c))
    obs = simulate(sc, np.random.default_rng(3), runs=3)
    model = DisturbanceModel.from_scenario(sc)
    x, cov, labels = linear_gls(obs, model)
    est = boresight.estimate(obs, weighting="gls", model=model, iterate=False)
    assert np.allclose(x, est.theta.to_value("arcsec"), rtol=0, atol=1e-6)
    assert np.allclose(cov, est.covariance.to_value("arcsec2"), rtol=1e-6)
    # with an effect floated the θ block of the covariance is the scored one
    x2, cov2, labels2 = linear_gls(obs, model, ["time_tag"])
    assert labels2[3] == "time_tag.dt_s"
    from boresight.studies.planning.fisher import information_block

    nominal, _ = noise_free_observations(sc)
    info, _ = information_block(nominal, model, ["time_tag"])
    # the time_tag column uses the attitude rate differentiated from the noisy reported attitudes
    # (4″ per image), so each run's σ differs from the nominal one by a few per cent
    assert np.allclose(np.sqrt(np.diagonal(cov2, axis1=1, axis2=2)), np.sqrt(np.diag(np.linalg.inv(info))), rtol=0.05)


# ---------------------------------------------------------------------------- naming (planning.naming)


def _projection_stats(Z, cols):
    """‖P_[cols] z‖² for each column z of Z (n, R)."""
    Q, _ = np.linalg.qr(cols)
    return np.sum((Q.T @ Z) ** 2, axis=0)


def test_naming_probability_against_a_simulated_diagnosis_rule():
    """Whitened linear model z = X b + c_e δ + ε: the diagnosis' first-round rule (Holm at α/K,
    BIC, winner by p-value, ambiguity when ΔlogL < 2 or e adds nothing at α once f is in) applied
    to 6000 draws, against naming.naming_scores (and the mean and variance of D = Δχ²_e − Δχ²_f)."""
    from boresight.studies.planning.naming import NamingRule, naming_scores

    rng = np.random.default_rng(7)
    n = 300
    X = rng.normal(size=(n, 3))
    ce = rng.normal(size=(n, 1)) + 0.3 * X[:, :1]
    cf = np.column_stack([0.8 * ce[:, 0] + 0.6 * rng.normal(size=n), rng.normal(size=n)])  # a look-alike, 2 parameters
    A = np.column_stack([X, ce, cf])
    info = (A.T @ A)[None]
    rule = NamingRule(level=0.01 / 2, alpha=0.01, power=0.9, dlogl=2.0, rho_max=0.995)
    lam_e = float(info[0, 3, 3] - info[0, 3, :3] @ np.linalg.solve(info[0, :3, :3], info[0, :3, 3]))
    delta = np.sqrt(30.0 / lam_e)  # λ_e = 30: a naming probability in the sensitive middle
    sl_e, sl_f = slice(3, 4), slice(4, 6)
    _, pname, rho, _ = naming_scores(
        info, info, np.array([float(n)]), [sl_e], [np.array([delta])], np.array([[30.0 * (1 - 0.0)]]), [sl_e, sl_f], rule
    )
    R = 6000
    Z = X @ rng.normal(size=(3, R)) + ce * delta + rng.normal(size=(n, R))
    chi_x = _projection_stats(Z, X)
    de = _projection_stats(Z, np.column_stack([X, ce])) - chi_x
    df = _projection_stats(Z, np.column_stack([X, cf])) - chi_x
    d_both = _projection_stats(Z, A) - _projection_stats(Z, np.column_stack([X, cf]))
    pe, pf = stats.chi2.sf(de, 1), stats.chi2.sf(df, 2)
    K = 2
    e_first = pe < pf
    sig_e = (pe <= rule.level) & (de > np.log(n))
    sig_f = pf <= 0.01 / K
    ambiguous = sig_f & ((0.5 * (de - df) < 2.0) | (stats.chi2.sf(d_both, 1) > rule.alpha))
    named = e_first & sig_e & ~ambiguous
    # the moments of D (the derivation in naming's docstring)
    S = info[0, 3:, 3:] - info[0, 3:, :3] @ np.linalg.solve(info[0, :3, :3], info[0, :3, 3:])
    lam_sep = delta**2 * (S[0, 0] - S[0, 1:] @ np.linalg.solve(S[1:, 1:], S[1:, 0]))
    kappa2 = (S[0, 1:] @ np.linalg.solve(S[1:, 1:], S[1:, 0])) / S[0, 0]
    D = de - df
    mean, var = 1 - 2 + lam_sep, 2 * (1 + 2 - 2 * kappa2) + 4 * lam_sep
    assert abs(D.mean() - mean) < 4 * np.sqrt(var / R)
    assert abs(D.var() / var - 1) < 4 * np.sqrt(2 / R) * 2  # kurtosis allowance
    # the predicted naming rate within 4 binomial σ (±0.02 here; halving λ_sep moves it by > 0.1)
    rate = named.mean()
    sd = np.sqrt(pname[0, 0] * (1 - pname[0, 0]) / R)
    assert 0.3 < pname[0, 0] < 0.95
    print(
        f"simulated naming rate {rate:.3f}, predicted {pname[0, 0]:.3f}; D mean {D.mean():.2f} (predicted {mean:.2f}), var {D.var():.1f} ({var:.1f})"
    )
    assert abs(rate - pname[0, 0]) < 4 * sd + 0.01, (rate, pname[0, 0])
    assert rho[0, 0] < 0.995


def test_canonical_correlation_and_raw_information_match_the_diagnosis(small_result):
    """The planner's canonical ρ of time_tag with the diagnosis' base model, and its information
    with only the per-image errors marginalised, equal those ``boresight.diagnose`` computes on
    simulated data of the same campaign (up to the noise of the attitude rate the diagnosis
    derives from the star-tracker quaternions)."""
    from boresight.core.disturbances import DisturbanceModel
    from boresight.observations.simulate import simulate
    from boresight.studies.discrepancy.campaign import CampaignProblem
    from boresight.studies.discrepancy.candidates import catalogue_candidates
    from boresight.studies.discrepancy.linear import extend
    from boresight.studies.discrepancy.state import State

    r = small_result
    kinds = {(o.site, o.attitude): o.index for o in r.options}
    want = sorted([kinds[("Kiev", "nadir")], kinds[("Nairobi", "site_tracking")], kinds[("Kiev", "site_tracking")]])
    c = int(np.flatnonzero((np.sort(r.candidates, axis=1) == want).all(axis=1))[0])
    sc = scenario_from_dict(r.scenario_document(c))
    obs = simulate(sc, np.random.default_rng(3), runs=1)
    prob = CampaignProblem(obs, DisturbanceModel.from_scenario(sc), catalogue_candidates(["time_tag"]))
    st = State(prob, np.zeros(3), {}, ["time_tag"])
    C, s = st.cl.candidates["time_tag"], st.cl.scales["time_tag"]
    ext = extend(st.base, C, rho_max=1 - 1e-9)
    raw = r.raw_information(c)[3, 3]
    assert float(st.cl.lin.raw_gram(C)[0, 0] / s[0] ** 2) == pytest.approx(raw, rel=0.02)
    sep_planner = 1 - r.scores.canonical_rho[c, 0] ** 2
    sep_diag = 1 - ext.rho[0] ** 2
    assert sep_diag == pytest.approx(sep_planner, rel=0.05)


def test_drowning_the_separating_pass_in_nadir_passes_is_not_nameable(small_result):
    """A campaign's separable information never falls when passes are added, but the diagnosis'
    canonical correlation does: the planner predicts where the diagnosis stops testing."""
    r = small_result
    s = r.scores
    assert s.name_ratio is not None and np.all((s.name_ratio >= s.detect_ratio_joint * (1 - 1e-9)) | ~np.isfinite(s.name_ratio))
    notsep = s.canonical_rho[:, 0] > r.rule.rho_max
    assert notsep.any() and np.all(np.isinf(s.name_ratio[notsep, 0])) and np.all(s.name_probability[notsep, 0] == 0)
    assert not r.feasible[notsep].any()


def test_fit_estimate_agrees_with_linear_gls():
    """The Monte Carlo checks' two fits: ``fit="estimate"`` (``boresight.estimate(effects=...)``,
    iterated on the exact model) and ``fit="linear"`` (``linear_gls``, one step from 0) give the
    same θ̂ and effect to the linearisation error (O(|θ|²) ≈ 0.01″ at |θ| = 50″; θ = 20, −15, 40″
    here) and the same covariance to the change of linearisation point (1 %)."""
    from boresight.studies.planning.checks import _fit, _simulate

    d = _doc(
        search=TWO_PASS_SEARCH,
        requirements={"sigma_theta_arcsec": [6.0, 6.0, 6.0], "effects": {"time_tag": 0.05}},
    )
    r = plan(plan_from_dict(d, source="fit.toml"))
    att = np.array([o.attitude for o in r.options])
    c = int(next(k for k in np.argsort(r.theta_ratio) if "site_tracking" in att[r.candidates[k][r.candidates[k] >= 0]]))
    obs, model = _simulate(r.scenario_document(c, effects={"time_tag": [0.03]}), runs=4, seed=5)
    th_l, x_l, cov_l, lab_l = _fit(obs, model, ("time_tag",), "linear")
    th_e, x_e, cov_e, lab_e = _fit(obs, model, ("time_tag",), "estimate")
    assert tuple(lab_l) == tuple(lab_e)
    assert np.allclose(th_l, th_e, atol=0.05), th_l - th_e
    sig_l, sig_e = np.sqrt(np.diagonal(cov_l, axis1=1, axis2=2)), np.sqrt(np.diagonal(cov_e, axis1=1, axis2=2))
    assert np.allclose(x_l[:, 3], x_e[:, 3], atol=0.05 * sig_e[:, 3])
    assert np.allclose(sig_l, sig_e, rtol=0.01)
    # and both differ from the truth by their σ, not by a bias: the hidden 30 ms is recovered
    assert np.all(np.abs(x_e[:, 3] - 0.03) < 4 * sig_e[:, 3])


def test_lookalike_update_equals_the_full_inverse(small_result):
    """ρ with a look-alike floated, from the block update of the base covariance, equals the one
    from inverting the whole (θ + required + look-alike) information."""
    from boresight.studies.planning.fisher import _rho, covariance_batch

    r = small_result
    info = np.stack([r.information(int(c)) for c in range(0, r.candidates.shape[0], 7)])
    nb = 3 + sum(sl.stop - sl.start for sl in r.effect_slices)
    for k, sl in enumerate(r.lookalike_slices):
        idx = np.r_[0:nb, sl.start : sl.stop]
        cov_f, sing = covariance_batch(info[:, idx[:, None], idx[None, :]])
        want = _rho(cov_f, r.effect_slices, r.required, r.lam_star)
        got = r.scores.lookalike_ratio[::7, :, k]
        ok = (want < 1e3) & ~sing[:, None]
        assert ok.sum() > 10
        assert np.allclose(got[ok], want[ok], rtol=1e-6)
        assert np.all(got[want >= 1e4] >= 1e3)


def test_pruned_search_equals_scoring_every_candidate(small_pruned):
    """The search scores in full (look-alikes, naming) only candidates its bounds do not rule out
    (``search.pruned_scores``); the front, the choice and every full score equal those of scoring
    all candidates, and the lower bound of the requirement ratio holds everywhere."""
    from boresight.studies.planning import search
    from boresight.studies.planning.fisher import NOT_SEPARABLE_RATIO, bound_scores

    r = small_pruned
    full = r.score_every_candidate()
    tr = np.max(full.sigma_theta_arcsec / np.asarray(r.spec.sigma_theta_arcsec), axis=-1)
    worst = full.name_ratio.max(axis=-1)
    feasible = (tr <= 1) & (worst <= 1)
    assert np.array_equal(search.pareto_front(full.cost, tr, np.minimum(worst, NOT_SEPARABLE_RATIO)), r.front)
    assert search.choose(full, feasible, tr, worst) == r.chosen
    assert np.array_equal(feasible, r.feasible)
    done = ~np.isnan(r.scores.name_ratio[:, 0])
    np.testing.assert_allclose(r.scores.name_ratio[done], full.name_ratio[done], rtol=1e-12)
    np.testing.assert_allclose(r.scores.sigma_theta_arcsec, full.sigma_theta_arcsec, rtol=1e-12)
    *_, lower = bound_scores(
        r.blocks, r.candidates, r.effect_slices, r.required, r.lam_star, option_rows=r.option_rows, rule=r.rule
    )
    assert np.all(lower <= full.name_ratio)
    assert r.timings_s["scored_in_full"] == done.sum() < r.candidates.shape[0]  # the pruning bites here too


def test_tail_tables_do_not_depend_on_the_batch_and_match_scipy():
    """``naming.NcxSf``: a critical value's probabilities are the same alone or in any batch (the
    search's lower bound of η relies on it), within 3e-4 of ``scipy.stats.ncx2`` (interpolated in
    crit) and exact at the ``exact`` value; ``inverse`` is its crossing to 1e-9 relative."""
    from boresight.studies.planning.naming import NcxSf

    crit = np.array([34.61, 36.02, 21.64, 40.3, 34.61])
    lam = np.array([30.0, 55.0, 21.0, 70.0, 12.0])
    batch = NcxSf(6, crit, exact=21.64)(lam)
    alone = np.array([NcxSf(6, [c], exact=21.64)(np.array([x]))[0] for c, x in zip(crit, lam)])
    np.testing.assert_array_equal(batch, alone)
    true = stats.ncx2.sf(crit, 6, lam)
    assert np.max(np.abs(batch - true)) < 3e-4
    assert abs(batch[2] - true[2]) < 1e-6  # the exact table (interpolated in λ only)
    t = NcxSf(6, crit, exact=21.64)
    inv = t.inverse(0.95)
    assert np.all(t(inv) >= 0.95) and np.all(t(inv * (1 - 1e-9)) < 0.95)


def test_shipped_plan_chooses_the_documented_campaign():
    """``plans/kiev680.toml`` as shipped: the chosen campaign (candidate 62671, docs/planning.md's
    worked example) and its 89-campaign front (90 while the one-pass campaigns that determine
    neither θ nor the effects carried ridge digits — σθ 3·10⁵″, ρ 2·10⁶ — that ordered them; as
    ``inf`` they tie, and the cheapest stands for them); the pruned search scores a fraction in full
    (``benchmarks/bench_plan.py --mode shipped --exhaustive`` checks the front and choice equal to
    scoring all 74 612)."""
    r = plan("plans/kiev680.toml")
    assert r.chosen == 62671 and r.front.size == 89
    assert r.describe(r.chosen).count("Nairobi") == 5
    assert r.timings_s["scored_in_full"] < 0.1 * r.candidates.shape[0]
    done = ~np.isnan(r.scores.name_ratio[:, 0])
    assert np.all(np.isin(r.front, np.flatnonzero(done)))


def test_spot_check_results_report_themselves():
    """The three spot-check results share one ``as_dict`` and the hidden-effect wording (the Monte
    Carlo runs behind them are slow tests; their reporting is checked here)."""
    from boresight.studies.planning.checks import DetectionCheck, NamingCheck

    d = DetectionCheck("thermal", (1.0, 2.0), 40, 29, 0.725, (0.56, 0.85), 0.8, 0.001, ("thermal",))
    n = NamingCheck("focal_scale", (1e-4,), 40, 30, 1, 2, 3, (0.6, 0.9), 0.8)
    assert d.as_dict()["detected"] == 29 and list(d.as_dict())[:3] == ["effect", "size", "runs"]
    assert d.text().startswith("thermal hidden at [1.0, 2.0]: detected in 29/40 runs")
    assert n.as_dict()["other_named"] == 3
    assert n.text().startswith("focal_scale hidden at [0.0001]: named by boresight.diagnose in 30/40 seeds")


def test_the_planner_separates_a_catalogue_datum_shift(tmp_path):
    """Issue 30: ``landmark_datum_shift`` is planned like every catalogue effect. The Kiev plan
    asked to name an 80 m east datum shift (thermal, gnss_bias and landmark_height_bias among the
    look-alikes) chooses passes in both directions — a ground offset turns the image one way from
    an ascending pass and the other from a descending one, which is what separates it — and names
    it with the required power."""
    import json

    from boresight.cli.main import main

    text = (ROOT / "plans/kiev680.toml").read_text()
    i, j = text.index("[requirements.effects]"), text.index("[cost]")
    text = text[:i] + "[requirements.effects]\nlandmark_datum_shift = { east_m = 80.0 }\n\n" + text[j:]
    text = text.replace("max_candidates = 200000", "max_candidates = 3000").replace("passes = [1, 6]", "passes = [1, 4]")
    p = tmp_path / "datum.toml"
    p.write_text(text)
    assert main(["plan", str(p), "--out", str(tmp_path / "o"), "--no-plot"]) == 0
    chosen = json.loads((tmp_path / "o" / "plan.json").read_text())["chosen"]
    dirs = {s.split()[1] for s in chosen["passes"]}
    assert dirs == {"asc", "des"}, chosen["passes"]
    assert chosen["p_name"]["landmark_datum_shift"] >= 0.95
