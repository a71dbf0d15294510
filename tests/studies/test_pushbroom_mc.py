"""Issue 29's statistical must-shows on ``scenarios/pushbroom-strip.toml`` (slow; run once, numbers in docs/pushbroom.md).

Run: ``python -m pytest -m slow -s -p no:cacheprovider tests/studies/test_pushbroom_mc.py`` (prints the figures).

* **Monte Carlo** (``N_MC`` = 2 000 runs, run k drawn from ``default_rng([SEED, k])``): θ by
  ``estimate_line_scan`` with the scenario's noise model (pixels, the tracker's white error per sample on the
  attitude-sample table). On every axis the mean reported σ is within 10 % of the scatter of θ̂ − θ, and at least
  98.5 % of runs are within 3σ. Tolerances: with 2 000 runs the scatter's standard deviation is known to
  1/√(2·2000) = 1.6 % (1σ), so a 10 % band fails an honest σ with probability ~1e-9 and catches a 15 % error
  with probability > 0.99; the 3σ rate of an honest σ is 99.73 % ± 0.12 % (binomial, 2 000 runs), 98.5 % is 10
  standard errors below it.
* **diagnose** (``diagnose_line_scan``, α = 0.01): a hidden 0.65 Hz jitter of 1 px (amplitude 1 px about the two
  cross-boresight camera axes) named in ≥ 36 of 40 seeds; a hidden chip offset (chip 1, 0.5 px along and across)
  named in ≥ 36 of 40; nothing named on clean data in ≥ 97 of 100. Each rate is printed with its 95 %
  Clopper–Pearson interval. The family-wise level 0.01 makes a false name on clean data a 1 % event (≤ 3 of 100 fails
  with probability 0.08 % at 1 %); the hidden effects' non-centralities (~130 for the jitter, ~350 for the chip)
  are far above their naming thresholds (~36 and ~13), so a miss is a < 1e-3 event per seed.
"""

import numpy as np
import pytest

from boresight.core.line_scan import estimate_line_scan
from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns
from boresight.stats import binomial_interval
from boresight.studies.discrepancy.line_scan import diagnose_line_scan
from orbits.effects import line_scan_truth
from orbits.strip import load_strip_scenario, simulate_strip

SEED = 20261127
N_MC = 2000
ARCSEC = np.pi / 180 / 3600
PIXEL_ARCSEC = 7e-6 / 1.7 / ARCSEC  # the ZY-3-like line's pixel, 0.849″

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def scenario():
    sc = load_strip_scenario("pushbroom-strip")
    sc.geometries()
    return sc


def _run(sc, truth, k, seed=SEED):
    (geo,) = sc.geometries()
    return strip_observations(
        simulate_strip(geo, truth, np.random.default_rng([seed, k]), sc.layout, sc.tracker, sc.sigma_pixel_px)
    )


def test_pushbroom_strip_montecarlo_sigma_is_honest(scenario):
    sc = scenario
    model, unknowns, truth = strip_noise_model(sc), strip_unknowns(sc), sc.truth()
    err, sig = np.empty((N_MC, 3)), np.empty((N_MC, 3))
    for k in range(N_MC):
        fit = estimate_line_scan(_run(sc, truth, k), unknowns, model)
        err[k], sig[k] = fit.x[:3] - truth.theta_rad, fit.sigma[:3]
    scatter = err.std(axis=0, ddof=1)
    reported = sig.mean(axis=0)
    within = np.mean(np.abs(err) <= 3 * sig, axis=0)
    print(f"\npushbroom-strip Monte Carlo, {N_MC} runs: scatter {scatter / ARCSEC} arcsec, mean reported σ {reported / ARCSEC}")
    print(f"  σ / scatter {reported / scatter}; within 3σ {within}")
    assert np.all(np.abs(reported / scatter - 1) <= 0.10)
    assert np.all(within >= 0.985)


CASES = {
    "jitter 0.65 Hz 1 px": (
        40,
        {
            "jitter": {
                "frequency_hz": 0.65,
                "amplitude_x_arcsec": PIXEL_ARCSEC,
                "amplitude_y_arcsec": PIXEL_ARCSEC,
                "phase_y_rad": 1.0,
            }
        },
        "jitter",
        36,
    ),
    "chip 1 offset 0.5 px": (
        40,
        {"chip_offset": {"chip": 1, "along_track_arcsec": 0.5 * PIXEL_ARCSEC, "across_track_arcsec": 0.5 * PIXEL_ARCSEC}},
        "chip_offset[1]",
        36,
    ),
    "clean": (100, {}, None, 97),
}


@pytest.mark.parametrize("case", list(CASES))
def test_pushbroom_diagnose_names_the_hidden_effect(scenario, case):
    n, effects, expect, need = CASES[case]
    sc = scenario
    model = strip_noise_model(sc)
    truth = line_scan_truth(sc.theta_rad, effects, sc.strips[0].sensor.n_chips)
    ok, named_other = 0, []
    for k in range(n):
        d = diagnose_line_scan(_run(sc, truth, k, seed=SEED + 1), model)
        good = d.named == ([expect] if expect else [])
        ok += good
        if not good:
            named_other.append((k, d.named))
    lo, hi = binomial_interval(ok, n)
    what = f"'{expect}' named alone" if expect else "nothing named"
    print(f"\ndiagnose {case}: {what} in {ok}/{n} (95 % Clopper–Pearson {lo:.3f}-{hi:.3f}); others: {named_other}")
    assert ok >= need
