"""One entry point for every estimator: ``boresight.estimate(observations, algorithm=…, weighting=…)``.

Least-squares algorithms (Kiev 2012 eqs 14-22, 29-31) are *linearisers*: functions
``linearize(obs, theta_rad) -> (G (R, N, M, 2, 3), q (R, N, M, 2))`` with q = measured −
predicted ≈ G (θ − θ0), plus a ``residual_map`` that says how image-plane errors reach q. They
share one Gauss-Newton loop and one accumulator (``NormalEquations``): each iteration
re-linearises about the last θ, so a 10′ initial error converges to the noise floor.

Weighting (default: ``"gls"`` when a noise model is known — ``model=`` or the observations' own,
``DisturbanceModel.from_observations`` — and ``"unit"`` otherwise; ``default_weighting``):

* ``"unit"`` — W = E (the slides' eqs 18, 22, 31). Covariance: the sandwich
  A (Gᵀ Σ G) A, A = (GᵀG)⁻¹, under ``model`` if given; else A·χ²/dof.
* ``"diagonal"`` — W = 1/diag(Σ): each residual weighted by its total variance under
  ``model`` (required); covariance by the sandwich with the full Σ.
* ``"gls"`` — generalised least squares under ``model`` (required), block-sparse
  (``boresight.core.campaign_gls``): pixel noise whitened per observation, per-image star-tracker/GNSS
  errors eliminated image by image, per-pass ones pass by pass, catalogue errors per connected group
  of landmarks — each by a QR factorisation with the error's prior. Its covariance is the inverse
  information, the Cramér–Rao bound (``boresight.core.crlb``) to first order.

Options common to the least-squares algorithms: ``loss=`` (robust IRLS), ``float=`` /
``extra_columns=`` (extra global parameters fitted jointly with θ), ``prior_sigma_arcsec`` (in
absolute terms under every weighting). ``Estimate.warnings``, ``converged``, ``sigma_includes`` and
``summary()`` say how far to trust the result (``docs/estimators.md``).

Other estimators (Algorithm 1, the Kalman filter) register themselves with
``register_algorithm(name, func)``; ``func(obs, *, weighting, iterate, model,
prior_sigma_arcsec, **options)`` returns an ``Estimate``.

Example
-------
>>> import numpy as np
>>> from boresight import simulate, estimate
>>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0))
>>> est = estimate(obs, algorithm="image_plane")
>>> np.round(est.theta.value, 6).tolist(), est.iterations
([20.0, -15.0, 40.0], 3)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from astropy import units as u

from orbits.rotations import ARCSEC

from boresight.core.disturbances import DisturbanceModel
from boresight.errors import ObservabilityError
from boresight.core.normal_equations import DEFAULT_MAX_CONDITION, NormalEquations

__all__ = ["Estimate", "estimate", "register_algorithm", "algorithms", "WEIGHTINGS"]

WEIGHTINGS = ("unit", "diagonal", "gls")
#: iterations when ``iterate=True``
MAX_ITERATIONS = 20
#: convergence: largest correction below this (rad) — 1e-6 arcsec
# DECISION: 1e-6″, a thousand times below the 0.001″ recovery requirement and ten times above
# the round-off floor (~1e-7″) of the GLS Schur complement with per-pass nuisances.
TOLERANCE_RAD = 1e-6 * ARCSEC
#: the narrowest prior σθ0 accepted (the convergence tolerance: a narrower prior cannot be resolved)
PRIOR_SIGMA_MIN_ARCSEC = 1e-6


@dataclass(frozen=True)
class Estimate:
    """The result of ``estimate``. The run axis is dropped when the input has one run.

    ``theta`` Quantity arcsec (R, 3) or (3,); ``covariance`` Quantity arcsec² (R, 3, 3) or (3, 3);
    ``residuals`` (R, N, M, 2) final residuals (measured − predicted) in ``residual_unit``,
    0 where masked; ``chi2`` the minimised weighted sum of squares (for ``unit`` weighting the
    plain sum of squares in ``residual_unit``²); ``dof`` degrees of freedom; ``condition_number``
    of the normal matrix of θ (prior included); ``iterations`` Gauss-Newton iterations;
    ``converged`` whether the last correction was below 1e-6″ (robust fits: 1e-3 σ and stable
    weights). ``warnings`` plain-language reasons not to trust the result (non-convergence, θ
    outside the small-angle range, χ²/dof inconsistent with the noise model, a dominant prior, no
    noise model); ``sigma_includes`` what σ contains; ``effects`` {name: (value, σ)} Quantities of
    floated effects; ``downweighted`` (image, landmark id, z, weight, why) of the robust fit's
    outlying observations (first run). ``extra`` holds ``chi2_model``/``dof_model`` (the noise-model
    statistic), ``normalised_residuals``, ``largest_residuals``, ``joint_covariance``/``joint_labels``/
    ``joint_units``, ``robust_weights``, ``truth_arcsec``.
    """

    theta: u.Quantity
    covariance: u.Quantity
    residuals: np.ndarray
    chi2: np.ndarray
    dof: np.ndarray
    condition_number: np.ndarray
    iterations: int
    converged: np.ndarray
    algorithm: str
    weighting: str
    residual_unit: str = ""
    extra: dict = field(default_factory=dict)
    warnings: tuple = ()
    sigma_includes: str = ""
    effects: dict = field(default_factory=dict)
    downweighted: tuple = ()

    @property
    def sigma(self) -> u.Quantity:
        """Standard deviations of θ (arcsec), (R, 3) or (3,)."""
        return np.sqrt(np.diagonal(self.covariance.to_value(u.arcsec**2), axis1=-2, axis2=-1)) * u.arcsec

    def __str__(self) -> str:
        return self.summary()

    def summary(self) -> str:
        """Human-readable lines (first run): θ ± σ and what σ includes, convergence, χ²/dof with its
        expected range, floated effects, the largest normalised residuals, the truth in σ, warnings."""
        th = np.atleast_2d(self.theta.to_value(u.arcsec))[0]
        sg = np.atleast_2d(self.sigma.to_value(u.arcsec))[0]
        chi2, dof, cond = (np.atleast_1d(v)[0] for v in (self.chi2, self.dof, self.condition_number))
        conv = bool(np.atleast_1d(self.converged)[0])
        lines = [f"algorithm     {self.algorithm} ({self.weighting} weighting), {self.iterations} iteration(s), "
                 + ("converged" if conv else "NOT converged")]
        for name, t, s in zip(("theta_x", "theta_y", "theta_z"), th, sg):
            lines.append(f"{name:<13} {t:+.4f} ± {s:.4f} arcsec")
        if self.sigma_includes:
            lines.append(f"sigma         {self.sigma_includes}")
        for name, (val, sig) in self.effects.items():
            v, e = np.atleast_1d(val.value), np.atleast_1d(sig.value)
            if v.ndim > 1:
                v, e = v[0], e[0]
            vals = ", ".join(f"{a:+.4g} ± {b:.2g}" for a, b in zip(v, e))
            lines.append(f"{name:<13} {vals} {val.unit}")
        c2m = self.extra.get("chi2_model")
        if c2m is not None:
            c2m, dofm = float(np.atleast_1d(c2m)[0]), int(np.atleast_1d(self.extra["dof_model"])[0])
            lo, hi = chi2_range(dofm)
            kept = self.extra.get("chi2_kept_observations")
            what = "" if kept is None else f" of the {int(np.atleast_1d(kept)[0])} observations kept (z ≤ {CHI2_INLIER_Z:.1f})"
            lines.append(f"chi2 / dof    {c2m / dofm:.3f} ({c2m:.4g} / {dofm}) under the noise model{what}; "
                         f"expected {lo:.3f}..{hi:.3f} ({CHI2_LEVEL:.1%})")
        else:
            lines.append(f"chi2 / dof    {chi2:.4g} / {int(dof)} (no noise model: no expected range)")
        lines.append(f"condition     {cond:.3g}")
        top = self.extra.get("largest_residuals") or ()
        if top:
            what = "pixel σ" if c2m is not None else "robust scatter"
            lines.append(f"largest normalised residuals ({what}): " + ", ".join(f"image {n} {lm} {z:.1f}" for n, lm, z in top))
        if self.downweighted:
            lines.append(f"down-weighted {len(self.downweighted)} observation(s) ({self.extra.get('loss')} loss), e.g. "
                         + "; ".join(f"image {d[0]} {d[1]}: {d[4]}" for d in self.downweighted[:3]))
        truth = self.extra.get("truth_arcsec")
        if truth is not None:
            t = np.atleast_2d(truth)[0]
            lines.append("truth         " + ", ".join(f"{a:+.4f}" for a in t) + " arcsec; error "
                         + ", ".join(f"{(e - a) / s:+.2f}" for a, e, s in zip(t, th, sg)) + " σ")
        for w in self.warnings:
            lines.append(f"warning       {w}")
        return "\n".join(lines)


#: the central probability of the χ²/dof range reported and checked
CHI2_LEVEL = 0.999
#: under a robust loss, observations with a pixel-level normalised residual length above this are
#: left out of the χ² check as outliers (a clean one: probability exp(−z²/2) = 1e-5)
CHI2_INLIER_Z = float(np.sqrt(-2.0 * np.log(1e-5)))


def chi2_range(dof, level: float = CHI2_LEVEL):
    """Central ``level`` range of χ²_dof / dof."""
    from scipy.stats import chi2

    a = 0.5 * (1 - level)
    return chi2.ppf(a, dof) / dof, chi2.ppf(1 - a, dof) / dof


@dataclass(frozen=True)
class _Spec:
    func: Callable
    kind: str  # "linearizer" | "estimator"
    residual_map: Callable | None = None
    residual_unit: str = ""


_REGISTRY: dict[str, _Spec] = {}
_ALIASES: dict[str, str] = {}


def register_algorithm(name: str, func: Callable, *, kind: str = "estimator", residual_map: Callable | None = None,
                       residual_unit: str = "", aliases: tuple = ()) -> None:
    """Make ``estimate(obs, algorithm=name)`` available.

    ``kind="estimator"``: ``func(obs, *, weighting, iterate, model, prior_sigma_arcsec,
    **options) -> Estimate`` does everything itself. ``kind="linearizer"``:
    ``func(obs, theta_rad) -> (G, q)`` joins the shared Gauss-Newton loop; give
    ``residual_map(obs, theta_rad) -> L (R, N, M, 2, 2)`` to allow weighted forms.
    Re-registering a name replaces it.

    >>> register_algorithm("demo", lambda obs, **kw: None, aliases=("d",))
    >>> "demo" in algorithms() and "d" in algorithms()
    True
    """
    if kind not in ("estimator", "linearizer"):
        raise ValueError(f"register_algorithm: kind must be 'estimator' or 'linearizer', got {kind!r}")
    if not callable(func):
        raise ValueError(f"register_algorithm: func for {name!r} is not callable")
    _REGISTRY[name] = _Spec(func, kind, residual_map, residual_unit)
    for a in aliases:
        _ALIASES[a] = name


def algorithms() -> list[str]:
    """Every algorithm name and alias ``estimate`` accepts: the built-in table
    (``boresight.core.registry``, complete without importing the algorithm modules) and any
    registered at run time with ``register_algorithm``."""
    from boresight.core import registry

    return sorted(set(registry.estimator_names()) | set(_REGISTRY) | set(_ALIASES))


def _builtin(name: str | None = None):
    """Register the built-in algorithm ``name`` (default: the linearizers) from ``boresight.core.registry``."""
    import importlib

    from boresight.core import registry

    rows = [registry.ALGORITHMS[name]] if name is not None else [registry.ALGORITHMS[n] for n in registry.names("linearizer")]
    for row in rows:
        module = importlib.import_module(row.module)
        register_algorithm(row.name, getattr(module, row.function), kind=row.kind,
                           residual_map=getattr(module, row.residual_map) if row.residual_map else None,
                           residual_unit=row.residual_unit, aliases=row.aliases)


_builtin()


def _lookup(algorithm):
    from boresight.core import registry

    name = _ALIASES.get(algorithm, algorithm)
    if name not in _REGISTRY:
        try:
            row = registry.lookup(algorithm)
        except registry.UnknownAlgorithmError:
            row = None
        if row is not None and row.kind == "study":
            raise registry.UnknownAlgorithmError(
                f"estimate: {algorithm!r} is a Monte Carlo study kernel ({row.summary}), not an estimator; "
                f"expected one of {algorithms()}"
            )
        if row is not None:
            _builtin(row.name)  # imports the estimator's module lazily
            name = row.name
        if name not in _REGISTRY:
            from orbits.errors import did_you_mean

            raise registry.UnknownAlgorithmError(f"estimate: unknown algorithm {algorithm!r}{did_you_mean(algorithm, algorithms())}; "
                                                 f"expected one of {algorithms()}")
    return name, _REGISTRY[name]


def _iterations(iterate):
    if iterate is True:
        return MAX_ITERATIONS
    if iterate is False or iterate is None:
        return 1
    if isinstance(iterate, (int, np.integer)) and iterate >= 1:
        return int(iterate)
    raise ValueError(f"estimate: iterate must be True, False or a positive integer, got {iterate!r}")


# DECISION: the Kalman filter is only meaningful with its full per-image noise model, so its
# default weighting is always "gls"; the least-squares algorithms default to "gls" when a noise
# model is known and to "unit" otherwise (``default_weighting``).
_DEFAULT_WEIGHTING = {"kalman": "gls"}


def default_weighting(observations, name: str, spec, weighting, model):
    """(weighting, model) ``estimate`` uses when the caller leaves them to it (issue 11: "the noise
    model travels in the file and is used by default").

    ``model=None`` with ``weighting`` None, ``"diagonal"`` or ``"gls"`` takes the observations' own
    noise model (``DisturbanceModel.from_observations``, the file's ``noise`` block), if any.
    ``weighting=None`` is then ``"gls"`` whenever a noise model is known (given or the file's) with
    σ_pixel > 0 and the algorithm can weight (a ``residual_map``; the Kalman filter always), else
    ``"unit"`` — the rule ``boresight estimate`` applies. An explicit ``weighting="unit"`` keeps
    ``model`` as given: the seminar's plain least squares, σ from the scatter unless ``model=``.
    """
    # DECISION: the file's model is taken for the weighted forms only; "unit" stays the slides'
    # eqs 18/22/31 exactly, with the warning that a carried noise model was not used. Algorithm 1
    # (and estimators registered at run time) take no model they were not given.
    weighted = spec.kind == "linearizer" or name in _DEFAULT_WEIGHTING
    if model is None and weighting != "unit" and weighted and getattr(observations, "noise", None) is not None:
        carried = DisturbanceModel.from_observations(observations)
        if weighting is not None or name in _DEFAULT_WEIGHTING or (spec.residual_map is not None and carried.sigma_pixel_m > 0):
            model = carried
    if weighting is None:
        if name in _DEFAULT_WEIGHTING:
            weighting = _DEFAULT_WEIGHTING[name]
        elif spec.kind == "linearizer" and spec.residual_map is not None and model is not None and model.sigma_pixel_m > 0:
            weighting = "gls"
        else:
            weighting = "unit"
    return weighting, model


#: robust losses: weight w(z) of an observation whose normalised residual vector has length z
#: (z = |e|/σ over its two components, e ~ N(0, σ² E₂) for a clean observation).
# DECISION: constants for the 2-D length z: Huber k = 2.45 = √χ²₂(0.95) (5 % of clean
# observations get a weight < 1); Cauchy c = 3.0 (a clean observation keeps w ≥ 0.64 at the
# 95th percentile); Tukey c = 4.9 (a clean observation is dropped with probability e^{−12}).
LOSSES = {"huber": 2.45, "cauchy": 3.0, "tukey": 4.9}
#: a robust fit iterates (reweights) at most this many times
MAX_ROBUST_ITERATIONS = 100
#: a robust fit has converged when θ moves by less than this fraction of its σ …
ROBUST_TOLERANCE_SIGMA = 1e-3
#: … and no observation's weight changes by more than this
ROBUST_WEIGHT_TOLERANCE = 1e-2
#: |θ| beyond which the estimate is flagged: ±3 σθ0 of the seminar's 10′ initial uncertainty.
# DECISION: the error models (first-order disturbance Jacobians at θ, the linearised covariance)
# and the seminar's framing assume a small misalignment; 0.5° = 1800″ is three times the Kiev
# 2012 initial uncertainty σθ0 = 10′. Beyond it θ is still computed exactly but flagged.
SMALL_ANGLE_LIMIT_ARCSEC = 1800.0
#: a prior "dominates" an axis when it carries more than this share of the posterior information
PRIOR_DOMINANCE = 0.5


def robust_weights(z, loss: str):
    """IRLS weights for normalised residual lengths ``z`` (array) under ``loss``."""
    c = LOSSES[loss]
    z = np.asarray(z, float)
    if loss == "huber":
        return np.where(z <= c, 1.0, c / np.maximum(z, 1e-300))
    if loss == "cauchy":
        return 1.0 / (1.0 + (z / c) ** 2)
    return np.where(z < c, (1.0 - (z / c) ** 2) ** 2, 0.0)


class _Extra:
    """Extra global parameters (floated effects or a user hook), scaled by a typical size."""

    def __init__(self, obs, names, hook):
        self.names = list(names or [])
        if hook is not None and self.names:
            raise ValueError("estimate: give float=[...] or extra_columns=..., not both")
        self.status = {}
        if self.names:
            from boresight.core import effect_model

            self._em = effect_model
            cols = effect_model.effect_columns(obs, np.zeros((obs.runs, 3)), self.names)  # unknown name → error
            self.status = dict(cols.status)
            # DECISION: an effect this data cannot evaluate (e.g. "needs velocity") is not fitted;
            # it is reported in the warnings and extra["effect_status"], never silently zero.
            self.names = [nm for nm in self.names if cols.status.get(nm) == "ok"]
            self._n = {nm: cols.slices[nm].stop - cols.slices[nm].start for nm in self.names}
            self.hook = self._effect_hook
            cols = effect_model.effect_columns(obs, np.zeros((obs.runs, 3)), self.names) if self.names else None
        else:
            self.hook = hook
            cols = hook(obs, np.zeros((obs.runs, 3)), None) if hook is not None else None
        if cols is None:
            self.K = 0
            return
        jac = np.asarray(cols.jacobian, float)
        self.K = jac.shape[-1]
        self.labels = tuple(str(v) for v in getattr(cols, "labels", [f"p{k}" for k in range(self.K)]))
        self.units = tuple(getattr(cols, "units", [u.one] * self.K))
        self.scales = np.asarray(getattr(cols, "scales", np.ones(self.K)), float).reshape(self.K)
        if not np.all(np.isfinite(self.scales) & (self.scales > 0)):
            raise ValueError(f"estimate: extra column scales must be finite and > 0, got {self.scales!r}")
        self.status.update(getattr(cols, "status", {}) or {})

    def _effect_hook(self, obs, theta, params):
        d = None
        if params is not None:
            d, k = {}, 0
            for name in self.names:
                d[name] = params[:, k : k + self._n[name]]
                k += self._n[name]
        return self._em.effect_columns(obs, theta, self.names, d)

    def groups(self):
        if self.names:
            k = 0
            for name in self.names:
                yield name, slice(k, k + self._n[name])
                k += self._n[name]
        else:
            for k, lab in enumerate(self.labels):
                yield lab, slice(k, k + 1)


def _robust_scale(q, valid):
    """1.4826 × median |component| over the valid residual components, per run (R,)."""
    a = np.where(valid, np.abs(q), np.nan).reshape(q.shape[0], -1)
    return 1.4826 * np.nanmedian(a, axis=1)


def estimate(observations, algorithm: str = "image_plane", weighting: str | None = None, iterate=True,
             model: DisturbanceModel | None = None, prior_sigma_arcsec=None, *, theta0_arcsec=None,
             max_condition: float = DEFAULT_MAX_CONDITION, loss: str | None = None, float=None,
             extra_columns: Callable | None = None, **options) -> Estimate:
    """Estimate the misalignment θ (Kiev 2012 eq 24 sign) from an ``ObservationSet``.

    Parameters
    ----------
    observations : ObservationSet (R runs, N images, M landmarks).
    algorithm : ``"image_plane"`` (alias ``"alg3"``, eqs 19-22), ``"ground_plane"`` (``"alg2"``,
        eqs 14-18), ``"unit_vector"`` (eqs 29-31), or a registered name (``"alg1"``, ``"kalman"``).
    weighting : ``"unit"``, ``"diagonal"`` or ``"gls"`` (the last two need a noise model: ``model``
        or the observations' own). Default (None): ``"gls"`` when a noise model is known — ``model``
        or, failing it, the one the observations carry (a format-1.1 file's ``noise`` block, a
        simulated set's scenario) — and the algorithm can weight; ``"unit"`` otherwise (σ then
        from the residual scatter, "scatter only", with a warning). Always ``"gls"`` for Kalman.
    iterate : True (re-linearise until the correction is < 1e-6″, at most 20 times), False (one
        linearisation about θ0), or the maximum number of iterations.
    model : ``DisturbanceModel`` for weights and covariance; None: the observations' own noise
        model (``DisturbanceModel.from_observations``) unless ``weighting="unit"``.
    prior_sigma_arcsec : σθ0, a prior θ ~ N(0, σθ0²) per axis (scalar or (3,)), in absolute terms
        under every weighting (``docs/estimators.md``, "The prior").
    theta0_arcsec : first linearisation point, (3,) or (R, 3); default 0.
    max_condition : refuse (``ObservabilityError``) a normal matrix worse conditioned than this.
    loss : None (least squares) or ``"huber"``, ``"cauchy"``, ``"tukey"``: iteratively reweighted
        least squares on each observation's normalised residual (pixel-level under the noise
        model, else scaled by a robust scale estimate); ``Estimate.downweighted`` lists them.
    float : names of effects (``boresight.core.effect_model.effect_names()``) fitted jointly with θ.
    extra_columns : a hook ``f(obs, theta_rad, params) -> EffectColumns``-like (offset, jacobian,
        labels, units, scales) of extra global parameters fitted jointly with θ.

    Returns an ``Estimate``; raises ``ObservabilityError`` when θ is not determined.
    """
    float_names = float
    name, spec = _lookup(algorithm)
    weighting, model = default_weighting(observations, name, spec, weighting, model)
    if weighting not in WEIGHTINGS:
        raise ValueError(f"estimate: weighting must be one of {WEIGHTINGS}, got {weighting!r}")
    if model is not None and not isinstance(model, DisturbanceModel):
        raise ValueError(f"estimate: model must be a boresight.DisturbanceModel or None, got {type(model).__name__}")
    if loss is not None and loss not in LOSSES:
        raise ValueError(f"estimate: loss must be None or one of {sorted(LOSSES)}, got {loss!r}")
    if isinstance(float_names, str):
        float_names = [n.strip() for n in float_names.split(",") if n.strip()]
    if spec.kind == "estimator":
        if loss is not None or float_names or extra_columns is not None:
            raise ValueError(f"estimate: algorithm {name!r} does not take loss=, float= or extra_columns= "
                             "(they are for the least-squares algorithms image_plane, ground_plane, unit_vector)")
        return spec.func(observations, weighting=weighting, iterate=iterate, model=model,
                         prior_sigma_arcsec=prior_sigma_arcsec, **options)
    if options:
        raise ValueError(f"estimate: algorithm {name!r} takes no options, got {sorted(options)}")
    if weighting != "unit" and model is None:
        raise ValueError(f"estimate: weighting={weighting!r} needs a disturbance model (model=DisturbanceModel(...))")
    if weighting != "unit" and spec.residual_map is None:
        raise ValueError(f"estimate: algorithm {name!r} has no residual_map, so only weighting='unit' is available")
    if model is not None and not model.sigma_pixel_m > 0:
        if weighting != "unit":
            raise ValueError(f"estimate: weighting={weighting!r} needs model.sigma_pixel_m > 0, got {model.sigma_pixel_m!r}")
    return _least_squares(observations, name, spec, weighting, iterate, model, prior_sigma_arcsec, theta0_arcsec,
                          max_condition, loss, float_names, extra_columns)


def _least_squares(obs, name, spec, weighting, iterate, model, prior_sigma_arcsec, theta0_arcsec, max_condition,
                   loss, float_names, extra_columns):
    from boresight.core.campaign_gls import (
        campaign_gls, pixel_residuals, residual_variances, sandwich_middle, solve_nuisances,
    )

    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    n_iter = _iterations(iterate)
    if loss is not None and iterate is True:
        n_iter = MAX_ROBUST_ITERATIONS
    modelled = model is not None and model.sigma_pixel_m > 0
    ext = _Extra(obs, float_names, extra_columns)
    K = ext.K
    n = 3 + K
    prior_info = None
    if prior_sigma_arcsec is not None:
        s = np.broadcast_to(np.asarray(prior_sigma_arcsec, dtype=np.float64), (3,))
        if not np.all(np.isfinite(s) & (s > 0)):
            raise ValueError(f"estimate: prior_sigma_arcsec must be > 0, got {prior_sigma_arcsec!r}")
        # DECISION: a prior narrower than the convergence tolerance (1e-6″) cannot be resolved (and
        # below ~1e-150″ its information overflows): refused. A huge σ is no prior (information 0).
        if np.any(s < PRIOR_SIGMA_MIN_ARCSEC):
            raise ValueError(f"estimate: prior_sigma_arcsec must be ≥ {PRIOR_SIGMA_MIN_ARCSEC:g} arcsec (the convergence tolerance), "
                             f"got {prior_sigma_arcsec!r}")
        prior_info = np.zeros((n, n))
        with np.errstate(over="ignore", under="ignore"):
            prior_info[:3, :3] = np.diag(1.0 / (s * ARCSEC) ** 2)
    theta = np.zeros((R, 3))
    if theta0_arcsec is not None:
        theta = np.broadcast_to(np.asarray(theta0_arcsec, dtype=np.float64) * ARCSEC, (R, 3)).copy()
    p = np.zeros((R, K))
    # DECISION: with extra parameters the joint system is solved in units of a typical size per
    # unknown — 1″ for θ, the effect's own scale for each extra — so its condition number (and
    # max_condition) compares like with like.
    cs = np.concatenate([np.full(3, ARCSEC if K else 1.0), ext.scales if K else np.zeros(0)])
    if prior_info is not None:
        prior_info = prior_info * cs[:, None] * cs[None, :]
    labels = ("θx", "θy", "θz") + (ext.labels if K else ())
    need_L = spec.residual_map is not None and (modelled or K)
    mask4 = obs.mask[None, :, :, None]

    def linearise(theta, p):
        G, q = spec.func(obs, theta)
        L = spec.residual_map(obs, theta) if need_L else None
        if K:
            cols = ext.hook(obs, theta, p)
            J = np.asarray(cols.jacobian, float)
            off = np.asarray(cols.offset, float)
            if name == "image_plane" and getattr(cols, "theta_jacobian", None) is not None:
                G = np.where(mask4[..., None], cols.theta_jacobian, 0.0)  # exact at (θ, p)
            if L is not None and name != "image_plane":
                J = L @ J
                off = (L @ off[..., None])[..., 0]
            q = q - np.where(mask4, off, 0.0)
            G = np.concatenate([G, np.where(mask4[..., None], J, 0.0)], axis=-1) * cs
        return G, q, L

    def normalised(G, q, L, theta, w=None):
        """Per-observation normalised residual length z (R, N, M) and, under a model, the GLS χ²."""
        if modelled:
            e, chi2m = pixel_residuals(obs, theta, G, q, model, L, obs_weights=w)
            return np.linalg.norm(e, axis=-1), chi2m, e
        valid = np.broadcast_to(mask4, q.shape)
        s = _robust_scale(q, valid)
        s = np.where(s > 0, s, 1.0)
        return np.linalg.norm(q, axis=-1) / s[:, None, None], None, None

    w = None
    converged = np.zeros(R, bool)
    last_step = np.full(R, np.inf)
    for it in range(1, n_iter + 1):
        G, q, L = linearise(theta, p)
        w_prev = w
        if loss is not None:
            z, _, _ = normalised(G, q, L, theta, w)
            # DECISION: Tukey's redescending loss starts from Huber weights (3 iterations) so a
            # far-off least-squares start cannot lock onto a wrong minimum.
            w = robust_weights(z, "huber" if (loss == "tukey" and it <= 3) else loss)
            w = np.where(obs.mask[None], w, 0.0)
        if weighting == "gls":
            last_fit = campaign_gls(obs, theta, G, q, model, L, obs_weights=w)
            ne = last_fit.normal_equations
            chi2_data = ne.solve(check=False).chi2  # before the prior: the noise-model statistic
            W = None
        else:
            Gf = G.reshape(R, N, -1, n)
            qf = q.reshape(R, N, -1)
            W = np.ones(q.shape) if w is None else np.repeat(w[..., None], 2, axis=-1)
            if weighting == "diagonal":
                W = W / np.where(mask4, residual_variances(obs, theta, model, L), 1.0)
            ne = NormalEquations(n, R)
            ne.update(Gf, qf, W.reshape(R, N, -1), valid=np.broadcast_to(mask4, q.shape).reshape(R, N, -1) & (W.reshape(R, N, -1) > 0))
        if prior_info is not None and weighting == "gls":
            mean = np.zeros((R, n))
            mean[:, :3] = -theta / cs[:3]
            ne.add_prior(information=prior_info, mean=mean)
        sol = ne.solve(max_condition=max_condition, labels=labels if K else None)
        step = sol.theta * cs
        theta = theta + step[:, :3]
        if K:
            p = p + step[:, 3:]
        last_step = np.max(np.abs(step[:, :3]), axis=-1)
        tol = TOLERANCE_RAD
        if loss is not None:
            # DECISION: reweighting converges linearly; a robust fit has converged when θ moves by
            # less than 1e-3 of its σ (or 1e-6″) and no weight changes by more than 0.01.
            sd = np.sqrt(np.diagonal(sol.covariance, axis1=-2, axis2=-1)[:, :3]) * cs[:3]
            tol = np.maximum(TOLERANCE_RAD, ROBUST_TOLERANCE_SIGMA * sd.min(axis=-1))
        converged = last_step < tol
        if K:
            converged &= np.all(np.abs(sol.theta[:, 3:]) < 1e-9, axis=-1)
        if loss is not None and w_prev is not None:
            converged &= np.max(np.abs(w - w_prev).reshape(R, -1), axis=1) < ROBUST_WEIGHT_TOLERANCE
        elif loss is not None:
            converged[:] = False
        if np.all(converged):
            break

    # ---- covariance (joint over [θ, p], in the scaled units)
    A = sol.covariance
    if weighting == "gls":
        cov = A
    elif modelled:
        WG = G * W[..., None]
        cov = A @ sandwich_middle(obs, theta, model, WG, L) @ A
    else:
        s2 = np.divide(sol.chi2, sol.dof, out=np.full(R, np.nan), where=sol.dof > 0)
        cov = A * s2[:, None, None]
    if prior_info is not None and weighting != "gls":
        # DECISION: the prior is combined with the data-only estimate θ_d through the data's own
        # honest covariance C_d (the sandwich under the noise model, or A·χ²/dof without one):
        # θ = θ_d + (C_d⁻¹ + P)⁻¹ P (θ_prior − θ_d). Under GLS the prior enters the normal
        # equations directly — the same thing, since there C_d⁻¹ is the GLS information.
        if not np.all(np.isfinite(cov)):
            raise ObservabilityError("estimate: the data-only covariance is not finite (too few residual degrees of freedom), "
                                     "so a prior cannot be combined with it")
        info_d = np.linalg.inv(cov)
        post = np.linalg.inv(info_d + prior_info)
        post = 0.5 * (post + np.swapaxes(post, -1, -2))
        m = np.zeros((R, n))
        m[:, :3] = -theta / cs[:3]  # prior mean 0 minus θ_d, in scaled units
        step = np.einsum("rij,jk,rk->ri", post, prior_info, m) * cs
        theta = theta + step[:, :3]
        if K:
            p = p + step[:, 3:]
        cov = post
    cov = cov * cs[:, None] * cs[None, :]  # rad for θ, effect units for the extras
    S = np.concatenate([np.full(3, 1.0 / ARCSEC), np.ones(K)])
    cov_phys = cov * S[:, None] * S[None, :]  # arcsec and effect units

    # ---- final residuals, normalised residuals, χ² under the model
    G, q_final, L = linearise(theta, p)
    if weighting == "gls":
        # the last fit's factors at its linearisation point, moved by the last (tiny) step
        e = _dense_slots(obs, last_fit, solve_nuisances(last_fit, sol.theta))
        z, chi2m = np.linalg.norm(e, axis=-1), chi2_data
    else:
        z, chi2m, e = normalised(G, q_final, L, theta, w)
    if weighting == "gls" and loss is not None:
        # the M-estimator's sandwich covariance replaces the fixed-weights inverse information
        cov = _m_estimator_covariance(obs, theta, G, q_final, model, L, z, loss, prior_info, R, n) * cs[:, None] * cs[None, :]
        cov_phys = cov * S[:, None] * S[None, :]
    extra = {"loss": loss}
    chi2 = sol.chi2
    if modelled and loss is not None:
        # DECISION: under a robust loss the weighted χ² is not χ²-distributed. The noise-model
        # statistic is the GLS χ² of the observations the fit treats as data: every observation
        # whose pixel-level residual length z is ≤ CHI2_INLIER_Z is kept (a clean one is cut with
        # probability exp(−z²/2) = 1e-5), the rest are excluded as outliers, and the GLS χ² of the
        # kept ones — per-image, per-pass and catalogue errors marginalised exactly, θ and the
        # floated parameters minimised — is χ²(2·kept − n) under the model, checked against its
        # own quantiles (docs/estimators.md, "Robust losses").
        keep = obs.mask[None] & (z <= CHI2_INLIER_Z)
        fit_in = campaign_gls(obs, theta, G, q_final, model, L, obs_weights=keep.astype(np.float64))
        chi2m = fit_in.normal_equations.solve(check=False).chi2
        chi2 = chi2m
        kept = keep.reshape(R, -1).sum(axis=1)
        extra["chi2_kept_observations"] = kept if R > 1 else int(kept[0])
    if modelled:
        extra["chi2_model"] = chi2m if R > 1 else chi2m[0]
        dofm = 2 * (obs.n_observations if loss is None else kept) - n
        extra["dof_model"] = np.broadcast_to(dofm, (R,)).copy() if R > 1 else int(np.atleast_1d(dofm)[0])
    if weighting == "unit" and loss is None:
        Wu = np.ones(q_final.shape) if w is None else np.repeat(w[..., None], 2, axis=-1)
        chi2 = np.einsum("rnmk,rnmk->r", np.where(mask4, q_final, 0.0) ** 2, Wu)
    extra["normalised_residuals"] = z if R > 1 else z[0]
    zz = np.where(obs.mask, z[0], -np.inf)
    top = np.argsort(zz, axis=None)[::-1][: min(5, obs.n_observations)]
    extra["largest_residuals"] = tuple((int(k // M), str(obs.landmark_ids[k % M]), builtins_float(zz.flat[k])) for k in top)
    downweighted = ()
    if loss is not None:
        extra["robust_weights"] = w if R > 1 else w[0]
        c = LOSSES[loss]
        rows = []
        # listed: z above the loss's constant (Huber: w < 1; Cauchy: w < 0.5; Tukey: w = 0)
        for nn_, mm_ in zip(*np.nonzero(obs.mask & (z[0] > c))):
            zi = builtins_float(z[0, nn_, mm_])
            rows.append((int(nn_), str(obs.landmark_ids[mm_]), zi, builtins_float(w[0, nn_, mm_]),
                         f"normalised residual {zi:.1f} > {c} ({loss}), weight {w[0, nn_, mm_]:.3f}"))
        downweighted = tuple(sorted(rows, key=lambda r: -r[2]))
    if K:
        extra["joint_covariance"] = cov_phys if R > 1 else cov_phys[0]
        extra["joint_labels"] = ("theta_x", "theta_y", "theta_z") + ext.labels
        extra["joint_units"] = (u.arcsec,) * 3 + ext.units
        extra["effect_status"] = ext.status
    if obs.truth is not None and "theta_rad" in obs.truth:
        with np.errstate(over="ignore", invalid="ignore"):  # a file's truth is untrusted metadata
            t = np.asarray(obs.truth["theta_rad"], dtype=np.float64).reshape(-1, 3) / ARCSEC
        if np.all(np.isfinite(t)):
            extra["truth_arcsec"] = t if R > 1 else t[0]
    effects = {}
    sig_p = np.sqrt(np.diagonal(cov_phys, axis1=-2, axis2=-1))[:, 3:]
    for gname, sl in ext.groups() if K else ():
        unit = ext.units[sl.start]
        val, sg = p[:, sl], sig_p[:, sl]
        if sl.stop - sl.start == 1:
            val, sg = val[:, 0], sg[:, 0]
        effects[gname] = ((val[0] if R == 1 else val) * unit, (sg[0] if R == 1 else sg) * unit)

    prior_rad = None if prior_info is None else prior_info / (cs[:, None] * cs[None, :])
    warnings = _warnings(obs, theta, cov, A, prior_rad, converged, last_step, it, chi2m if modelled else None,
                         extra.get("dof_model"), modelled, weighting, loss, ext, extra.get("chi2_kept_observations"))
    includes = _sigma_includes(model if modelled else None, weighting, prior_info is not None, K, loss)

    def squeeze(a):
        return a[0] if R == 1 else a

    return Estimate(
        theta=squeeze(theta / ARCSEC) * u.arcsec,
        covariance=squeeze(cov[:, :3, :3] / ARCSEC**2) * u.arcsec**2,
        residuals=squeeze(q_final),
        chi2=squeeze(chi2),
        dof=squeeze(np.broadcast_to(extra["dof_model"], (R,)) if modelled and loss is not None else sol.dof),
        condition_number=squeeze(sol.condition_number),
        iterations=it,
        converged=squeeze(converged),
        algorithm=name,
        weighting=weighting,
        residual_unit=spec.residual_unit,
        extra=extra,
        warnings=tuple(warnings),
        sigma_includes=includes,
        effects=effects,
        downweighted=downweighted,
    )


def robust_weight_slope(z, loss: str):
    """dw/dz of ``robust_weights`` (array)."""
    c = LOSSES[loss]
    z = np.asarray(z, float)
    if loss == "huber":
        return np.where(z <= c, 0.0, -c / np.maximum(z, c) ** 2)
    if loss == "cauchy":
        return -2.0 * z / c**2 * robust_weights(z, loss) ** 2
    return np.where(z < c, -4.0 * z / c**2 * (1.0 - (z / c) ** 2), 0.0)


def _clean_constants(loss: str):
    """(κ1, κ2) = (E[w + z w′/2], E[w² z²]/2) for a clean observation, z the length of a standard
    normal 2-vector (Rayleigh), truncated at CHI2_INLIER_Z: the expected slope of the estimating
    function per component (trace of ∂ψ/∂r over 2) and the variance of ψ per component."""
    from scipy.integrate import quad

    if loss not in _KAPPA:
        f = lambda z: z * np.exp(-0.5 * z * z)  # noqa: E731 - Rayleigh density
        norm = 1.0 - np.exp(-0.5 * CHI2_INLIER_Z**2)
        brk = [LOSSES[loss]] if LOSSES[loss] < CHI2_INLIER_Z else None
        k1 = quad(lambda z: (robust_weights(z, loss) + 0.5 * z * robust_weight_slope(z, loss)) * f(z), 0, CHI2_INLIER_Z, points=brk)[0]
        k2 = quad(lambda z: 0.5 * (robust_weights(z, loss) * z) ** 2 * f(z), 0, CHI2_INLIER_Z, points=brk)[0]
        _KAPPA[loss] = (k1 / norm, k2 / norm)
    return _KAPPA[loss]


_KAPPA: dict = {}


def _m_estimator_covariance(obs, theta, G, q, model, L, z, loss, prior_info, R, n):
    """Sandwich covariance of the robust GLS fit (Huber & Ronchetti, Robust Statistics, 2nd ed. 2009, ch. 7:
    the M-estimator of regression, cov = J⁻¹ K J⁻¹, (Eψ²/(Eψ′)²)(XᵀX)⁻¹ for i.i.d. errors),
    with the per-image/per-pass/catalogue nuisances carried as random effects with their prior.

    The IRLS fit solves Σ_i Z_iᵀ ψ(r_i) − [0; ν] − P x = 0 over the joint [x, ν] (whitened rows Z_i
    of an observation, ψ(r) = w(|r|) r, the nuisance prior and the prior P on θ quadratic).
    Linearised, x̂ − x = A Σ_i z̃_i ψ_i + (prior terms), with J the expected slope of the estimating
    function (observation i: ψ′_i = E[tr ∂ψ/∂r]/2 per component), A = (Schur complement of J onto
    x)⁻¹ and z̃_i the rows reduced by J (``campaign_gls.reduced_rows``). Its covariance is

        cov = A [Σ_i m_i z̃_i z̃_iᵀ + Σ_priors] A = A + A [Σ_i (m_i − ψ′_i) z̃_i z̃_iᵀ] A,

    m_i = E|ψ_i|²/2, because the quadratic prior rows contribute equally to both brackets. For an
    observation the model describes (pixel-level z ≤ CHI2_INLIER_Z) ψ′ and m are the loss's
    expected constants for a standard normal 2-vector (``_clean_constants``) — the residual itself
    is shrunk by the nuisances (leverage), the true error is not; for an outlier (z above) its own
    values, w + z w′/2 (≥ 0) and w² z²/2. Without outliers and w ≡ 1 this is the GLS inverse
    information; in scaled units (R, n, n).
    """
    from boresight.core.campaign_gls import campaign_gls, reduced_rows

    k1, k2 = _clean_constants(loss)
    inl = z <= CHI2_INLIER_Z
    psi1 = np.where(inl, k1, np.maximum(robust_weights(z, loss) + 0.5 * z * robust_weight_slope(z, loss), 0.0))
    meat = np.where(inl, k2, 0.5 * (robust_weights(z, loss) * z) ** 2)
    psi1, meat = (np.where(obs.mask[None], a, 0.0) for a in (psi1, meat))
    fit = campaign_gls(obs, theta, G, q, model, L, obs_weights=psi1)
    ne = fit.normal_equations
    if prior_info is not None:
        ne.add_prior(information=prior_info)
    A = ne.solve(check=False).covariance
    _, zt = reduced_rows(fit, A)
    idx, valid = fit._store["idx"], fit._store["valid"]
    diff = np.take_along_axis(meat - psi1, idx[None], axis=2) * valid
    D = np.einsum("rns,rnski,rnskj->rij", diff, zt, zt)
    cov = A + A @ D @ A
    return 0.5 * (cov + np.swapaxes(cov, -1, -2))


def _dense_slots(obs, fit, e):
    """Slot-layout residuals (R, N, Mx, 2) → dense (R, N, M, 2), 0 where masked."""
    idx, valid = fit._store["idx"], fit._store["valid"]
    out = np.zeros(obs.xy_m.shape)
    nn, ss = np.nonzero(valid)
    out[:, nn, idx[nn, ss]] = e[:, nn, ss]
    return out


def builtins_float(v):
    return np.float64(v).item()


def model_parts(model) -> list:
    """The non-zero error sources of a ``DisturbanceModel`` in plain words, e.g. ``'GNSS 15 m (both)'``."""
    parts = []
    if model.sigma_pixel_m > 0:
        parts.append(f"pixel {model.sigma_pixel_m:.3g} m")
    st = np.asarray(model.sigma_star_tracker_rad) / ARCSEC
    if np.any(st > 0):
        parts.append(f"star tracker {np.array2string(st, precision=3, separator=', ')}″ ({model.star_tracker_mode})")
    if model.sigma_gnss_m > 0:
        parts.append(f"GNSS {model.sigma_gnss_m:.3g} m ({model.gnss_mode})")
    if model.sigma_catalogue_m > 0:
        parts.append(f"catalogue {model.sigma_catalogue_m:.3g} m")
    return parts


def _sigma_includes(model, weighting, prior, K, loss) -> str:
    if model is None:
        text = "scatter only — star-tracker and GNSS errors not included (no noise model; σ from the residual scatter)"
    else:
        parts = model_parts(model)
        how = "GLS under" if weighting == "gls" else f"{weighting}-weighted fit, sandwich covariance under"
        text = f"{how} the noise model: " + ", ".join(parts)
    if K:
        text += "; the floated effects' uncertainty (fitted jointly)"
    if prior:
        text += "; the prior on θ"
    if loss and model is not None and weighting == "gls":
        text += f"; {loss} loss: M-estimator sandwich (outliers' own influence, inliers at the loss's expected constants)"
    elif loss:
        text += f"; {loss} reweighting treated as fixed weights"
    return text


def _warnings(obs, theta, cov, A, prior_info, converged, last_step, iterations, chi2m, dofm, modelled, weighting, loss, ext,
              kept=None):
    from scipy.stats import chi2 as chi2_dist

    out = []
    R = theta.shape[0]
    tag = (lambda r: "") if R == 1 else (lambda r: f"run {r}: ")
    if chi2m is not None:
        # the χ² range of every run at once (one vectorised ppf, not two per run: 40 % of a batched call)
        d_all = np.broadcast_to(np.asarray(dofm, dtype=np.float64), (R,))
        lo_all = chi2_dist.ppf(0.5 * (1 - CHI2_LEVEL), d_all)
        hi_all = chi2_dist.ppf(0.5 * (1 + CHI2_LEVEL), d_all)
    for r in range(R):
        if not converged[r]:
            out.append(f"{tag(r)}did not converge in {iterations} iteration(s): last θ correction {last_step[r] / ARCSEC:.3g}″ "
                       f"(tolerance {TOLERANCE_RAD / ARCSEC:.0e}″{', or 1e-3 σ' if loss else ''}){' or the robust weights still changing' if loss else ''}")
        mag = np.linalg.norm(theta[r]) / ARCSEC
        if mag > SMALL_ANGLE_LIMIT_ARCSEC:
            out.append(f"{tag(r)}|θ| = {mag:.4g}″ is outside the small-angle range |θ| ≤ {SMALL_ANGLE_LIMIT_ARCSEC:.0f}″ (0.5°) "
                       "the error model and the linearised covariance assume — check the conventions (boresight check)")
        if chi2m is not None:
            c2, d = np.float64(np.atleast_1d(chi2m)[r]), np.float64(np.atleast_1d(dofm)[r])
            if d > 0 and kept is not None:
                lo, hi = lo_all[r], hi_all[r]
                k = int(np.atleast_1d(kept)[r])
                if not lo <= c2 <= hi:
                    out.append(f"{tag(r)}χ²/dof = {c2 / d:.3g} under the noise model, of the {k} observations the {loss} fit kept "
                               f"(pixel-level z ≤ {CHI2_INLIER_Z:.1f}; {obs.n_observations - k} left out as outliers), is outside its "
                               f"{CHI2_LEVEL:.1%} range {lo / d:.3f}..{hi / d:.3f}: the noise model does not describe the inliers")
            elif d > 0:
                lo, hi = lo_all[r], hi_all[r]
                if not lo <= c2 <= hi:
                    out.append(f"{tag(r)}χ²/dof = {c2 / d:.3g} under the noise model is outside its {CHI2_LEVEL:.1%} range "
                               f"{lo / d:.3f}..{hi / d:.3f}: the noise model does not describe these residuals"
                               + (" (outliers? try loss='huber')" if c2 > hi and loss is None else ""))
        if prior_info is not None:
            P = np.diag(prior_info)[:3]
            share = P * np.diag(cov[r])[:3]  # prior information × posterior variance ≈ the prior's share
            for k in np.flatnonzero(share > PRIOR_DOMINANCE):
                out.append(f"{tag(r)}the prior dominates θ{'xyz'[k]}: it carries {share[k]:.0%} of the information "
                           f"(prior σ {1 / np.sqrt(P[k]) / ARCSEC:.3g}″, posterior σ {np.sqrt(cov[r, k, k]) / ARCSEC:.3g}″)")
    if not modelled:
        if getattr(obs, "noise", None) is not None:
            # the observations carry a noise model the caller did not pass: say so, never silently
            out.append("the observations carry a noise model that was NOT used (weighting='unit', or no pixel σ to weight "
                       "with): σ is the residual scatter only and does not include star-tracker or GNSS errors (pass "
                       "model=DisturbanceModel.from_observations(obs) for its sandwich σ, or leave weighting=None for GLS)")
        else:
            out.append("no noise model: σ is the residual scatter only and does not include star-tracker or GNSS errors "
                       "(give model=DisturbanceModel(...) or a file with a noise model)")
    for nm, st in getattr(ext, "status", {}).items():
        if st != "ok":
            out.append(f"effect {nm}: {st}")
    return out
