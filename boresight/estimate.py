"""One entry point for every estimator: ``boresight.estimate(observations, algorithm=…, weighting=…)``.

Least-squares algorithms (Kiev 2012 eqs 14-22, 29-31) are *linearisers*: functions
``linearize(obs, theta_rad) -> (G (R, N, M, 2, 3), q (R, N, M, 2))`` with q = measured −
predicted ≈ G (θ − θ0), plus a ``residual_map`` that says how image-plane errors reach q. They
share one Gauss-Newton loop and one accumulator (``NormalEquations``): each iteration
re-linearises about the last θ, so a 10′ initial error converges to the noise floor.

Weighting:

* ``"unit"`` — W = E (the slides' eqs 18, 22, 31). Covariance: the sandwich
  A (Gᵀ Σ G) A, A = (GᵀG)⁻¹, under ``model`` if given; else A·χ²/dof.
* ``"diagonal"`` — W = 1/diag(Σ): each residual weighted by its total variance under
  ``model`` (required); covariance by the sandwich with the full Σ.
* ``"gls"`` — generalised least squares under ``model`` (required): each image is whitened by
  its per-image covariance (pixel noise and per-image star-tracker/GNSS errors, which are
  common to the image's landmarks), and errors shared by several images (per-pass star-tracker
  and GNSS biases, catalogue errors) are carried as nuisance parameters with their prior
  variances and eliminated by a Schur complement. Its covariance is B⁻¹, the Cramér–Rao bound
  (``boresight.crlb``) to first order.

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

from .crlb import error_structure
from .disturbances import DisturbanceModel
from .normal_equations import DEFAULT_MAX_CONDITION, NormalEquations

__all__ = ["Estimate", "estimate", "register_algorithm", "algorithms", "WEIGHTINGS"]

WEIGHTINGS = ("unit", "diagonal", "gls")
#: iterations when ``iterate=True``
MAX_ITERATIONS = 20
#: convergence: largest correction below this (rad) — 1e-6 arcsec
# DECISION: 1e-6″, a thousand times below the 0.001″ recovery requirement and ten times above
# the round-off floor (~1e-7″) of the GLS Schur complement with per-pass nuisances.
TOLERANCE_RAD = 1e-6 * ARCSEC


@dataclass(frozen=True)
class Estimate:
    """The result of ``estimate``. The run axis is dropped when the input has one run.

    ``theta`` Quantity arcsec (R, 3) or (3,); ``covariance`` Quantity arcsec² (R, 3, 3) or (3, 3);
    ``residuals`` (R, N, M, 2) final residuals (measured − predicted) in ``residual_unit``,
    0 where masked; ``chi2`` the minimised weighted sum of squares (for ``unit`` weighting the
    plain sum of squares in ``residual_unit``²); ``dof`` degrees of freedom; ``condition_number``
    of the normal matrix of θ (prior included); ``iterations`` Gauss-Newton iterations;
    ``converged`` whether the last correction was below 1e-6″.
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

    @property
    def sigma(self) -> u.Quantity:
        """Standard deviations of θ (arcsec), (R, 3) or (3,)."""
        return np.sqrt(np.diagonal(self.covariance.to_value(u.arcsec**2), axis1=-2, axis2=-1)) * u.arcsec

    def __str__(self) -> str:
        return self.summary()

    def summary(self) -> str:
        """Human-readable lines: θ ± σ per axis, χ²/dof, condition number (first run)."""
        th = np.atleast_2d(self.theta.to_value(u.arcsec))[0]
        sg = np.atleast_2d(self.sigma.to_value(u.arcsec))[0]
        chi2, dof, cond = (np.atleast_1d(v)[0] for v in (self.chi2, self.dof, self.condition_number))
        lines = [f"algorithm     {self.algorithm} ({self.weighting} weighting), {self.iterations} iteration(s)"]
        for name, t, s in zip(("theta_x", "theta_y", "theta_z"), th, sg):
            lines.append(f"{name:<13} {t:+.4f} ± {s:.4f} arcsec")
        lines.append(f"chi2 / dof    {chi2:.4g} / {int(dof)}")
        lines.append(f"condition     {cond:.3g}")
        return "\n".join(lines)


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
    (``boresight.registry``, complete without importing the algorithm modules) and any
    registered at run time with ``register_algorithm``."""
    from . import registry

    return sorted(set(registry.estimator_names()) | set(_REGISTRY) | set(_ALIASES))


def _builtin(name: str | None = None):
    """Register the built-in algorithm ``name`` (default: the linearizers) from ``boresight.registry``."""
    import importlib

    from . import registry

    rows = [registry.ALGORITHMS[name]] if name is not None else [registry.ALGORITHMS[n] for n in registry.names("linearizer")]
    for row in rows:
        module = importlib.import_module(row.module)
        register_algorithm(row.name, getattr(module, row.function), kind=row.kind,
                           residual_map=getattr(module, row.residual_map) if row.residual_map else None,
                           residual_unit=row.residual_unit, aliases=row.aliases)


_builtin()


def _lookup(algorithm):
    from . import registry

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
            raise registry.UnknownAlgorithmError(f"estimate: unknown algorithm {algorithm!r}; expected one of {algorithms()}")
    return name, _REGISTRY[name]


def _iterations(iterate):
    if iterate is True:
        return MAX_ITERATIONS
    if iterate is False or iterate is None:
        return 1
    if isinstance(iterate, (int, np.integer)) and iterate >= 1:
        return int(iterate)
    raise ValueError(f"estimate: iterate must be True, False or a positive integer, got {iterate!r}")


def _weights_and_structure(obs, theta, spec, weighting, model):
    """Per-image weights (R, N, 2M[, 2M]) and the error structure for the covariance."""
    if model is None:
        return None, None
    L = spec.residual_map(obs, theta) if spec.residual_map is not None else None
    es = error_structure(obs, theta, model, L)
    return L, es


def _sandwich(A, Gf, W, es, prior_info):
    """Covariance of θ̂ for weights W under the error structure es: A (Σ Gᵀ W Σ W G) A."""
    if W.ndim == Gf.ndim - 1:  # diagonal (R, N, 2M)
        WG = Gf * W[..., None]
    else:
        WG = W @ Gf
    mid = np.einsum("rnki,rnkl,rnlj->rij", WG, es.D, WG)
    K = np.einsum("rnki,rnkp->rip", WG, es.U)
    mid = mid + np.einsum("rip,p,rjp->rij", K, es.variance, K)
    if prior_info is not None:
        mid = mid + prior_info
    return A @ mid @ A


# DECISION: the Kalman filter is only meaningful with its full per-image noise model, so its
# default weighting is "gls"; every other algorithm defaults to "unit".
_DEFAULT_WEIGHTING = {"kalman": "gls"}


def estimate(observations, algorithm: str = "image_plane", weighting: str | None = None, iterate=True,
             model: DisturbanceModel | None = None, prior_sigma_arcsec=None, *, theta0_arcsec=None,
             max_condition: float = DEFAULT_MAX_CONDITION, **options) -> Estimate:
    """Estimate the misalignment θ (Kiev 2012 eq 24 sign) from an ``ObservationSet``.

    Parameters
    ----------
    observations : ObservationSet (R runs, N images, M landmarks).
    algorithm : ``"image_plane"`` (alias ``"alg3"``, eqs 19-22), ``"ground_plane"`` (``"alg2"``,
        eqs 14-18), ``"unit_vector"`` (eqs 29-31), or a registered name (``"alg1"``, ``"kalman"``).
    weighting : ``"unit"``, ``"diagonal"`` or ``"gls"`` (the last two need ``model``); default
        ``"gls"`` for the Kalman filter and ``"unit"`` for every other algorithm.
    iterate : True (re-linearise until the correction is < 1e-6″, at most 20 times), False (one
        linearisation about θ0), or the maximum number of iterations.
    model : ``DisturbanceModel`` for weights and covariance.
    prior_sigma_arcsec : σθ0, a prior θ ~ N(0, σθ0²) per axis as initial information (scalar or (3,)).
    theta0_arcsec : first linearisation point, (3,) or (R, 3); default 0.
    max_condition : refuse (``ObservabilityError``) a normal matrix worse conditioned than this.

    Returns an ``Estimate``; raises ``ObservabilityError`` when θ is not determined.
    """
    name, spec = _lookup(algorithm)
    if weighting is None:
        weighting = _DEFAULT_WEIGHTING.get(name, "unit")
    if weighting not in WEIGHTINGS:
        raise ValueError(f"estimate: weighting must be one of {WEIGHTINGS}, got {weighting!r}")
    if model is not None and not isinstance(model, DisturbanceModel):
        raise ValueError(f"estimate: model must be a boresight.DisturbanceModel or None, got {type(model).__name__}")
    if spec.kind == "estimator":
        return spec.func(observations, weighting=weighting, iterate=iterate, model=model,
                         prior_sigma_arcsec=prior_sigma_arcsec, **options)
    if options:
        raise ValueError(f"estimate: algorithm {name!r} takes no options, got {sorted(options)}")
    if weighting != "unit" and model is None:
        raise ValueError(f"estimate: weighting={weighting!r} needs a disturbance model (model=DisturbanceModel(...))")
    if weighting != "unit" and spec.residual_map is None:
        raise ValueError(f"estimate: algorithm {name!r} has no residual_map, so only weighting='unit' is available")
    if weighting != "unit" and not model.sigma_pixel_m > 0:
        raise ValueError(f"estimate: weighting={weighting!r} needs model.sigma_pixel_m > 0, got {model.sigma_pixel_m!r}")
    obs = observations
    R = obs.runs
    n_iter = _iterations(iterate)
    prior_info = None
    if prior_sigma_arcsec is not None:
        s = np.broadcast_to(np.asarray(prior_sigma_arcsec, float), (3,))
        if not np.all(np.isfinite(s) & (s > 0)):
            raise ValueError(f"estimate: prior_sigma_arcsec must be > 0, got {prior_sigma_arcsec!r}")
        prior_info = np.diag(1.0 / (s * ARCSEC) ** 2)
    theta = np.zeros((R, 3))
    if theta0_arcsec is not None:
        theta = np.broadcast_to(np.asarray(theta0_arcsec, float) * ARCSEC, (R, 3)).copy()

    converged = np.zeros(R, bool)
    for it in range(1, n_iter + 1):
        G, q = spec.func(obs, theta)
        Gf = G.reshape(R, obs.n_images, -1, 3)
        qf = q.reshape(R, obs.n_images, -1)
        _, es = _weights_and_structure(obs, theta, spec, weighting, model)
        W = None
        if weighting == "unit":
            ne = NormalEquations(3, R)
            ne.update(Gf, qf)
        elif weighting == "diagonal":
            var = np.diagonal(es.D, axis1=-2, axis2=-1) + np.einsum("rnkp,p->rnk", es.U**2, es.variance)
            W = 1.0 / var
            ne = NormalEquations(3, R)
            ne.update(Gf, qf, W)
        else:
            p = es.U.shape[-1]
            ne = NormalEquations(3 + p, R)
            # DECISION: nuisances in units of their own σ (columns U·σ, prior information E): the
            # augmented normal matrix then mixes no units (rad, m) and stays well conditioned.
            Us = es.U * np.sqrt(es.variance)
            ne.update(np.concatenate([Gf, Us], axis=-1), qf, covariance=es.D, valid=np.any(Gf != 0, axis=-1))
            if p:
                info = np.zeros((3 + p, 3 + p))
                info[3:, 3:] = np.eye(p)
                ne.add_prior(information=info)
                ne = ne.eliminate(3)
        if prior_info is not None:
            ne.add_prior(information=prior_info, mean=-theta)
        sol = ne.solve(max_condition=max_condition)
        theta = theta + sol.theta
        converged = np.max(np.abs(sol.theta), axis=-1) < TOLERANCE_RAD
        if np.all(converged):
            break

    A = sol.covariance
    if weighting == "gls":
        cov = A
    elif model is not None:
        if weighting == "unit":
            W = np.ones(qf.shape)
        cov = _sandwich(A, Gf, W, es, prior_info)
    else:
        s2 = np.divide(sol.chi2, sol.dof, out=np.full(R, np.nan), where=sol.dof > 0)
        cov = A * s2[:, None, None]
    _, q_final = spec.func(obs, theta)

    def squeeze(a):
        return a[0] if R == 1 else a

    return Estimate(
        theta=squeeze(theta / ARCSEC) * u.arcsec,
        covariance=squeeze(cov / ARCSEC**2) * u.arcsec**2,
        residuals=squeeze(q_final),
        chi2=squeeze(sol.chi2),
        dof=squeeze(sol.dof),
        condition_number=squeeze(sol.condition_number),
        iterations=it,
        converged=squeeze(converged),
        algorithm=name,
        weighting=weighting,
        residual_unit=spec.residual_unit,
    )
