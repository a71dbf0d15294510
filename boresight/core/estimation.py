"""One entry point for every estimator: ``boresight.estimate(observations, algorithm=…, weighting=…)``.

Least-squares algorithms (Kiev 2012 eqs 14-22, 29-31) are *linearisers*: functions
``linearize(obs, theta_rad) -> (G (R, K, 2, 3), q (R, K, 2))`` — one row per observation (the row
model, ``docs/architecture.md``) — with q = measured − predicted ≈ G (θ − θ0), plus a
``residual_map`` (R, K, 2, 2) that says how image-plane errors reach q. They share one Gauss-Newton
loop and one accumulator (``NormalEquations``): each iteration re-linearises about the last θ, so a
10′ initial error converges to the noise floor. Nothing in the loop has an images × targets axis
pair: memory and cost are linear in observations, plus the GLS's reduced image/pass system.

Weighting (default: ``"gls"`` when a noise model is known — ``model=`` or the observations' own,
``DisturbanceModel.from_observations`` — and ``"unit"`` otherwise; ``boresight.core.weighting``):
``"unit"``, ``"diagonal"`` (sandwich covariances) or ``"gls"`` — generalised least squares under
``model``, the one GLS on rows (``boresight.core.gls.rows``, its rows built by
``boresight.core.gls.campaign.row_problem``): pixel noise whitened per observation, single-use
targets folded into their row, shared targets eliminated by a sparse Schur complement, per-image
and per-pass errors in the reduced image/pass system — each error with its prior. Its covariance
is the inverse information, the Cramér–Rao bound (``boresight.core.crlb``) to first order.

Options common to the least-squares algorithms: ``loss=`` (robust IRLS, ``boresight.core.robust``),
``effects=`` / ``extra_columns=`` (extra global parameters fitted jointly with θ,
``boresight.core.floated``), ``prior_sigma_arcsec`` (in absolute terms under every weighting).
``Estimate.warnings``, ``converged``, ``sigma_includes`` and ``summary()`` say how far to trust the
result (``boresight.core.result``, ``docs/estimators.md``).

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

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from astropy import units as u

from boresight.core.consistency import with_scatter_check
from boresight.core.disturbances import DisturbanceModel
from boresight.core.floated import ExtraParameters
from boresight.core.gls.normal_equations import DEFAULT_MAX_CONDITION, NormalEquations
from boresight.core.gls.structure import has_pixel_noise
from boresight.core.registry import Registered, algorithms, register_algorithm, resolve  # re-exported: the one registry
from boresight.core.result import Estimate, estimate_warnings, model_unit_slips, sigma_includes, top_residuals
from boresight.core.robust import (
    CHI2_INLIER_Z,
    LOSSES,
    MAX_ROBUST_ITERATIONS,
    ROBUST_TOLERANCE_SIGMA,
    ROBUST_WEIGHT_TOLERANCE,
    m_estimator_covariance,
    rejection_warning,
    robust_scale,
    robust_weights,
)
from boresight.core.weighting import WEIGHTINGS, default_effects, default_weighting, iteration_limit
from boresight.errors import OBSERVATION_SET, InputTypeError, InputValueError, ObservabilityError
from orbits.rotations import ARCSEC

__all__ = ["Estimate", "estimate", "register_algorithm", "algorithms", "WEIGHTINGS"]

#: iterations when ``iterate=True``
MAX_ITERATIONS = 20
#: convergence: largest correction below this (rad) — 1e-6 arcsec
# DECISION: 1e-6″, a thousand times below the 0.001″ recovery requirement and ten times above
# the round-off floor (~1e-7″) of the GLS Schur complement with per-pass nuisances.
TOLERANCE_RAD = 1e-6 * ARCSEC
#: the narrowest prior σθ0 accepted (the convergence tolerance: a narrower prior cannot be resolved)
PRIOR_SIGMA_MIN_ARCSEC = 1e-6


def estimate(
    observations: Any,
    algorithm: str = "image_plane",
    weighting: str | None = None,
    iterate: bool | int = True,
    model: DisturbanceModel | None = None,
    prior_sigma_arcsec: Any = None,
    *,
    theta0_arcsec: Any = None,
    max_condition: float = DEFAULT_MAX_CONDITION,
    loss: str | None = None,
    effects: str | list[str] | None = None,
    extra_columns: Callable[..., Any] | None = None,
    **options: Any,
) -> Estimate:
    """Estimate the misalignment θ (Kiev 2012 eq 24 sign) from an ``ObservationSet``.

    Parameters
    ----------
    observations : ObservationSet (R runs, N images, T targets, K observations).
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
    effects : names of effects (``boresight.core.effect_model.effect_names()``) fitted jointly with θ;
        ``[]`` or ``"none"``: none. Default (None): none, except on a set of star and landmark rows, where
        ``gnss_bias`` (which the star rows separate from θ) is floated (``core.weighting.default_effects``;
        ``Estimate.effects_by_default`` says so).
    extra_columns : a hook ``f(obs, theta_rad, params) -> EffectColumns``-like (offset (R, K, 2),
        jacobian (R, K, 2, P), labels, units, scales: one row per observation of the row set ``obs``)
        of extra global parameters fitted jointly with θ.
    **options : a registered estimator's own keywords (``kalman``'s ``states``, ``gate_probability``, …;
        ``homography``'s ``plane``, …); the least-squares algorithms take none.

    Returns
    -------
    Estimate
        The fit (``boresight.core.result.Estimate``, whose Attributes section gives each field); the run axis
        is dropped when ``observations`` has one run. ``theta`` (R, 3) or (3,) and ``covariance``
        (R, 3, 3) or (3, 3), astropy Quantities in arcsec and arcsec²; ``residuals`` (R, K, 2) in
        ``residual_unit``, one row per observation in canonical order; the fit's statistics ``chi2``,
        ``dof``, ``chi2_model`` / ``dof_model`` (under the noise model), ``condition_number``,
        ``iterations``, ``converged``; how far to trust it: ``warnings``, ``sigma_includes``,
        ``unit_slips``, ``noise_free``; with ``effects=``: ``effects`` ({name: (value, σ)} Quantities),
        ``joint_covariance`` / ``joint_labels`` / ``joint_units``, ``effect_status``,
        ``effects_by_default``; per observation: ``whitened_residual_norm``, ``largest_residuals`` and,
        with ``loss=``, ``robust_weights``, ``downweighted``, ``chi2_kept_observations``; the
        algorithm's own: ``rejected`` and ``nees`` (Kalman), ``planar_model_error_arcsec``
        (Algorithm 1), ``algorithm_result``; ``truth_arcsec`` when the input is simulated.

    Raises
    ------
    InputTypeError
        ``observations`` is not an ``ObservationSet`` (nor pushbroom lines), ``model`` is not a
        ``DisturbanceModel``, ``algorithm`` is not a string.
    UnknownAlgorithmError
        ``algorithm`` is neither a registered name nor an alias (the message lists them).
    UnknownEffectError
        A name in ``effects`` is not in the effects catalogue, or is repeated.
    InputValueError
        An argument's value is refused: ``weighting`` or ``loss`` not among theirs, ``"diagonal"`` /
        ``"gls"`` without a noise model or without a pixel σ on every row, ``prior_sigma_arcsec`` ≤ 0 or
        below 1e-6″, ``theta0_arcsec`` or ``iterate`` malformed, options a least-squares algorithm does
        not take, ``loss`` / ``effects`` / ``extra_columns`` for an estimator that takes none, a frame
        algorithm on pushbroom lines (or ``line_scan`` on frames); an estimator's own options
        (``kalman``: a ``weighting`` other than ``"gls"``, ``gate_probability`` outside (0, 1), unknown
        ``states``, …; ``homography``: ``plane``, ``z_ref_m``, …).
    ObservabilityError
        θ is not determined by the data: too few residual components, or a normal matrix worse
        conditioned than ``max_condition`` (the message names the weak axis and the run);
        ``HomographyError``, a subclass, for an image Algorithm 1 cannot fit (fewer than 4 landmarks,
        a collinear set).
    UnsupportedComputationError
        ``ground_plane`` on a set with star targets (a star has no position, hence no plane).
    MemoryBudgetError
        The GLS on rows, or the Kalman filter's state history, would not fit the memory budget
        (``orbits.limits``); raised with the estimate before anything is allocated.
    """
    from boresight.core.line_scan import is_line_scan_input

    lines = is_line_scan_input(observations)
    if lines and algorithm == "image_plane":
        # DECISION: pushbroom lines are estimated by their own model (registry row ``line_scan``); the frame camera's
        # algorithms do not model a line, so the default algorithm on lines means the line model
        algorithm = "line_scan"
    if not lines and not (hasattr(observations, "runs") and hasattr(observations, "xy_m")):  # core does not import the data model
        raise InputTypeError.expected("estimate", "observations", OBSERVATION_SET, observations)
    if model is not None and not isinstance(model, DisturbanceModel):
        raise InputTypeError.expected("estimate", "model", "a boresight.DisturbanceModel or None", model)
    effect_names = effects
    name, spec = resolve(algorithm)
    if lines != (name == "line_scan"):
        raise InputValueError(
            f"estimate: algorithm {name!r} on "
            + ("pushbroom lines: they are estimated by 'line_scan'" if lines else "a set that is not pushbroom lines")
        )
    first = observations[0] if isinstance(observations, (list, tuple)) else observations
    weighting, model = default_weighting(first, name, spec, weighting, model)
    _check_common(weighting, model, loss)
    if isinstance(effect_names, str):
        effect_names = [n.strip() for n in effect_names.split(",") if n.strip() and n.strip() != "none"]
    effect_names, by_default = default_effects(observations, spec, effect_names)
    if spec.kind == "estimator":
        if name == "line_scan" and loss is not None:  # the line model takes a robust loss (core.line_scan)
            options = {**options, "loss": loss}
            loss = None
        if loss is not None or effect_names or extra_columns is not None:
            raise InputValueError(
                f"estimate: algorithm {name!r} does not take loss=, effects= or extra_columns= "
                "(they are for the least-squares algorithms image_plane, ground_plane, unit_vector)"
            )
        result: Estimate = spec.func(
            observations, weighting=weighting, iterate=iterate, model=model, prior_sigma_arcsec=prior_sigma_arcsec, **options
        )
        if name in ("homography", "kalman") and result.whitened_residual_norm is None:  # the frame estimators of the table
            result = _with_common_fields(observations, result, model)
        return cast(Estimate, with_scatter_check(observations, result, model))  # every algorithm: small-angle and scatter checks
    _check_least_squares(name, spec, weighting, model, options, observations)
    result = _least_squares(
        observations,
        name,
        spec,
        weighting,
        iterate,
        model,
        prior_sigma_arcsec,
        theta0_arcsec,
        max_condition,
        loss,
        effect_names,
        extra_columns,
    )
    if by_default:
        fitted = tuple(n for n in by_default if n in result.effects)
        result = dataclasses.replace(result, effects_by_default=fitted)
    return cast(
        Estimate, with_scatter_check(observations, result, model)
    )  # small-angle check; a σ from the scatter alone: a robust outlier test


def _check_common(weighting: str, model: Any, loss: str | None) -> None:
    if weighting not in WEIGHTINGS:
        raise InputValueError(f"estimate: weighting must be one of {WEIGHTINGS}, got {weighting!r}")
    if loss is not None and (not isinstance(loss, str) or loss not in LOSSES):
        raise InputValueError(f"estimate: loss must be None or one of {sorted(LOSSES)}, got {loss!r}")


def _check_least_squares(
    name: str, spec: Registered, weighting: str, model: DisturbanceModel | None, options: dict[str, Any], observations: Any
) -> None:
    if options:
        raise InputValueError(f"estimate: algorithm {name!r} takes no options, got {sorted(options)}")
    if weighting != "unit" and model is None:
        raise InputValueError(f"estimate: weighting={weighting!r} needs a disturbance model (model=DisturbanceModel(...))")
    if weighting != "unit" and spec.residual_map is None:
        raise InputValueError(f"estimate: algorithm {name!r} has no residual_map, so only weighting='unit' is available")
    if model is not None and not has_pixel_noise(observations, model) and weighting != "unit":
        raise InputValueError(
            f"estimate: weighting={weighting!r} needs a pixel σ > 0 on every row (model.sigma_pixel_m > 0, or each row's own "
            f"sigma_xy_m), got model.sigma_pixel_m = {model.sigma_pixel_m!r}"
        )


# ---- the shared Gauss–Newton loop of the least-squares algorithms


def _three_numbers(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as float64 broadcast to ``shape`` ((3,) or (R, 3)), or an ``InputValueError`` naming it."""
    try:
        return np.broadcast_to(np.asarray(value, dtype=np.float64), shape)
    except (TypeError, ValueError):
        what = "(3,)" if len(shape) == 1 else f"(3,) or ({shape[0]}, 3)"
        raise InputValueError(f"estimate: {name} must be a number or {what} numbers, got {value!r}") from None


def _prior_information(prior_sigma_arcsec: Any, n: int) -> np.ndarray | None:
    """The prior information on [θ, extras] (rad⁻² for θ, 0 for the extras), or None."""
    if prior_sigma_arcsec is None:
        return None
    s = _three_numbers("prior_sigma_arcsec", prior_sigma_arcsec, (3,))
    if not np.all(np.isfinite(s) & (s > 0)):
        raise InputValueError(f"estimate: prior_sigma_arcsec must be > 0, got {prior_sigma_arcsec!r}")
    # DECISION: a prior narrower than the convergence tolerance (1e-6″) cannot be resolved (and
    # below ~1e-150″ its information overflows): refused. A huge σ is no prior (information 0).
    if np.any(s < PRIOR_SIGMA_MIN_ARCSEC):
        raise InputValueError(
            f"estimate: prior_sigma_arcsec must be ≥ {PRIOR_SIGMA_MIN_ARCSEC:g} arcsec (the convergence tolerance), "
            f"got {prior_sigma_arcsec!r}"
        )
    prior_info = np.zeros((n, n))
    with np.errstate(over="ignore", under="ignore"):
        prior_info[:3, :3] = np.diag(1.0 / (s * ARCSEC) ** 2)
    return prior_info


@dataclass
class _Problem:
    """The fixed parts of one least-squares fit: the data, the algorithm, the weighting and the
    scaling of the joint unknowns [θ, extras] (``cs``: 1″ for θ, each extra's own scale)."""

    obs: Any
    name: str
    spec: Any
    weighting: str
    model: DisturbanceModel | None
    loss: str | None
    max_condition: float
    ext: ExtraParameters
    prior_info: np.ndarray | None  # in scaled units

    def __post_init__(self) -> None:
        self.R = self.obs.runs
        self.K = self.ext.K
        self.n = 3 + self.K
        self.modelled = has_pixel_noise(self.obs, self.model)  # the model's σK or every row's own σ
        # DECISION: with extra parameters the joint system is solved in units of a typical size per
        # unknown — 1″ for θ, the effect's own scale for each extra — so its condition number (and
        # max_condition) compares like with like.
        self.cs = np.concatenate([np.full(3, ARCSEC if self.K else 1.0), self.ext.scales if self.K else np.zeros(0)])
        if self.prior_info is not None:
            self.prior_info = self.prior_info * self.cs[:, None] * self.cs[None, :]
        self.labels = ("θx", "θy", "θz") + (self.ext.labels if self.K else ())
        self.need_L = self.spec.residual_map is not None and (self.modelled or self.K)

    @property
    def noise_model(self) -> DisturbanceModel:
        """The noise model of a weighted or modelled fit (``_check_least_squares`` refused the rest)."""
        assert self.model is not None
        return self.model

    def linearise(self, theta: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(G (R, K, 2, n) in scaled units, q (R, K, 2), L (R, K, 2, 2) or None) about (θ, extras)."""
        obs = self.obs
        G, q = self.spec.func(obs, theta)
        rmap = self.spec.residual_map
        L = rmap(obs, theta) if self.need_L and rmap is not None else None
        if self.K:
            hook = self.ext.hook
            assert hook is not None  # K > 0: effects or a caller's columns
            cols = hook(obs, theta, p)
            J = np.asarray(cols.jacobian, float)
            off = np.asarray(cols.offset, float)
            if self.name == "image_plane" and getattr(cols, "theta_jacobian", None) is not None:
                G = np.asarray(cols.theta_jacobian, float)  # exact at (θ, p)
            if L is not None and self.name != "image_plane":
                J = L @ J
                off = (L @ off[..., None])[..., 0]
            q = q - off
            G = np.concatenate([G, J], axis=-1) * self.cs
        return G, q, L

    def gls(self, theta: np.ndarray, G: np.ndarray, q: np.ndarray, L: np.ndarray | None, w: Any = None) -> Any:
        """The GLS on rows (``gls.rows.RowFit``) of the linearisation (G, q, L) under the noise model,
        with robust weights ``w`` (R, K) or None."""
        from boresight.core.gls.campaign import fit_rows

        return fit_rows(self.obs, theta, G, q, self.noise_model, L, w)

    def normalised(
        self, G: np.ndarray, q: np.ndarray, L: np.ndarray | None, theta: np.ndarray, w: np.ndarray | None = None
    ) -> tuple[np.ndarray, Any]:
        """Per-observation normalised residual length z (R, K) and, under a model, the GLS χ².

        Under a model: the pixel-level residuals at θ (no correction) — the MAP per-image, per-pass
        and catalogue errors given θ removed (``gls.rows.row_residuals`` with dx = 0) and the rest
        divided by the pixel σ, N(0, E₂) per observation up to leverage; with ``w`` the nuisances
        are those of the robustly weighted fit (an outlier does not leak into its image's other
        observations). The χ² is the GLS χ² minimised over a (linearised) correction of x: the
        noise-model consistency statistic whatever weighting produced θ. Without a model: |q| over
        the robust scale of the components."""
        from boresight.core.gls.rows import row_residuals

        if self.modelled:
            fit = self.gls(theta, G, q, L, w)
            e = row_residuals(fit, np.zeros((self.R, G.shape[-1])))
            return np.linalg.norm(e, axis=-1), fit.normal_equations.solve(check=False).chi2
        s = robust_scale(q, np.ones(q.shape, bool))
        s = np.where(s > 0, s, 1.0)
        return np.linalg.norm(q, axis=-1) / s[:, None], None


@dataclass
class _State:
    """Where the Gauss–Newton loop stands: θ (R, 3) rad, the extras p (R, K), the robust weights,
    the last linearisation (G, q, L), the unit/diagonal weights W, the last GLS fit."""

    theta: np.ndarray
    p: np.ndarray
    w: np.ndarray | None = None
    converged: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    last_step: np.ndarray = field(default_factory=lambda: np.zeros(0))
    it: int = 0
    sol: Any = None
    G: Any = None
    L: Any = None
    W: Any = None
    last_fit: Any = None
    chi2_data: Any = None


def _normal_equations(pb: _Problem, st: _State, q: np.ndarray) -> NormalEquations:
    """The normal equations of one iteration (prior included under GLS); sets W / last_fit."""
    from boresight.core.gls.structure import residual_variances

    obs, R, n, G, L, w = pb.obs, pb.R, pb.n, st.G, st.L, st.w
    if pb.weighting == "gls":
        st.last_fit = None  # the previous fit's factors (O(K)) are not held while the next is built
        st.last_fit = pb.gls(st.theta, G, q, L, w)
        ne: NormalEquations = st.last_fit.normal_equations
        st.chi2_data = ne.solve(check=False).chi2  # before the prior: the noise-model statistic
        st.W = None
        if pb.prior_info is not None:
            mean = np.zeros((R, n))
            mean[:, :3] = -st.theta / pb.cs[:3]
            ne.add_prior(information=pb.prior_info, mean=mean)
        return ne
    W = np.ones(q.shape) if w is None else np.repeat(w[..., None], 2, axis=-1)
    if pb.weighting == "diagonal":
        W = W / residual_variances(obs, st.theta, pb.noise_model, L)
    st.W = W
    ne = NormalEquations(n, R)
    ne.update(G, q, W, valid=W > 0)
    return ne


def _has_converged(pb: _Problem, st: _State, w_prev: np.ndarray | None) -> np.ndarray:
    """Per run: the last θ correction below tolerance (robust: also stable weights)."""
    sol, R = st.sol, pb.R
    tol = TOLERANCE_RAD
    if pb.loss is not None:
        # DECISION: reweighting converges linearly; a robust fit has converged when θ moves by
        # less than 1e-3 of its σ (or 1e-6″) and no weight changes by more than 0.01.
        sd = np.sqrt(np.diagonal(sol.covariance, axis1=-2, axis2=-1)[:, :3]) * pb.cs[:3]
        tol = np.maximum(TOLERANCE_RAD, ROBUST_TOLERANCE_SIGMA * sd.min(axis=-1))
    converged = st.last_step < tol
    if pb.K:
        converged &= np.all(np.abs(sol.theta[:, 3:]) < 1e-9, axis=-1)
    if pb.loss is not None and w_prev is not None:
        converged &= np.max(np.abs(st.w - w_prev).reshape(R, -1), axis=1) < ROBUST_WEIGHT_TOLERANCE
    elif pb.loss is not None:
        converged[:] = False
    return converged


def _gauss_newton(pb: _Problem, st: _State, n_iter: int) -> _State:
    """Re-linearise and solve until every run has converged or ``n_iter`` iterations are done."""
    for it in range(1, n_iter + 1):
        st.it = it
        st.G, q, st.L = pb.linearise(st.theta, st.p)
        w_prev = st.w
        if pb.loss is not None:
            z, _ = pb.normalised(st.G, q, st.L, st.theta, st.w)
            # DECISION: Tukey's redescending loss starts from Huber weights (3 iterations) so a
            # far-off least-squares start cannot lock onto a wrong minimum.
            w = robust_weights(z, "huber" if (pb.loss == "tukey" and it <= 3) else pb.loss)
            st.w = w
        ne = _normal_equations(pb, st, q)
        st.sol = ne.solve(max_condition=pb.max_condition, labels=pb.labels if pb.K else None)
        step = st.sol.theta * pb.cs
        st.theta = st.theta + step[:, :3]
        if pb.K:
            st.p = st.p + step[:, 3:]
        st.last_step = np.max(np.abs(step[:, :3]), axis=-1)
        st.converged = _has_converged(pb, st, w_prev)
        if np.all(st.converged):
            break
    return st


def _covariance(pb: _Problem, st: _State) -> np.ndarray:
    """The joint covariance over [θ, extras] in scaled units (the prior combined, moving θ)."""
    from boresight.core.gls.campaign import sandwich_middle

    A: np.ndarray = st.sol.covariance
    sol, R = st.sol, pb.R
    if pb.weighting == "gls":
        return A
    if pb.modelled:
        WG = st.G * st.W[..., None]
        cov: np.ndarray = A @ sandwich_middle(pb.obs, st.theta, pb.noise_model, WG, st.L) @ A
    else:
        s2 = np.divide(sol.chi2, sol.dof, out=np.full(R, np.nan), where=sol.dof > 0)
        cov = A * s2[:, None, None]
    if pb.prior_info is not None:
        cov = _combine_prior(pb, st, cov)
    return cov


def _combine_prior(pb: _Problem, st: _State, cov: np.ndarray) -> np.ndarray:
    # DECISION: the prior is combined with the data-only estimate θ_d through the data's own
    # honest covariance C_d (the sandwich under the noise model, or A·χ²/dof without one):
    # θ = θ_d + (C_d⁻¹ + P)⁻¹ P (θ_prior − θ_d). Under GLS the prior enters the normal
    # equations directly — the same thing, since there C_d⁻¹ is the GLS information.
    P = pb.prior_info
    assert P is not None
    if not np.all(np.isfinite(cov)):
        raise ObservabilityError(
            "estimate: the data-only covariance is not finite (too few residual degrees of freedom), "
            "so a prior cannot be combined with it"
        )
    info_d = np.linalg.inv(cov)
    post = np.linalg.inv(info_d + P)
    post = 0.5 * (post + np.swapaxes(post, -1, -2))
    m = np.zeros((pb.R, pb.n))
    m[:, :3] = -st.theta / pb.cs[:3]  # prior mean 0 minus θ_d, in scaled units
    step = np.einsum("rij,jk,rk->ri", post, P, m) * pb.cs
    st.theta = st.theta + step[:, :3]
    if pb.K:
        st.p = st.p + step[:, 3:]
    return post


def _squeeze(a: Any, R: int) -> Any:
    return a[0] if R == 1 else a


def _model_statistics(
    pb: _Problem,
    st: _State,
    G: np.ndarray,
    q_final: np.ndarray,
    L: np.ndarray | None,
    z: np.ndarray,
    chi2m: Any,
    extra: dict[str, Any],
) -> tuple[Any, Any]:
    """χ² under the noise model (robust: of the observations kept) into ``extra``; returns (χ², χ²_model)."""
    obs, R, loss = pb.obs, pb.R, pb.loss
    chi2 = st.sol.chi2
    kept = None
    if pb.modelled and loss is not None:
        # DECISION: under a robust loss the weighted χ² is not χ²-distributed. The noise-model
        # statistic is the GLS χ² of the observations the fit treats as data: every observation
        # whose pixel-level residual length z is ≤ CHI2_INLIER_Z is kept (a clean one is cut with
        # probability exp(−z²/2) = 1e-5), the rest are excluded as outliers, and the GLS χ² of the
        # kept ones — per-image, per-pass and catalogue errors marginalised exactly, θ and the
        # floated parameters minimised — is χ²(2·kept − n) under the model, checked against its
        # own quantiles (docs/estimators.md, "Robust losses").
        keep = z <= CHI2_INLIER_Z
        chi2m = pb.gls(st.theta, G, q_final, L, keep.astype(np.float64)).normal_equations.solve(check=False).chi2
        chi2 = chi2m
        kept = keep.reshape(R, -1).sum(axis=1)
        extra["chi2_kept_observations"] = kept if R > 1 else int(kept[0])
    if pb.modelled:
        extra["chi2_model"] = _squeeze(chi2m, R)
        dofm = 2 * (obs.n_observations if kept is None else kept) - pb.n
        extra["dof_model"] = np.broadcast_to(dofm, (R,)).copy() if R > 1 else int(np.atleast_1d(dofm)[0])
    if pb.weighting == "unit" and loss is None:
        Wu = np.ones(q_final.shape) if st.w is None else np.repeat(st.w[..., None], 2, axis=-1)
        chi2 = np.einsum("rkc,rkc->r", q_final**2, Wu)
    return chi2, chi2m


def _with_common_fields(obs: Any, result: Estimate, model: DisturbanceModel | None) -> Estimate:
    """An estimator's result (Algorithm 1, the Kalman filter) with ``truth_arcsec`` (a simulated input's, as the
    least-squares fits return it) and ``whitened_residual_norm`` and ``largest_residuals`` at its θ: the quantity the
    least-squares fits return (``_Problem.normalised`` on Algorithm 3's linearisation, no extra unknowns, no robust
    weights), so every algorithm's largest normalised residuals are one statistic.

    DECISION: the statistic is taken at the estimator's θ whatever produced it, as the χ² under the model is
    (``_Problem.normalised``: "the noise-model consistency statistic whatever weighting produced θ"); Algorithm 3's
    rows are the focal-plane residuals every algorithm is judged on. Only the table's frame estimators get it: an
    estimator registered at run time returns what it returns (its input may be one Algorithm 3 cannot linearise)."""
    name, spec = resolve("image_plane")
    if result.chi2_model is None:  # a fit that tested no noise model (Algorithm 1): z over the robust scale, as it says
        model = None
    weighting = "gls" if has_pixel_noise(obs, model) else "unit"
    pb = _Problem(obs, name, spec, weighting, model, None, DEFAULT_MAX_CONDITION, ExtraParameters(obs, None, None), None)
    theta = result.theta_rad(obs.runs)
    G, q, L = pb.linearise(theta, np.zeros((obs.runs, 0)))
    z, _ = pb.normalised(G, q, L, theta)
    truth = result.truth_arcsec if result.truth_arcsec is not None else _truth_arcsec(obs, obs.runs)
    return dataclasses.replace(
        result, whitened_residual_norm=_squeeze(z, obs.runs), largest_residuals=_largest_residuals(obs, z), truth_arcsec=truth
    )


def _largest_residuals(obs: Any, z: np.ndarray, count: int = 5) -> tuple[tuple[int, str, float], ...]:
    """(image, landmark id, z) of the ``count`` largest normalised residuals (R, K) of the first run."""
    return top_residuals(obs.image_index, np.asarray(obs.landmark_ids)[obs.target_index], z[0], count)


def _downweighted(obs: Any, z: np.ndarray, w: np.ndarray, loss: str) -> tuple[tuple[int, str, float, float, str], ...]:
    """The robust fit's outlying observations of the first run, (image, landmark id, z, weight, why),
    largest z first (``z``, ``w``: (R, K) per observation)."""
    c = LOSSES[loss]
    rows = []
    # listed: z above the loss's constant (Huber: w < 1; Cauchy: w < 0.5; Tukey: w = 0)
    for k in np.flatnonzero(z[0] > c):
        zi, wi = float(z[0, k]), float(w[0, k])
        rows.append(
            (
                int(obs.image_index[k]),
                str(obs.landmark_ids[obs.target_index[k]]),
                zi,
                wi,
                f"normalised residual {zi:.1f} > {c} ({loss}), weight {wi:.3f}",
            )
        )
    return tuple(sorted(rows, key=lambda r: -r[2]))


def _effects(pb: _Problem, p: np.ndarray, cov_phys: np.ndarray) -> dict[str, Any]:
    """{effect: (value, σ)} Quantities of the extra parameters."""
    R, ext = pb.R, pb.ext
    effects = {}
    sig_p = np.sqrt(np.diagonal(cov_phys, axis1=-2, axis2=-1))[:, 3:]
    for gname, sl in ext.groups() if pb.K else ():
        unit = ext.units[sl.start]
        val, sg = p[:, sl], sig_p[:, sl]
        if sl.stop - sl.start == 1:
            val, sg = val[:, 0], sg[:, 0]
        effects[gname] = (_squeeze(val, R) * unit, _squeeze(sg, R) * unit)
    return effects


def _truth_arcsec(obs: Any, R: int) -> Any:
    """The file's true θ in arcsec, when it carries a finite one (else None)."""
    if obs.truth is None or "theta_rad" not in obs.truth:
        return None
    with np.errstate(over="ignore", invalid="ignore"):  # a file's truth is untrusted metadata
        t = np.asarray(obs.truth["theta_rad"], dtype=np.float64).reshape(-1, 3) / ARCSEC
    return _squeeze(t, R) if np.all(np.isfinite(t)) else None


def _final_residuals(pb: _Problem, st: _State) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, Any]:
    """(G, q, L, z, χ²_model) at the final (θ, extras)."""
    from boresight.core.gls.campaign import single_threaded_blas
    from boresight.core.gls.rows import row_residuals

    G, q_final, L = pb.linearise(st.theta, st.p)
    if pb.weighting == "gls":
        # the last fit's factors at its linearisation point, moved by the last (tiny) step
        with single_threaded_blas():
            e = row_residuals(st.last_fit, st.sol.theta)
        return G, q_final, L, np.linalg.norm(e, axis=-1), st.chi2_data
    z, chi2m = pb.normalised(G, q_final, L, st.theta, st.w)
    return G, q_final, L, z, chi2m


def _least_squares(
    obs: Any,
    name: str,
    spec: Registered,
    weighting: str,
    iterate: bool | int,
    model: DisturbanceModel | None,
    prior_sigma_arcsec: Any,
    theta0_arcsec: Any,
    max_condition: float,
    loss: str | None,
    effect_names: list[str] | None,
    extra_columns: Callable[..., Any] | None,
) -> Estimate:
    R = obs.runs
    n_iter = iteration_limit(iterate)
    if n_iter is None:
        n_iter = MAX_ITERATIONS if loss is None else MAX_ROBUST_ITERATIONS
    ext = ExtraParameters(obs, effect_names, extra_columns)
    pb = _Problem(obs, name, spec, weighting, model, loss, max_condition, ext, _prior_information(prior_sigma_arcsec, 3 + ext.K))
    theta = np.zeros((R, 3))
    if theta0_arcsec is not None:
        theta = np.broadcast_to(_three_numbers("theta0_arcsec", theta0_arcsec, (R, 3)) * ARCSEC, (R, 3)).copy()
    st = _gauss_newton(pb, _State(theta=theta, p=np.zeros((R, pb.K))), n_iter)

    # ---- covariance (joint over [θ, p], in the scaled units)
    cs, K = pb.cs, pb.K
    cov = _covariance(pb, st)
    cov = cov * cs[:, None] * cs[None, :]  # rad for θ, effect units for the extras
    S = np.concatenate([np.full(3, 1.0 / ARCSEC), np.ones(K)])
    cov_phys = cov * S[:, None] * S[None, :]  # arcsec and effect units

    # ---- final residuals, normalised residuals, χ² under the model
    G, q_final, L, z, chi2m = _final_residuals(pb, st)
    if weighting == "gls" and loss is not None:
        # the M-estimator's sandwich covariance replaces the fixed-weights inverse information
        cov = m_estimator_covariance(obs, st.theta, G, q_final, model, L, z, loss, pb.prior_info) * cs[:, None] * cs[None, :]
        cov_phys = cov * S[:, None] * S[None, :]
    extra: dict[str, Any] = {"loss": loss}
    chi2, chi2m = _model_statistics(pb, st, G, q_final, L, z, chi2m, extra)
    extra["whitened_residual_norm"] = _squeeze(z, R)
    extra["largest_residuals"] = _largest_residuals(obs, z)
    downweighted: tuple[Any, ...] = ()
    if loss is not None:
        assert st.w is not None  # a robust fit has weights
        extra["robust_weights"] = _squeeze(st.w, R)
        downweighted = _downweighted(obs, z, st.w, loss)
    if K:
        extra["joint_covariance"] = _squeeze(cov_phys, R)
        extra["joint_labels"] = ("theta_x", "theta_y", "theta_z") + ext.labels
        extra["joint_units"] = (u.arcsec,) * 3 + ext.units
        extra["effect_status"] = ext.status
    truth = _truth_arcsec(obs, R)
    if truth is not None:
        extra["truth_arcsec"] = truth

    prior_rad = None if pb.prior_info is None else pb.prior_info / (cs[:, None] * cs[None, :])
    warnings = estimate_warnings(
        obs,
        st.theta,
        cov,
        prior_rad,
        st.converged,
        st.last_step,
        st.it,
        chi2m if pb.modelled else None,
        extra.get("dof_model"),
        pb.modelled,
        loss,
        ext.status,
        extra.get("chi2_kept_observations"),
        tolerance_rad=TOLERANCE_RAD,
        unit_slips=extra.setdefault("unit_slips", tuple(model_unit_slips(model)) if pb.modelled else ()),
        outlier_hint=_outlier_hint(obs, spec, ext.names if K else []),
    )
    if loss is not None:
        rejected = rejection_warning(obs, z, st.w, loss)
        if rejected is not None:
            warnings = list(warnings) + [rejected]
    if pb.weighting == "gls" and st.last_fit is not None:
        from boresight.core.gls.rows import condition_warning

        cond = condition_warning(st.last_fit)
        if cond is not None:
            warnings = list(warnings) + [cond]
    includes = sigma_includes(
        model if pb.modelled else None, weighting, pb.prior_info is not None, K, loss, getattr(pb.obs, "sigma_xy_m", None)
    )
    dof = np.broadcast_to(extra["dof_model"], (R,)) if pb.modelled and loss is not None else st.sol.dof
    return Estimate(
        theta=_squeeze(st.theta / ARCSEC, R) * u.arcsec,
        covariance=_squeeze(cov[:, :3, :3] / ARCSEC**2, R) * u.arcsec**2,
        residuals=_squeeze(q_final, R),
        chi2=_squeeze(chi2, R),
        dof=_squeeze(dof, R),
        condition_number=_squeeze(st.sol.condition_number, R),
        iterations=st.it,
        converged=_squeeze(st.converged, R),
        algorithm=name,
        weighting=weighting,
        residual_unit=spec.residual_unit,
        **extra,  # the typed diagnostic fields (chi2_model, joint_covariance, …), named as Estimate's
        warnings=tuple(warnings),
        sigma_includes=includes,
        effects=_effects(pb, st.p, cov_phys),
        downweighted=downweighted,
    )


def _outlier_hint(obs: Any, spec: Any, floated: list[str]) -> str:
    """What a χ² too high suggests: outliers — or, on a set of star and landmark rows fitted without the
    effects star rows separate (``default_effects`` switched off), the two kinds disagreeing."""
    from boresight.core.result import OUTLIER_HINT
    from boresight.core.weighting import SEPARABLE_BY_STARS

    _, defaults = default_effects(obs, spec, None)
    missing = [n for n in defaults if n not in floated]
    if not missing:
        return OUTLIER_HINT
    return (
        f"star and landmark rows disagree? {', '.join(missing)} is not floated (the default on such a set floats "
        f"{', '.join(SEPARABLE_BY_STARS)}); boresight diagnose names what differs; or outliers: a robust loss"
    )
