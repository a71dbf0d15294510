"""Variance components: the scale of each error source of the noise model, estimated from the residuals.

The campaign residuals are (``boresight.core.gls.campaign``) q = X x + ε + Σ_k Z_k a_k: pixel noise ε
(σK² per component) and the shared errors of each source k — star tracker per image, star tracker per
pass, GNSS, catalogue — with columns Z_k scaled by the source's σ so that a_k ~ N(0, E). A wrong σ is a
wrong covariance Σ(λ) = λ_pix σK² E + Σ_k λ_k Z_k Z_kᵀ; the variance factors λ (1 = as declared) are
estimated by **restricted maximum likelihood** (REML), the likelihood of the residuals with x
integrated out (Koch, *Parameter Estimation and Hypothesis Testing in Linear Models*, 2nd ed. 1999,
§3.6 "Estimation of variance and covariance components"; Koch & Kusche, J. Geodesy 76:259–268, 2002).
Its score equations are

    ∂ℓ_R/∂λ_k = ½ [ qᵀ Σ⁻¹ V_k Σ⁻¹ q̂ − tr(P V_k) ] = 0,     P = Σ⁻¹ − Σ⁻¹X (XᵀΣ⁻¹X)⁻¹ XᵀΣ⁻¹,

(V_k = ∂Σ/∂λ_k, q̂ the GLS residual). Written in the units of the current model (λ = 1 there):

* the quadratic form is g_k = |â_k|², the squared norm of the source's **MAP nuisances**
  â_k = Z_kᵀ Σ⁻¹ q̂ (the BLUP of the errors). With the pixel-whitened residual e = σK Σ⁻¹ q̂ that the GLS
  back-substitution returns (``gls.rows.row_residuals``: what is left after the MAP per-image, per-pass and
  catalogue errors are removed, in units of σK), â_k = (Z_k/σK)ᵀ e summed over the rows each nuisance
  touches, and for the pixel noise g_pix = |e|²;
* the trace is the source's **redundancy** r_k = tr(Z_kᵀ P Z_k) = E[g_k] under the current model
  (Förstner 1979's redundancy of a variance component; Σ_k r_k + r_pix = n − p).

The fixed point of REML is then **λ_k ← λ_k g_k / r_k** for every source at once, the iteration of
Förstner (1979) and Koch & Kusche (2002) (Helmert's and REML's estimators share it at convergence). The
redundancies are traces of products of the inverse covariance, which the block-sparse GLS does not form;
they are computed by **Monte Carlo** as Kusche (2003, "A Monte-Carlo technique for weight estimation in
satellite geodesy", J. Geodesy 76:641–652) does for large problems: r_k = E[g_k(y*)] for simulated
residuals y* ~ N(0, Σ) run through the same GLS (``gls.campaign.fit_rows`` + ``rows.row_residuals``: the public
functions, so this works on any layout of the GLS internals), one row per observation
(``docs/architecture.md``, "The row model": per-image, per-pass and per-target sums are bincounts over
the rows, no images × targets array). The same samples give the Fisher
information of λ: F_kj = ½ tr(P V_k P V_j) = ¼ cov(g_k, g_j) (quadratic forms of a Gaussian vector),
and each scale's σ from F⁻¹ (σ_σ = ½ σ √(F⁻¹)_kk, the delta method on σ = √λ σ_declared).

DECISION: the random draws are fixed by ``seed`` and re-used in every iteration (common random numbers),
so the fixed point is a smooth function of λ and the result reproducible; ``samples`` = 16 gives r_k to
≈ √(2/(16 r_k)) relative (≤ 7 % for r_k ≥ 25, i.e. σ to 3.5 %) during the iteration, which stops when no
σ moves by more than ``tolerance`` = 2 % or when θ's GLS σ moves by less than ``theta_tolerance`` = 0.5 %
from one iteration to the next (sources the data barely tell apart — per-image star tracker about z and
GNSS — creep along their shared direction for tens of iterations without changing θ's σ); ``final_samples`` = 48 fresh draws then give the redundancies
and the Fisher information at the estimate (each scale's σ to ≈ 10 %). Fisher scoring (Newton) was tried
instead of the fixed point and did not converge: its Monte Carlo F is noisy along the direction two
sources share (per-image star tracker and GNSS are both nearly a rotation of the image), and steps along
it oscillated; the fixed point creeps along that direction but θ's σ depends on their sum, which it
fixes in the first iterations. A source whose
redundancy is tiny (r_k < 1: the data barely see it) keeps its declared scale, and says so.
DECISION: one factor per source and, for the star tracker, per axis (an attitude jitter about one axis
must not be spread over three: with one factor for the three axes a 10″ jitter about x was sized at
4.3″ on every axis, GNSS took the rest and θ stayed 3.3σ off); GNSS per image and per pass scaled together
(one σ in the model). A source the data barely see keeps its scale (``MIN_REDUNDANCY``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.campaign import fit_rows
from boresight.core.gls.rows import RowStructure, row_residuals
from boresight.core.gls.structure import error_columns, row_pixel_sigma
from orbits.rotations import ARCSEC

__all__ = ["VarianceComponent", "VarianceComponents", "variance_components", "variance_components_at", "SOURCES"]

_AXES = ("x", "y", "z")
#: the sources a variance factor can be estimated for (the star tracker one per axis), with their display unit
SOURCES = {
    "pixel": "um",
    **{f"star_tracker_image_{a}": "arcsec" for a in _AXES},
    **{f"star_tracker_pass_{a}": "arcsec" for a in _AXES},
    "gnss": "m",
    "catalogue": "m",
}
_LABEL = {
    "pixel": "pixel noise",
    **{f"star_tracker_image_{a}": f"star tracker per image, {a} axis" for a in _AXES},
    **{f"star_tracker_pass_{a}": f"star tracker per pass, {a} axis" for a in _AXES},
    "gnss": "GNSS",
    "catalogue": "catalogue",
}
_TO_DISPLAY = {"um": 1e6, "arcsec": 1.0 / ARCSEC, "m": 1.0}
#: a source whose redundancy is below this keeps its declared scale (the data do not see it)
MIN_REDUNDANCY = 1.0
#: a variance factor below this (σ < 1 % of the declared) is a source the data do not have: set to 0
MIN_FACTOR = 1e-4
#: a source below this factor (σ < 10 % of the declared, < 1 % of its variance) no longer holds up the
#: convergence test: it creeps to zero at the pace of the fixed point and changes nothing else
NEGLIGIBLE_FACTOR = 1e-2


@dataclass(frozen=True)
class VarianceComponent:
    """One source: declared and estimated σ (display unit; the largest star-tracker axis), the σ of
    the estimate, the variance factor λ = (estimate/declared)², its redundancy r (the data's
    degrees of freedom for it) and whether the data determined it."""

    source: str
    label: str
    unit: str
    declared: float
    estimate: float
    sigma: float
    factor: float
    redundancy: float
    determined: bool
    added: bool = False

    def text(self) -> str:
        """``star tracker per image, x axis: declared 1.5 arcsec, the data say 2.2 ± 0.1 arcsec``."""
        unit = "µm" if self.unit == "um" else self.unit
        if self.added:
            if not self.determined or self.estimate == 0:
                return f"{self.label}: not in the declared model, and the data do not ask for it"
            return f"{self.label}: not in the declared model, the data say {self.estimate:.3g} ± {self.sigma:.2g} {unit}"
        if not self.determined:
            return f"{self.label}: declared {self.declared:.3g} {unit}, kept (redundancy {self.redundancy:.2g}: the data barely see it)"
        return f"{self.label}: declared {self.declared:.3g} {unit}, the data say {self.estimate:.3g} ± {self.sigma:.2g} {unit}"

    def as_json(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "unit": self.unit,
            "declared": self.declared,
            "estimate": self.estimate,
            "sigma": self.sigma,
            "factor": self.factor,
            "redundancy": self.redundancy,
            "determined": self.determined,
            "added": self.added,
        }


@dataclass(frozen=True)
class VarianceComponents:
    """The estimated scales, the noise model they give, and how the estimate went."""

    components: tuple[VarianceComponent, ...]
    model: DisturbanceModel
    declared_model: DisturbanceModel
    converged: bool
    iterations: int
    samples: int
    chi2_dof_before: float
    chi2_dof_after: float
    kurtosis: dict[str, float] = field(default_factory=dict)
    kurtosis_n: dict[str, int] = field(default_factory=dict)
    method: str = "REML (Förstner / Koch–Kusche iteration, Monte Carlo redundancies, Kusche 2003)"
    #: the factor the pixel scale puts on every row's own σ (``ObservationSet.sigma_xy_m``): √λ_pixel; 1 without them
    pixel_factor: float = 1.0

    def scaled_rows(self, obs: Any) -> Any:
        """``obs`` with the rows' own pixel σ scaled by the estimated pixel factor (``model`` scales the
        noise model's σK alike): refit a set whose rows carry their own σ under ``model`` on these rows."""
        if getattr(obs, "sigma_xy_m", None) is None or self.pixel_factor == 1.0:
            return obs
        return obs.with_sigma_xy(obs.sigma_xy_m * self.pixel_factor)

    @property
    def heavy_tailed(self) -> bool:
        """Excess kurtosis of the normalised pixel residuals or of the per-image errors above
        max(1, 4 √(24/n)): Gaussian errors give 0 with standard error √(24/n) (n values), so 4 of
        those is a false alarm below 1e-4 per statistic; Student-t with 5 degrees of freedom gives 6."""
        return any(v > max(1.0, 4.0 * np.sqrt(24.0 / max(self.kurtosis_n.get(k, 1), 1))) for k, v in self.kurtosis.items())

    def lines(self) -> list[str]:
        return [c.text() for c in self.components]

    def as_json(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "components": [c.as_json() for c in self.components],
            "lines": self.lines(),
            "converged": self.converged,
            "iterations": self.iterations,
            "samples": self.samples,
            "chi2_dof_before": self.chi2_dof_before,
            "chi2_dof_after": self.chi2_dof_after,
            "excess_kurtosis": dict(self.kurtosis),
            "kurtosis_n": dict(self.kurtosis_n),
            "heavy_tailed": self.heavy_tailed,
        }


# ---------------------------------------------------------------------------- the sources of a model


def _sources(model: DisturbanceModel, extra_pass_rotation_rad: float) -> dict[str, np.ndarray]:
    """Declared σ (SI) per source, star-tracker axes as (3,) arrays; only sources with σ > 0.

    A per-pass star-tracker error in mode ``both`` and the model's extra per-pass rotation are the same
    columns (rotations about the star-tracker axes shared by a pass): one source; ``extra_pass_rotation_rad``
    adds that source at this starting σ when the model has none (a per-pass structure to size)."""
    st = np.asarray(model.sigma_star_tracker_rad, float)
    out: dict[str, np.ndarray] = {"pixel": np.array([model.sigma_pixel_m])}
    img = st if model.star_tracker_mode in ("per_image", "both") else np.zeros(3)
    img = np.sqrt(img**2 + np.asarray(model.sigma_image_rotation_rad, float) ** 2)
    pas = st if model.star_tracker_mode in ("per_pass", "both") else np.zeros(3)
    pas = np.sqrt(pas**2 + np.asarray(model.sigma_pass_rotation_rad, float) ** 2)
    if not np.any(pas > 0) and extra_pass_rotation_rad > 0:
        pas = np.full(3, float(extra_pass_rotation_rad))
    for kind, v in (("image", img), ("pass", pas)):
        for j, a in enumerate(_AXES):
            if v[j] > 0:
                out[f"star_tracker_{kind}_{a}"] = v * (np.arange(3) == j)
    if model.sigma_gnss_m > 0:
        out["gnss"] = np.array([model.sigma_gnss_m])
    if model.sigma_catalogue_m > 0:
        out["catalogue"] = np.array([model.sigma_catalogue_m])
    return out


def _model(declared: DisturbanceModel, sig: dict[str, np.ndarray]) -> DisturbanceModel:
    """The noise model with the sources' σ ``sig`` (SI), star-tracker per image and per pass as
    independent columns (mode ``per_image`` + the per-pass rotation)."""
    zero = (0.0, 0.0, 0.0)
    return DisturbanceModel(
        sigma_pixel_m=float(sig["pixel"][0]),
        sigma_star_tracker_rad=tuple(_axes_sum(sig, "star_tracker_image")),
        star_tracker_mode="per_image",
        sigma_gnss_m=float(sig.get("gnss", [0.0])[0]),
        gnss_mode=declared.gnss_mode,
        sigma_catalogue_m=float(sig.get("catalogue", [0.0])[0]),
        sigma_image_rotation_rad=zero,
        sigma_pass_rotation_rad=tuple(_axes_sum(sig, "star_tracker_pass")),
    )


def _axes_sum(sig: dict[str, np.ndarray], kind: str) -> np.ndarray:
    """The (3,) σ of the per-axis star-tracker sources of ``kind`` (each has one axis nonzero)."""
    out: np.ndarray = np.sqrt(sum((sig[n] ** 2 for n in sig if n.startswith(kind)), np.zeros(3)))
    return out


def _source_columns(obs: Any, theta_rad: Any, name: str, s: np.ndarray, gnss_mode: str, rows: Any) -> tuple[Any, Any, Any]:
    """(per-image, per-pass, catalogue) columns of one source at σ ``s`` (SI) on the ``rows``, each (1, K, 2, ·) or None."""
    tiny = 1.0  # the pixel σ does not enter the columns
    if name.startswith("star_tracker_image"):
        m = DisturbanceModel(sigma_pixel_m=tiny, sigma_star_tracker_rad=tuple(s), star_tracker_mode="per_image")
    elif name.startswith("star_tracker_pass"):
        m = DisturbanceModel(sigma_pixel_m=tiny, sigma_pass_rotation_rad=tuple(s))
    elif name == "gnss":
        m = DisturbanceModel(sigma_pixel_m=tiny, sigma_gnss_m=float(s[0]), gnss_mode=gnss_mode)
    else:
        m = DisturbanceModel(sigma_pixel_m=tiny, sigma_catalogue_m=float(s[0]))
    cols: tuple[Any, Any, Any] = error_columns(obs, theta_rad, m, None, rows=rows)
    return cols


#: the pixel-noise draws follow the old per-image slot order (image n's m_n rows in the first m_n of
#: max_n m_n slots) while that grid holds at most this many cells per row, so every result is the one
#: drawn before the row model; beyond (one image with far more rows than the rest) one pair per row
SLOT_DRAW_MAX_CELLS_PER_ROW = 64


def _sum_by(index: np.ndarray, size: int, values: np.ndarray) -> np.ndarray:
    """Σ of ``values`` (1, K, k) over the rows of each ``index`` (K,) value: (1, size, k)."""
    out = np.zeros((values.shape[0], size, values.shape[-1]))
    np.add.at(out, (slice(None), index), values)  # type: ignore[arg-type]
    return out


# ---------------------------------------------------------------------------- the estimator


class _Residuals:
    """The data of one estimate: the sources' unit columns, the draws, and the three operations of
    the iteration — the GLS fit under factors λ, the quadratic forms g_k of a whitened residual, and
    a residual simulated under λ. Everything per row (K rows of the one run)."""

    def __init__(self, obs: Any, theta_rad: Any, G: Any, q: Any, model: DisturbanceModel, extra_pass: float) -> None:
        self.obs, self.theta, self.G, self.q, self.model = obs, theta_rad, G, q, model
        self.structure = RowStructure.of(obs)
        self.img, self.tgt = self.structure.image_index, self.structure.target_index
        rows = (self.img, self.tgt)
        self.n_rows, self.n_images, self.n_targets = self.img.size, int(obs.n_images), int(obs.n_targets)
        self.declared = _sources(model, extra_pass)
        # a set whose rows carry their own pixel σ: one pixel factor scales them and σK alike; the pixel
        # component is shown on the rows' RMS σ when every row has its own (σK then unused), else on σK
        self.own = None if getattr(obs, "sigma_xy_m", None) is None else np.asarray(obs.sigma_xy_m, float)
        if self.own is not None and (np.all(np.isfinite(self.own)) or not model.sigma_pixel_m > 0):
            self.declared["pixel"] = np.array([float(np.sqrt(np.nanmean(self.own**2)))])
        plain = _sources(model, 0.0)
        self.extra = {n: n not in plain for n in self.declared}
        self.names = list(self.declared)
        self.cols = {
            n: _source_columns(obs, theta_rad, n, self.declared[n], model.gnss_mode, rows) for n in self.names if n != "pixel"
        }
        self.pidx = self.structure.pass_of_image
        self.n_pass = self.structure.n_passes
        # each row's cell in the per-image slot grid (N, Mx) of the old draw order (SLOT_DRAW_MAX_CELLS_PER_ROW)
        counts = np.bincount(self.img, minlength=self.n_images)
        self.mx = max(int(counts.max()), 1) if counts.size else 1
        self.slot_cell = self.img * self.mx + (np.arange(self.n_rows) - self.structure.row_start[self.img])

    def _pixel_draw(self, rng: np.random.Generator) -> np.ndarray:
        """Standard normal pixel noise (1, K, 2): the rows' cells of an (1, N, Mx, 2) draw while that grid is
        small (the draw order of the slot layout, so results are unchanged), one pair per row beyond."""
        if self.n_images * self.mx <= SLOT_DRAW_MAX_CELLS_PER_ROW * max(self.n_rows, 1):
            grid = rng.standard_normal((1, self.n_images * self.mx, 2))
            out: np.ndarray = grid[:, self.slot_cell]
            return out
        return rng.standard_normal((1, self.n_rows, 2))

    def draws(self, samples: int, seed: int) -> list[dict[str, Any]]:
        """Pixel noise and each source's N(0, E) nuisances, ``samples`` times (common random numbers)."""
        rng = np.random.default_rng(seed)
        out = []
        for _ in range(samples):
            d: dict[str, Any] = {"pixel": self._pixel_draw(rng)}
            for n, (A, B, C) in self.cols.items():
                d[n] = (
                    None if A is None else rng.standard_normal((1, self.n_images, A.shape[-1])),
                    None if B is None else rng.standard_normal((1, self.n_pass, B.shape[-1])),
                    None if C is None else rng.standard_normal((1, self.n_targets, 3)),
                )
            out.append(d)
        return out

    def model_at(self, lam: dict[str, float]) -> DisturbanceModel:
        sig = {n: self.declared[n] * np.sqrt(lam[n]) for n in self.names}
        if self.own is not None:  # σK scales with the pixel factor (the rows' own σ in ``obs_at``)
            sig["pixel"] = np.array([self.model.sigma_pixel_m * np.sqrt(lam["pixel"])])
        return _model(self.model, sig)

    def obs_at(self, lam: dict[str, float]) -> Any:
        """The observations with their own pixel σ (if any) scaled by the pixel factor √λ_pixel."""
        return self.obs if self.own is None else self.obs.with_sigma_xy(self.own * np.sqrt(lam["pixel"]))

    def pixel_sigma(self, lam: dict[str, float]) -> Any:
        """The pixel σ under λ: σK √λ_pixel, or each row's (1, K, 2) for a set with its own σ."""
        if self.own is not None:
            rows = cast(np.ndarray, row_pixel_sigma(self.obs_at(lam), self.model_at(lam)))  # (K, 2): the set has its own σ
            return rows[None]
        return float(self.declared["pixel"][0] * np.sqrt(lam["pixel"]))

    def fit(self, lam: dict[str, float], q: np.ndarray) -> tuple[np.ndarray, float, float]:
        """The pixel-whitened residual e (1, K, 2) of the GLS on rows under λ, its χ² and dof."""
        gls = fit_rows(self.obs_at(lam), self.theta, self.G, q, self.model_at(lam))
        sol = gls.normal_equations.solve(check=False)
        self.sigma_theta = np.sqrt(np.diag(sol.covariance[0])[:3])
        return row_residuals(gls, sol.theta), float(sol.chi2[0]), float(sol.dof[0])

    def per_image(self, Z: np.ndarray, e: np.ndarray) -> np.ndarray:
        """Zᵀe summed over each image's rows, (1, N, k)."""
        return _sum_by(self.img, self.n_images, np.einsum("rkja,rkj->rka", Z, e))

    def quad(self, e: np.ndarray, lam: dict[str, float]) -> dict[str, float]:
        """g_k = |â_k|², â_k = (Z_k/σK)ᵀ e summed over the rows each nuisance touches."""
        g = {"pixel": float(np.sum(e**2))}
        s_pix = self.pixel_sigma(lam)
        if self.own is not None:  # each row's σ: â_k = Σ_rows (Z_k / σ_row)ᵀ e (σK² → 1 below)
            e, s_pix = e / s_pix, 1.0
        for n, (A, B, C) in self.cols.items():
            tot = 0.0
            if A is not None:
                tot += float(np.sum(self.per_image(A, e) ** 2))
            if B is not None:
                per_pass = np.zeros((1, self.n_pass, B.shape[-1]))
                np.add.at(per_pass, (slice(None), self.pidx), self.per_image(B, e))  # type: ignore[arg-type]
                tot += float(np.sum(per_pass**2))
            if C is not None:
                per_lm = _sum_by(self.tgt, self.n_targets, np.einsum("rkja,rkj->rka", C, e))
                tot += float(np.sum(per_lm**2))
            g[n] = tot * lam[n] / s_pix**2
        return g

    def simulated(self, d: dict[str, Any], lam: dict[str, float]) -> np.ndarray:
        """A residual y* ~ N(0, Σ(λ)) (m) from the draws ``d``, (1, K, 2)."""
        y: np.ndarray = d["pixel"] * self.pixel_sigma(lam)
        for n, (A, B, C) in self.cols.items():
            f = np.sqrt(lam[n])
            a, b, c = d[n]
            if A is not None:
                y = y + f * np.einsum("rkja,rka->rkj", A, a[:, self.img])
            if B is not None:
                y = y + f * np.einsum("rkja,rka->rkj", B, b[:, self.pidx[self.img]])
            if C is not None:
                y = y + f * np.einsum("rkja,rka->rkj", C, c[:, self.tgt])
        return y


def variance_components(
    obs: Any,
    theta_rad: Any,
    G: Any,
    q: Any,
    model: DisturbanceModel,
    *,
    extra_pass_rotation_rad: float = 0.0,
    samples: int = 16,
    final_samples: int = 48,
    seed: int = 0,
    max_iterations: int = 30,
    tolerance: float = 0.02,
    theta_tolerance: float = 0.005,
) -> VarianceComponents:
    """Estimate the scale of each error source of ``model`` from the residuals (module docstring).

    ``obs`` one run; ``G`` (1, K, 2, n) the Jacobian of q with respect to the fitted parameters x
    (θ first) and ``q`` (1, K, 2) the residuals at θ, one row per observation in the set's canonical
    order. Image-plane
    residuals (no ``residual_map``). ``extra_pass_rotation_rad``: also size a per-pass rotation when
    the model has no per-pass star-tracker error. Returns the components, the noise model with the
    estimated scales (``model``) and the χ²/dof of the GLS before and after.
    """
    from boresight.errors import BoresightError, InputValueError

    if obs.runs != 1:
        raise BoresightError(f"variance_components: one run at a time, got {obs.runs}")
    if samples < 4:
        raise InputValueError(f"variance_components: samples must be ≥ 4, got {samples!r}")
    G, q = np.asarray(G, float), np.asarray(q, float)
    if q.shape != (1, obs.n_observations, 2) or G.shape[:3] != q.shape:
        raise InputValueError(
            f"variance_components: G (1, K, 2, n) and q (1, K, 2) on the {obs.n_observations} rows, got {G.shape}, {q.shape}"
        )
    P = _Residuals(obs, theta_rad, G, q, model, extra_pass_rotation_rad)
    draws = P.draws(samples, seed)
    lam = {n: 1.0 for n in P.names}
    seen: list[str] = []
    chi2_before = np.nan
    converged = False
    it = 0
    r: dict[str, float] = {}
    gs: list[dict[str, float]] = []
    sig_prev = None
    for it in range(1, max_iterations + 1):
        e, chi2, dof = P.fit(lam, q)
        if it == 1:
            chi2_before = chi2 / dof
        # θ's σ (what is quoted) has settled: the split between sources the data barely tell apart
        # may still creep, at the fixed point's slow pace, without changing it
        if sig_prev is not None and np.max(np.abs(P.sigma_theta / sig_prev - 1.0)) < theta_tolerance:
            converged = True
            break
        sig_prev = P.sigma_theta
        g = P.quad(e, lam)
        gs = [P.quad(P.fit(lam, P.simulated(d, lam))[0], lam) for d in draws]
        r = {n: float(np.mean([x[n] for x in gs])) for n in P.names}
        if it == 1:  # the sources the data see at their declared scale
            seen = [n for n in P.names if r[n] >= MIN_REDUNDANCY]
        # the REML fixed point (Förstner; Koch & Kusche 2002); a source the data barely see keeps its scale
        new = {n: (lam[n] * max(g[n], 0.0) / r[n] if n in seen else lam[n]) for n in P.names}
        change = 0.5 * max((abs(np.log(new[n] / lam[n])) for n in seen if new[n] > NEGLIGIBLE_FACTOR), default=0.0)
        lam = new
        if change < tolerance:
            converged = True
            break
    for n in P.names:
        if P.extra[n] and (n not in seen or lam[n] < NEGLIGIBLE_FACTOR):  # an undeclared source the data do not ask for
            lam[n] = 0.0
        elif lam[n] < MIN_FACTOR:
            lam[n] = 0.0
    # the redundancies and the Fisher information at the estimate, with more draws
    gs = [P.quad(P.fit(lam, P.simulated(d, lam))[0], lam) for d in P.draws(final_samples, seed + 1)]
    r = {n: float(np.mean([x[n] for x in gs])) for n in P.names}
    e, chi2, dof = P.fit(lam, q)
    kurt, kurt_n = _kurtosis(e, P)
    return VarianceComponents(
        components=_components(P, lam, r, gs, seen),
        model=P.model_at(lam),
        declared_model=model,
        converged=converged,
        iterations=it,
        samples=final_samples,
        chi2_dof_before=float(chi2_before),
        chi2_dof_after=float(chi2 / dof),
        kurtosis=kurt,
        kurtosis_n=kurt_n,
        pixel_factor=1.0 if P.own is None else float(np.sqrt(lam["pixel"])),
    )


def variance_components_at(obs: Any, theta_rad: Any, model: DisturbanceModel, **options: Any) -> VarianceComponents:
    """The variance components of ``model`` on the image-plane residuals of one run at θ (Algorithm 3,
    ``boresight.core.measurement.linearize``; θ the only fitted parameters): what
    ``boresight estimate --variance-components`` computes at its GLS θ. ``options`` as
    ``variance_components``."""
    from boresight.core.measurement import linearize

    theta = np.asarray(theta_rad, float).reshape(-1)[:3]
    G, q = linearize(obs, theta)  # one row per observation
    return variance_components(obs, theta, G, q, model, **options)


def _components(
    P: _Residuals, lam: dict[str, float], r: dict[str, float], gs: list[dict[str, float]], seen: list[str]
) -> tuple[VarianceComponent, ...]:
    """Each source's estimate and σ: the Fisher information of the factors (relative to the
    estimate) is ¼ cov(g) over the draws of the last iteration; σ_σ = ½ σ √(F⁻¹)_kk."""
    det = [n for n in seen if r.get(n, 0.0) > 0]
    var_rel: dict[str, float] = {n: np.inf for n in det}
    if len(gs) > len(det) and det:
        F = 0.25 * np.atleast_2d(np.cov(np.array([[x[n] for n in det] for x in gs]), rowvar=False))
        try:
            var_rel = dict(zip(det, np.diag(np.linalg.inv(F)).tolist()))
        except np.linalg.LinAlgError:
            pass
    out = []
    for n in P.names:
        unit = SOURCES[n]
        start = float(np.max(P.declared[n])) * _TO_DISPLAY[unit]
        est = start * float(np.sqrt(lam[n]))
        dec = 0.0 if P.extra[n] else start
        vr = float(var_rel.get(n, np.inf))
        sd = 0.5 * est * float(np.sqrt(vr)) if np.isfinite(vr) and vr >= 0 else float("inf")
        out.append(
            VarianceComponent(n, _LABEL[n], unit, dec, est, sd, float(lam[n]), float(r.get(n, 0.0)), n in seen, P.extra[n])
        )
    return tuple(out)


def _kurtosis(e: np.ndarray, P: _Residuals) -> tuple[dict[str, float], dict[str, int]]:
    """Excess kurtosis of the normalised pixel residuals e (1, K, 2) and of each image's projection
    of them on the per-image star-tracker columns (the per-image errors), with the number of values:
    0 for Gaussian errors, large for heavy tails."""
    from scipy import stats

    px = e[0].reshape(-1)
    out, n = {"pixel": float(stats.kurtosis(px))}, {"pixel": int(px.size)}
    A = [c[0] for name, c in P.cols.items() if name.startswith("star_tracker_image")]
    if A:
        a = P.per_image(np.concatenate(A, axis=-1), e)[0]  # (N, k)
        a = a / np.maximum(a.std(axis=0, keepdims=True), 1e-300)
        out["image"] = float(stats.kurtosis(a.reshape(-1)))
        n["image"] = int(a.size)
    return out, n
