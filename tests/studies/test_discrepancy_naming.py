"""Issue 20: one naming rule (LR at α/K and BIC) for diagnose's verdicts, its minimum detectable
sizes and the planner; a significant candidate that is not decisive is reported by name; the
summary states what the data could not have detected.

The default run checks single seeds; ``-m slow`` measures rates (docs/discrepancy.md).
"""

import numpy as np
import pytest
from builders import discrepancy_campaign as campaign
from paths import ROOT
from scipy import stats

from boresight import simulate
from boresight.core.disturbances import DisturbanceModel
from boresight.studies.discrepancy import diagnose, rule

pytest.importorskip("boresight.core.effect_model")


def test_nameable_noncentrality_has_the_stated_power_under_both_legs():
    """χ²(k, λ*) draws pass max(χ²_{1−level}(k), k ln n) at the stated power: 20 000 draws, the
    rate within 4 binomial σ (σ = √(0.8·0.2/20 000) = 0.0028) of 0.8, for a case where BIC binds
    (k = 6, n = 880) and one where the LR leg binds (k = 1, n = 50)."""
    rng = np.random.default_rng(20)
    for k, level, n in ((6, 0.01 / 6, 880), (1, 0.01 / 6, 50)):
        lam = rule.nameable_noncentrality(k, level, n, 0.8)
        crit = rule.critical_value(k, level, n)
        x = stats.ncx2.rvs(k, lam, size=20000, random_state=rng)
        assert abs(np.mean(x > crit) - 0.8) < 4 * np.sqrt(0.16 / 20000), (k, lam, crit)
    # BIC binds for the six-parameter effect: its nameable λ exceeds the LR-only one by > 50 %
    from boresight.stats import minimum_detectable_noncentrality

    assert rule.nameable_noncentrality(6, 0.01 / 6, 880, 0.8) > 1.5 * minimum_detectable_noncentrality(6, 0.01 / 6, 0.8)
    assert rule.nameable_noncentrality(1, 0.01 / 6, 50, 0.8) == pytest.approx(minimum_detectable_noncentrality(1, 0.01 / 6, 0.8))


def test_planner_uses_the_diagnosis_rule():
    """One rule: the planner's NamingRule is the diagnosis' and its threshold is ``rule.critical_value``."""
    from boresight.studies.planning import naming

    assert naming.NamingRule is rule.NamingRule
    r = rule.NamingRule.from_diagnose(0.01 / 7, 0.01, 0.8)
    n = np.array([50.0, 880.0, 1e5])
    assert np.array_equal(r.critical_value(6, n), rule.critical_value(6, 0.01 / 7, n))
    from boresight.studies.discrepancy import naming as naming_step

    assert naming_step.AMBIGUITY_DLOGL == rule.AMBIGUITY_DLOGL == r.dlogl


def test_more_data_factor():
    """k + f λ̂ = k ln(f n) at the returned f; 1 when already decisive; inf with no signal."""
    f = rule.more_data_factor(30.0, 6, 400)
    assert f > 1 and np.isclose(6 + f * 24.0, 6 * np.log(f * 400), rtol=1e-6)
    assert rule.more_data_factor(60.0, 6, 400) == 1.0
    assert rule.more_data_factor(5.0, 6, 400) == np.inf


#: thermal sin_x at about its reported minimum detectable size on the catalogue test campaign (10.9″)
THERMAL_AT_MDE = {"sin_x_arcsec": 10.9}


def test_significant_but_not_decisive_is_reported_by_name(tmp_path):
    """Seed 1000: thermal at its reported size passes the LR test (p = 4e-4) but not BIC
    (Δχ² 24.5 ≤ 6 ln 880 = 40.7). The verdict names it as such, with the data that would decide,
    in the summary, diagnosis.md and diagnosis.json — never "no candidate explains"; θ is quoted
    with thermal floated (its σ covers it) and lies within 3σ of the truth."""
    from boresight.studies.discrepancy.report import write_report

    sc = campaign({"thermal": THERMAL_AT_MDE})
    obs = simulate(sc, np.random.default_rng(1000))
    d = diagnose(obs, DisturbanceModel.from_scenario(sc))
    assert d.named == [] and [n["effect"] for n in d.not_decisive] == ["thermal"], d.summary()
    nd = d.not_decisive[0]
    assert nd["p_value"] <= 0.01 / 6 and nd["statistic"] <= nd["bic_threshold"] == pytest.approx(6 * np.log(880))
    assert 1 < nd["more_data_factor"] < 10
    text = d.summary()
    assert "thermal: significant, p = 0.00043, not decisive by BIC" in text and "more data would name it" in text
    assert "no candidate explains" not in text
    assert d.details["final_state"].named.keys() == {"thermal"}  # floated, unnamed
    th = obs.truth["theta_rad"][0] / (np.pi / 180 / 3600)
    assert np.all(np.abs(np.array(d.theta_arcsec) - th) < 3 * np.array(d.theta_sigma_arcsec))
    paths = write_report(d, tmp_path, plots=False)
    assert "## Significant but not decisive" in paths["md"].read_text()
    import json

    js = json.loads(paths["json"].read_text())
    assert js["not_decisive"][0]["effect"] == "thermal" and js["version"] == "1.5"


def test_one_image_file_states_what_it_could_not_detect(tmp_path, capsys):
    """A one-image file: the terminal says which catalogue effects it could not have detected and
    at what size (radial distortion below 0.41 against a typical 0.01 here)."""
    from boresight.cli.main import main
    from orbits.scenario import load_scenario

    root = ROOT
    sc = load_scenario(root / "scenarios/diagnose-example.toml")
    obs = simulate(sc, np.random.default_rng(0)).images([0])
    f = tmp_path / "one.ecsv"
    obs.write(f)
    assert main(["diagnose", str(f), "--out", str(tmp_path / "d"), "--no-plots", "--sigma-pixel-m", "3e-6"]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith("low power")]
    assert any("could not detect radial_distortion below" in line and "(typical 0.01)" in line for line in lines), out
    v = float(next(line for line in lines if "radial_distortion" in line).split("below ")[1].split()[0].rstrip(","))
    assert v > 0.01


def _thermal_sizes():
    """thermal's identifiability entry on the catalogue test campaign (seed 1, nothing hidden) and the
    model of the diagnosis there."""
    sc0 = campaign()
    model = DisturbanceModel.from_scenario(sc0)
    d0 = diagnose(simulate(sc0, np.random.default_rng(1)), model)
    return next(e for e in d0.identifiability if e["effect"] == "thermal"), model


def _outcome(d) -> str:
    return "named" if d.named == ["thermal"] else "not_decisive" if d.not_decisive else "ambiguous" if d.ambiguous else "other"


@pytest.mark.slow
def test_thermal_at_its_reported_size_is_named_at_the_stated_power():
    """40 seeds with thermal sin_x at 1× and 0.5× the minimum *nameable* size diagnose reports on this
    campaign (``min_nameable``, power 0.8: named — detected and not ambiguous with a look-alike —
    with probability 0.8, by the naming model ``naming_power``; 11.7″ here, landmark_datum_shift
    binding). Named alone at 1×: ≥ 25 of 40, the binomial lower 99.7 % bound of 0.8 (P(X ≤ 24 | 0.8)
    = 0.003; a true rate of 0.4 — half the stated one — passes with probability 0.003, and a size
    quoted at half the true one names ~1 % at 0.5×). At 0.5× rarely: ≤ 6 (the model predicts
    P ≈ 0.01; P(X ≥ 7 | 0.05) = 0.003). Before ``min_nameable`` the reported size was the detection
    size (10.9″), at which thermal was named 24 of 40 (6 ambiguous with landmark_datum_shift): the
    model predicts 0.64 there. Rates in docs/discrepancy.md."""
    th, model = _thermal_sizes()
    size = th["min_nameable"][0]
    assert th["nameable_rival"][0] == "landmark_datum_shift" and size > th["min_detectable"][0]
    counts = {}
    for mult in (1.0, 0.5):
        sc = campaign({"thermal": {"sin_x_arcsec": mult * size}})
        c = {"named": 0, "not_decisive": 0, "ambiguous": 0, "other": 0}
        for seed in range(2000, 2040):
            c[_outcome(diagnose(simulate(sc, np.random.default_rng(seed)), model))] += 1
        counts[mult] = c
    print("thermal at the reported nameable size", round(size, 2), counts)
    assert counts[1.0]["named"] >= 25 and counts[0.5]["named"] <= 6


@pytest.mark.slow
def test_thermal_at_its_reported_detectable_size_is_detected_at_the_stated_power():
    """40 seeds with thermal sin_x at the minimum *detectable* size diagnose reports (``min_detectable``,
    10.9″): the size at which the rule's two legs — LR at α/K and BIC — pass with power 0.8, whatever
    the naming then makes of it (named, or ambiguous with a look-alike). Counted from the first naming
    round: thermal's Δχ² above ``rule.critical_value(6, level, n)``, ≥ 25 of 40 (the same binomial
    bound as above)."""
    th, model = _thermal_sizes()
    size = th["min_detectable"][0]
    sc = campaign({"thermal": {"sin_x_arcsec": size}})
    passed, c = 0, {"named": 0, "not_decisive": 0, "ambiguous": 0, "other": 0}
    for seed in range(2000, 2040):
        obs = simulate(sc, np.random.default_rng(seed))
        d = diagnose(obs, model)
        c[_outcome(d)] += 1
        r1 = next(r for r in d.details["rounds"][0]["candidates"] if r["effect"] == "thermal")
        passed += r1["delta_chi2"] > rule.critical_value(6, th["level"], 2 * obs.n_observations)
    print("thermal at the reported detectable size", round(size, 2), "detected", passed, c)
    assert passed >= 25
