"""Monte Carlo spot checks of the planner's predictions (simulate + estimate, the real pipeline).

* ``sigma_check``: simulate the campaign's scenario ``runs`` times, estimate θ by GLS with the
  scenario's noise model (the required effects floated when ``floated`` is given, through
  ``boresight.estimate(..., effects=[...])``), and compare the sample σ of θ̂ − θ per axis with the
  predicted σθ. The sample variance of n Gaussian errors is σ² χ²(n−1)/(n−1), so the 95 %
  interval of σ is s·√((n−1)/χ²_{0.975}) … s·√((n−1)/χ²_{0.025}); the prediction agrees when
  it lies inside.
* ``detection_check``: hide an effect at a given size (the scenario's ``[effects]`` table),
  fit with the required effects floated, and count how often the Wald (= likelihood-ratio, in
  the linear Gaussian model) statistic of that effect exceeds the χ²(k) critical value at the
  plan's level α/K; the rate is compared with the stated power by its binomial (Clopper–Pearson)
  interval.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from boresight.errors import InputValueError
from boresight.stats import binomial_interval, sigma_interval
from orbits.rotations import ARCSEC

__all__ = [
    "SigmaCheck",
    "DetectionCheck",
    "NamingCheck",
    "sigma_check",
    "detection_check",
    "naming_check",
    "predicted_naming_probability",
]


class _Check:
    """A spot check's result: ``as_dict`` for the JSON report, ``text`` for the terminal."""

    def as_dict(self) -> dict:
        return asdict(self)  # type: ignore[call-overload]  # every subclass is a dataclass


@dataclass(frozen=True)
class _HiddenEffect(_Check):
    """A check of ``effect`` hidden at ``size`` (its units) over ``runs`` simulations."""

    effect: str
    size: tuple
    runs: int

    def _hidden(self) -> str:
        return f"{self.effect} hidden at {np.round(np.asarray(self.size, dtype=float), 6).tolist()}"


@dataclass(frozen=True)
class SigmaCheck(_Check):
    runs: int
    predicted_arcsec: tuple
    sample_sigma_arcsec: tuple
    interval_low_arcsec: tuple
    interval_high_arcsec: tuple
    mean_error_arcsec: tuple
    floated: tuple
    agrees: bool

    def text(self) -> str:
        fl = f"effects {list(self.floated)} floated" if self.floated else "no effect floated"
        return (
            f"σθ by Monte Carlo ({self.runs} runs, GLS, {fl}): "
            + ", ".join(
                f"{a} {s:.3g}″ (95 % CI {lo:.3g}–{hi:.3g}; predicted {p:.3g})"
                for a, s, lo, hi, p in zip(
                    "xyz", self.sample_sigma_arcsec, self.interval_low_arcsec, self.interval_high_arcsec, self.predicted_arcsec
                )
            )
            + (" — agrees" if self.agrees else " — DISAGREES")
        )


@dataclass(frozen=True)
class DetectionCheck(_HiddenEffect):
    detected: int
    rate: float
    interval: tuple
    expected: float
    level: float
    floated: tuple

    def text(self) -> str:
        return (
            f"{self._hidden()}: detected in {self.detected}/{self.runs} runs "
            f"({self.rate:.2f}, 95 % CI {self.interval[0]:.2f}–{self.interval[1]:.2f}; predicted power {self.expected:.2f}; "
            f"Wald test at level {self.level:.3g}, floated {list(self.floated)})"
        )


def _simulate(doc, runs, seed):
    from boresight.core.disturbances import DisturbanceModel
    from boresight.observations.simulate import simulate
    from orbits.scenario import scenario_from_dict

    sc = scenario_from_dict(doc, source=f"<plan check {doc.get('name')}>")
    obs = simulate(sc, np.random.default_rng(np.random.SeedSequence(seed)), runs=runs)
    return obs, DisturbanceModel.from_scenario(sc)


def _fit(obs, model, floated, fit):
    """(θ̂ (R, 3) arcsec, values (R, P) of [θ, floated effects], covariance (R, P, P), labels)."""
    if fit == "linear":
        from boresight.studies.planning.fisher import linear_gls

        with _one_thread():
            x, cov, labels = linear_gls(obs, model, list(floated))
        return x[:, :3], x, cov, labels
    from boresight.core.estimation import estimate

    if floated:
        est = estimate(obs, weighting="gls", model=model, effects=list(floated))
        labels = ("theta_x", "theta_y", "theta_z") + tuple(est.joint_labels[3:])
        cov = np.asarray(est.joint_covariance, float).reshape((obs.runs,) + (len(labels),) * 2)
        th = np.atleast_2d(est.theta.to_value("arcsec"))
        vals = np.concatenate(
            [th] + [np.atleast_2d(np.asarray(est.effects[n][0].value, float)).reshape(obs.runs, -1) for n in floated], axis=1
        )
        return th, vals, cov, labels
    est = estimate(obs, weighting="gls", model=model, effects=[])  # the planner's σθ: no effect floated (not estimate's default)
    th = np.atleast_2d(est.theta.to_value("arcsec"))
    return th, th, np.asarray(est.covariance.value).reshape(obs.runs, 3, 3), ("theta_x", "theta_y", "theta_z")


def _one_thread():
    from boresight.studies.planning import single_thread_blas

    return single_thread_blas()


def sigma_check(result, c: int, runs: int = 200, seed: int = 1, floated=None, chunk: int = 50, fit: str = "linear") -> SigmaCheck:
    """Monte Carlo σθ of candidate c vs the prediction (``floated``: default none; pass
    ``result.spec.effect_names`` to float the required effects). ``fit``: ``"linear"``
    (``fisher.linear_gls``: the GLS of ``boresight.estimate`` linearised once about 0, fast) or
    ``"estimate"`` (``boresight.estimate`` itself, iterated)."""
    floated = tuple(floated or ())
    doc = result.scenario_document(c)
    errs = []
    for k, a in enumerate(range(0, runs, chunk)):
        obs, model = _simulate(doc, min(chunk, runs - a), seed * 1000 + k)
        th, _, _, _ = _fit(obs, model, floated, fit)
        errs.append(th - obs.truth["theta_rad"] / ARCSEC)
    e = np.concatenate(errs)
    s = e.std(axis=0, ddof=1)
    lo, hi = sigma_interval(s, e.shape[0], 0.95)
    pred = result.scores.sigma_theta_arcsec[c] if floated else result.scores.sigma_theta_only_arcsec[c]
    return SigmaCheck(
        runs=e.shape[0],
        predicted_arcsec=tuple(map(float, pred)),
        sample_sigma_arcsec=tuple(map(float, s)),
        interval_low_arcsec=tuple(map(float, lo)),
        interval_high_arcsec=tuple(map(float, hi)),
        mean_error_arcsec=tuple(map(float, e.mean(axis=0))),
        floated=floated,
        agrees=bool(np.all((pred >= lo) & (pred <= hi))),
    )


def detection_check(
    result, c: int, effect: str, size=None, runs: int = 40, seed: int = 1, floated=None, chunk: int = 20, fit: str = "linear"
) -> DetectionCheck:
    """Hide ``effect`` at ``size`` (default: the predicted minimum detectable size) in candidate
    c and count detections by the Wald test at the plan's level α/K."""
    spec = result.spec
    if floated is None:
        from boresight.studies.planning.report import why

        binding = why(result, c)["effects"][effect]["binding_lookalike"]
        floated = tuple(spec.effect_names) + ((binding,) if binding else ())
    floated = tuple(floated)
    scanned = [n for n in floated if n in spec.scanned_rivals]
    if scanned:  # its columns need a boundary (fisher.step_terms); the fits here take catalogue columns only
        raise InputValueError(
            f"detection_check: {scanned[0]!r} (a scanned boundary) cannot be floated in the check's fit; "
            f"pass floated= without it (floated = {list(floated)})"
        )
    if effect not in floated:
        raise InputValueError(f"detection_check: {effect!r} must be among the floated effects {list(floated)}")
    size = np.asarray(result.detectable_size(c, effect) if size is None else size, float)
    doc = result.scenario_document(c, effects={effect: size})
    level = spec.alpha / spec.n_candidates
    k = size.size
    crit = stats.chi2.isf(level, k)
    hits = 0
    n = 0
    for j, a in enumerate(range(0, runs, chunk)):
        obs, model = _simulate(doc, min(chunk, runs - a), seed * 1000 + j)
        _, value, cov, labels = _fit(obs, model, floated, fit)
        cols = [i for i, lab in enumerate(labels) if lab.split(".")[0] == effect]
        for r in range(value.shape[0]):
            P = cov[r][np.ix_(cols, cols)]
            v = value[r, cols]
            w = float(v @ np.linalg.solve(P, v))
            hits += w > crit
            n += 1
    expected = float(stats.ncx2.sf(crit, k, predicted_noncentrality(result, c, effect, size, floated)))
    lo, hi = binomial_interval(hits, n)
    return DetectionCheck(
        effect=effect,
        size=tuple(map(float, size)),
        runs=n,
        detected=int(hits),
        rate=hits / n,
        interval=(lo, hi),
        expected=expected,
        level=level,
        floated=floated,
    )


def predicted_noncentrality(result, c: int, effect: str, size, floated) -> float:
    """λ = pᵀ (P_ee)⁻¹ p of ``effect`` at ``size`` in the model θ + ``floated`` (from the plan's
    information of candidate c; every floated effect must be among its required effects or
    look-alikes)."""
    from boresight.studies.planning.fisher import covariance_batch

    labels = [lab.split(".")[0] for lab in result.labels]
    idx = [0, 1, 2] + [i for n in floated for i, lab in enumerate(labels) if lab == n]
    info = result.information(c)[np.ix_(idx, idx)]
    cov, _ = covariance_batch(info[None])
    sub = [k for k, i in enumerate(idx) if labels[i] == effect]
    P = cov[0][np.ix_(sub, sub)]
    p = np.asarray(size, float)
    return float(p @ np.linalg.solve(P, p))


@dataclass(frozen=True)
class NamingCheck(_HiddenEffect):
    """How often ``boresight.diagnose`` names ``effect`` hidden at ``size`` (one run per seed)."""

    named: int
    ambiguous: int
    not_separable: int
    other_named: int
    interval: tuple
    predicted: float

    def text(self) -> str:
        return (
            f"{self._hidden()}: named by boresight.diagnose in {self.named}/{self.runs} seeds "
            f"(95 % CI {self.interval[0]:.2f}–{self.interval[1]:.2f}; predicted {self.predicted:.3f}); "
            f"ambiguous {self.ambiguous}, not separable {self.not_separable}, something else named {self.other_named}"
        )


def predicted_naming_probability(result, c: int, effect: str, size=None) -> float:
    """The planner's P_name (``naming``) of ``effect`` hidden at ``size`` (default: required) in candidate c."""
    from boresight.studies.planning.fisher import covariance_batch, effect_lambda, naming_with_step

    j = result.spec.effect_names.index(effect)
    required = [np.asarray(p, float) for p in result.required]
    if size is not None:
        required[j] = np.asarray(size, float).reshape(required[j].shape)
    info = result.information(c)[None]
    nb = 3 + sum(sl.stop - sl.start for sl in result.effect_slices)
    cov, _ = covariance_batch(info[..., :nb, :nb])
    lam = effect_lambda(cov, result.effect_slices, required)
    slices = list(result.effect_slices) + list(result.lookalike_slices)
    _, pname, _, _ = naming_with_step(
        info,
        result.raw_information(c)[None],
        np.array([float(result.n_rows(c))]),
        result.effect_slices,
        required,
        lam,
        slices,
        result.rule,
        result.step_terms(result.candidates[c : c + 1]),
    )
    return float(pname[0, j])


def naming_check(result, c: int, effect: str, size=None, seeds=range(40), salt: int = 12, **diagnose_kw) -> NamingCheck:
    """Simulate candidate c with ``effect`` hidden at ``size`` (default: its required size), one run
    per seed (``SeedSequence([seed, salt])``), run ``boresight.diagnose`` with the scenario's noise
    model, and count how often it names the effect; with the planner's predicted probability."""
    import boresight
    from boresight.core.disturbances import DisturbanceModel
    from boresight.observations.simulate import simulate
    from orbits.scenario import scenario_from_dict

    j = result.spec.effect_names.index(effect)
    size = np.asarray(result.required[j] if size is None else size, float)
    sc = scenario_from_dict(result.scenario_document(c, effects={effect: size.tolist()}), source=f"<naming check {effect}>")
    model = DisturbanceModel.from_scenario(sc)
    named = amb = ns = other = 0
    seeds = list(seeds)
    for seed in seeds:
        obs = simulate(sc, np.random.default_rng(np.random.SeedSequence([seed, salt])), runs=1)
        d = boresight.diagnose(obs, model, **diagnose_kw)
        named += effect in d.named
        amb += any(effect in a["effects"] for a in d.ambiguous)
        ns += effect in [n["effect"] for n in d.not_separable]
        other += any(n != effect for n in d.named)
    lo, hi = binomial_interval(named, len(seeds))
    return NamingCheck(
        effect=effect,
        size=tuple(map(float, size)),
        runs=len(seeds),
        named=int(named),
        ambiguous=int(amb),
        not_separable=int(ns),
        other_named=int(other),
        interval=(lo, hi),
        predicted=predicted_naming_probability(result, c, effect, size),
    )
