"""What ``estimate`` returns: the ``Estimate`` type, its summary, the χ²/dof band it is checked
against, what σ includes and the plain-language warnings (``docs/estimators.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from astropy import units as u

from boresight.core.robust import CHI2_INLIER_Z
from boresight.stats import CHI2_LEVEL, chi2_band, chi2_outside
from orbits.rotations import ARCSEC

__all__ = [
    "Estimate",
    "CHI2_LEVEL",
    "model_parts",
    "model_unit_slips",
    "noise_model_text",
    "sigma_includes",
    "estimate_warnings",
    "SMALL_ANGLE_LIMIT_ARCSEC",
    "PRIOR_DOMINANCE",
    "small_angle_warning",
    "top_residuals",
]

#: |θ| beyond which the estimate is flagged: the one small-angle range (orbits.rotations, 10°)
from orbits.rotations import SMALL_ANGLE_LIMIT_ARCSEC  # noqa: E402 - re-exported

#: a prior "dominates" an axis when it carries more than this share of the posterior information
PRIOR_DOMINANCE = 0.5


def small_angle_warning(theta_arcsec: Any, tag: str = "") -> str | None:
    """The warning for a θ (3,) arcsec outside the small-angle range, or None (every algorithm's:
    the least-squares warnings below and ``boresight.core.consistency`` for the others)."""
    mag = float(np.linalg.norm(theta_arcsec))
    if not mag > SMALL_ANGLE_LIMIT_ARCSEC:
        return None
    return (
        f"{tag}|θ| = {mag:.4g}″ is outside the small-angle range |θ| ≤ {SMALL_ANGLE_LIMIT_ARCSEC:.0f}″ "
        f"({SMALL_ANGLE_LIMIT_ARCSEC / 3600:g}°) the error model assumes — check the conventions (boresight check)"
    )


@dataclass(frozen=True)
class Estimate:
    """The result of ``estimate``. The run axis is dropped when the input has one run.

    Attributes
    ----------
    theta : astropy.units.Quantity
        θ in arcsec, (R, 3) or (3,) (Kiev 2012 eq 24 sign, ``docs/conventions.md``).
    covariance : astropy.units.Quantity
        Its covariance in arcsec², (R, 3, 3) or (3, 3); ``sigma`` is the square root of the diagonal.
    residuals : numpy.ndarray
        (R, K, 2) final residuals (measured − predicted) in ``residual_unit``, one row per observation
        in the set's canonical (image, target) order (``image_index``, ``target_index``).
    chi2, dof : numpy.ndarray
        The minimised weighted sum of squares (for ``unit`` weighting the plain sum of squares in
        ``residual_unit`` squared) and its degrees of freedom.
    condition_number : numpy.ndarray
        Of the normal matrix of θ (prior included).
    iterations : int
        Gauss-Newton iterations.
    converged : numpy.ndarray
        Whether the last correction was below 1e-6″ (robust fits: 1e-3 σ and stable weights).
    algorithm, weighting : str
        The algorithm (registry name) and the weighting (``unit``, ``diagonal``, ``gls``).
    residual_unit : str
        The unit of ``residuals``.
    warnings : tuple of str
        Plain-language reasons not to trust the result: non-convergence, θ outside the small-angle
        range, χ²/dof inconsistent with the noise model, a dominant prior, no noise model.
    sigma_includes : str
        What σ contains (which noise sources, at which weighting).
    effects : dict
        {name: (value, σ)} Quantities of the effects floated jointly with θ.
    downweighted : tuple
        (image, landmark id, z, weight, why) of the robust fit's outlying observations (first run).
    loss : str or None
        The robust loss of the fit (``huber``, ``cauchy``, ``tukey``), None for least squares.
    chi2_model, dof_model : numpy.ndarray, float or None
        χ² under the noise model and its degrees of freedom (robust fits: of the observations kept;
        the Kalman filter: Σ NIS and Σ dof), the statistic ``chi2_text`` tests; None without a noise model.
    chi2_kept_observations : numpy.ndarray, int or None
        Robust fits under a noise model: the observations the χ² is taken over (z ≤ ``CHI2_INLIER_Z``).
    whitened_residual_norm : numpy.ndarray or None
        (R, K) or (K,): the normalised residual z per observation — the length of its 2-vector residual over the
        pixel σ once the fit's MAP estimates of the errors it shares with other observations (per-image star
        tracker and GNSS, per-pass biases, catalogue positions) are removed; without a noise model, over the
        residuals' robust scale. The robust loss's argument; every frame algorithm returns it. Not ``residual_z``,
        which is per coordinate over its marginal σ under the whole model.
    largest_residuals : tuple
        (image, landmark id, z) of the five largest ``whitened_residual_norm`` of the first run
        (``largest_residuals_text`` prints the first three and says what z is).
    robust_weights : numpy.ndarray or None
        (R, K) or (K,): the robust fit's final weight per observation; None for least squares.
    joint_covariance : numpy.ndarray or None
        With floated effects: the covariance of θ and the effects' parameters over ``joint_labels``
        in ``joint_units`` (arcsec for θ, each effect's unit after).
    joint_labels, joint_units : tuple
        The names and units of the jointly estimated parameters, θ's three first.
    effect_status : dict
        {effect: ``"ok"`` or why it was not fitted} of the effects asked for.
    effects_by_default : tuple of str
        The effects floated because the caller left ``effects`` to ``estimate`` (``gnss_bias`` on a set of
        star and landmark rows: ``core.weighting.default_effects``); ``effects=[]`` fixes them at 0.
    truth_arcsec : numpy.ndarray or None
        The simulated truth of θ (arcsec) when the input carries it.
    unit_slips : tuple of str
        Each σ of the noise model more than 100× outside its typical range (``model_unit_slips``).
    noise_free : bool
        The residuals are at round-off (noise-free input): σ is not meaningful.
    rejected : numpy.ndarray or None
        The Kalman filter: the images its χ² gate rejected, (R, N) or (N,) bool.
    nees : numpy.ndarray or None
        The Kalman filter: NEES of θ against the truth, when the input carries it.
    planar_model_error_arcsec : numpy.ndarray or None
        Algorithm 1 (``homography``): its planar model's deterministic error on this geometry, included in σ.
    algorithm_result : object or None
        The algorithm's own result: ``KalmanResult`` for ``kalman``, ``HomographyResult`` for ``homography``.

    Notes
    -----
    ``extra``, the dict that held these values under string keys, is deprecated: reading it warns
    and returns the fields above under their old keys (``normalised_residuals`` is
    ``whitened_residual_norm``; ``kalman`` / ``homography`` are ``algorithm_result``).
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
    warnings: tuple[str, ...] = ()
    sigma_includes: str = ""
    effects: dict[str, Any] = field(default_factory=dict)
    downweighted: tuple[Any, ...] = ()
    loss: str | None = None
    chi2_model: Any = None
    dof_model: Any = None
    chi2_kept_observations: Any = None
    whitened_residual_norm: np.ndarray | None = None
    largest_residuals: tuple[tuple[int, str, float], ...] = ()
    robust_weights: np.ndarray | None = None
    joint_covariance: np.ndarray | None = None
    joint_labels: tuple[str, ...] = ()
    joint_units: tuple[Any, ...] = ()
    effect_status: dict[str, str] = field(default_factory=dict)
    truth_arcsec: np.ndarray | None = None
    unit_slips: tuple[str, ...] = ()
    noise_free: bool = False
    rejected: np.ndarray | None = None
    nees: np.ndarray | None = None
    planar_model_error_arcsec: np.ndarray | None = None
    algorithm_result: Any = None
    effects_by_default: tuple[str, ...] = ()

    @property
    def extra(self) -> dict[str, Any]:
        """Deprecated: the fields above as the old untyped dict (its old keys; only those set).

        DECISION: kept readable for one release with a ``DeprecationWarning`` because ``Estimate`` is
        public and ``extra`` was documented; it is rebuilt on each read, so writing into it changes nothing.
        """
        import warnings

        warnings.warn(
            "Estimate.extra is deprecated; read the typed fields instead (est.chi2_model, est.joint_covariance, "
            "est.whitened_residual_norm for extra['normalised_residuals'], est.algorithm_result for "
            "extra['kalman'] / extra['homography'], …)",
            DeprecationWarning,
            stacklevel=2,
        )
        out: dict[str, Any] = {}
        for key, name in _EXTRA_KEYS.items():
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (tuple, dict)) and not value) and value is not False:
                out[key] = value
        if self.algorithm_result is not None:
            out[self.algorithm] = self.algorithm_result
        if self.algorithm == "homography":
            out["warnings"] = self.warnings
        return out

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
        lines = [
            f"algorithm     {self.algorithm} ({self.weighting} weighting), {self.iterations} iteration(s), "
            + ("converged" if conv else "NOT converged")
        ]
        for name, t, s in zip(("theta_x", "theta_y", "theta_z"), th, sg):
            lines.append(f"{name:<13} {t:+.4f} ± {s:.4f} arcsec")
        if self.sigma_includes:
            lines.append(f"sigma         {self.sigma_includes}")
        lines += self._effect_lines()
        lines.append(f"chi2 / dof    {self.chi2_text()}")
        lines.append(f"condition     {cond:.3g}")
        if self.largest_residuals or self.noise_free:
            lines.append(f"largest z     {self.largest_residuals_text()}")
        if self.downweighted:
            lines.append(
                f"down-weighted {len(self.downweighted)} observation(s) ({self.loss} loss), e.g. "
                + "; ".join(f"image {d[0]} {d[1]}: {d[4]}" for d in self.downweighted[:3])
            )
        te = self.truth_error()
        if te is not None:
            t, _, ns = te
            lines.append(
                "truth         "
                + ", ".join(f"{a:+.4f}" for a in t)
                + " arcsec; error "
                + ("σ not meaningful (noise-free input)" if ns is None else ", ".join(f"{v:+.2f}" for v in ns) + " σ")
            )
        for w in self.warnings:
            lines.append(f"warning       {w}")
        return "\n".join(lines)

    def truth_error(self, run: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
        """(true θ, θ̂ − true θ, (θ̂ − true θ) / σ) of ``run``, each (3,), arcsec then σ, when the input carried its
        true θ (``truth_arcsec``: a simulated set or file); None otherwise. The last is None when σ is not meaningful
        (``noise_free``, or a σ of 0): the error is then in arcsec only."""
        if self.truth_arcsec is None:
            return None
        t = np.atleast_2d(self.truth_arcsec)
        t = t[min(run, len(t) - 1)]
        err = np.atleast_2d(self.theta.to_value(u.arcsec))[run] - t
        sg = np.atleast_2d(self.sigma.to_value(u.arcsec))[run]
        with np.errstate(divide="ignore", invalid="ignore"):
            ns = err / sg
        return t, err, None if self.noise_free or not np.all(np.isfinite(ns)) else ns

    def downweighted_count(self, run: int = 0) -> int | None:
        """How many observations of ``run`` the robust loss down-weights: those whose ``whitened_residual_norm``
        exceeds the loss's constant (``core.losses.LOSSES``; Huber: weight < 1, Cauchy: < 0.5, Tukey: 0) — the rows
        ``downweighted`` lists for a frame fit, counted the same way for pushbroom lines. None for least squares."""
        if self.loss is None or self.whitened_residual_norm is None:
            return None
        from boresight.core.losses import LOSSES

        z = np.atleast_2d(self.whitened_residual_norm)[run]
        return int(np.sum(z > LOSSES[self.loss]))

    def largest_residuals_json(self, count: int = 5) -> dict[str, Any]:
        """The ``count`` largest normalised residuals of the first run (``largest_residuals``), worst first, and what
        they are normalised by, as JSON values: what ``largest_residuals_text`` renders and ``boresight estimate
        --json`` writes under ``largest_residuals`` (``docs/data-format.md``, "Command outputs (JSON)").

        Returns
        -------
        dict
            ``z_definition`` (str): what z is (below); ``meaningful`` (bool): False on noise-free input, where the
            residuals are round-off; ``observations`` (list, worst first, at most ``count``; empty when the estimator
            returns no z): for frame images ``{"image": n, "landmark": id, "z": z}`` (the image's index in the file
            and the target's id), for pushbroom lines ``{"row": k, "detection": "[strip s ]line L id", "z": z}``
            (the row of the stacked strips and the detection as a user finds it in the file: strip, measured line,
            point id).

        z is ``whitened_residual_norm``: the length of an observation's 2-vector residual after the fit's own
        estimate of every error shared between observations (per-image star tracker and GNSS, per-pass biases,
        catalogue positions, a line's tracker samples: their MAP values given θ) is removed, over the pixel σ alone —
        the part of the residual that belongs to this detection, which is what marks it as an outlier (the robust
        losses weight this z; ``downweighted`` lists it). Without a noise model: the residual length over the robust
        scale (MAD) of the residual components. For a good detection z is the length of a 2-D standard normal
        (P(z > 2.45) = 5 %, P(z > 3.72) = 0.1 %), up to leverage.

        DECISION: not the residual over its marginal σ (``residual_z``: every error of the model at that
        observation): that σ includes the image's star-tracker error, so an image with a large attitude
        error shows all its detections at the top of the list together, and the list names images, not
        detections."""
        top = self.largest_residuals[:count]
        if self.algorithm == "line_scan":  # a line is no image of its own: the label names the strip, line and point
            what = "residual length over the pixel σ, the fitted tracker-sample (interpolated to the line), per-pass and catalogue errors removed"
            rows = [{"row": int(k), "detection": str(lm), "z": float(z)} for k, lm, z in top]
        else:
            what = (
                "residual length over the pixel σ, the fitted per-image, per-pass and catalogue errors removed"
                if self.chi2_model is not None
                else "residual length over the residuals' robust scale (no noise model)"
            )
            rows = [{"image": int(n), "landmark": str(lm), "z": float(z)} for n, lm, z in top]
        return {"z_definition": what, "meaningful": not self.noise_free, "observations": rows}

    def largest_residuals_text(self, count: int = 3) -> str:
        """The ``count`` largest normalised residuals of the first run, worst first, and what they are normalised
        by — the one statistic the summary and the command line print: ``largest_residuals_json`` (which says what z
        is) rendered on one line."""
        top = self.largest_residuals_json(count)
        if not top["meaningful"]:
            return "not meaningful (the residuals are at round-off: noise-free input)"
        if not top["observations"]:
            return "not computed"
        named = [o["detection"] if "detection" in o else f"image {o['image']} {o['landmark']}" for o in top["observations"]]
        return ", ".join(f"{name} {o['z']:.2f}" for name, o in zip(named, top["observations"])) + f" (z: {top['z_definition']})"

    def _effect_lines(self) -> list[str]:
        lines = []
        for name, (val, sig) in self.effects.items():
            v, e = np.atleast_1d(val.value), np.atleast_1d(sig.value)
            if v.ndim > 1:
                v, e = v[0], e[0]
            vals = ", ".join(f"{a:+.4g} ± {b:.2g}" for a, b in zip(v, e))
            note = (
                " (floated by default: star rows separate it from θ; effects=[] fixes it at 0)"
                if name in self.effects_by_default
                else ""
            )
            unit = f" {val.unit}" if str(val.unit) else ""  # a dimensionless effect: no unit, no trailing gap
            lines.append(f"{name:<13} {vals}{unit}{note}")
        return lines

    def theta_rad(self, runs: int) -> np.ndarray:
        """θ in radians as (runs, 3), whether or not the run axis was dropped."""
        return np.atleast_2d(self.theta.to_value(u.rad)).reshape(runs, 3)

    def focal_plane_residuals(self, obs: Any) -> np.ndarray:
        """Residuals measured − predicted on the focal plane at this θ and the floated effects' fitted values,
        (R, K, 2) m, one row per observation (``core.measurement``, plus ``effect_model.effect_columns``' offsets
        of the effects fitted: the prediction the fit made).

        DECISION: with effects floated (asked for, or by default on a set of star and landmark rows) the residuals
        are those of the fitted model; θ's alone would show a fitted GNSS bias as landmark residuals of many σ."""
        from boresight.core.measurement import measured_rows, predict_rows

        theta = self.theta_rad(obs.runs)
        out: np.ndarray = measured_rows(obs) - predict_rows(obs, theta)
        fitted = [n for n in self.effects if self.effect_status.get(n) == "ok"]
        if fitted:
            from boresight.core.effect_model import effect_columns

            params = {n: np.reshape(self.effects[n][0].value, (obs.runs, -1)) * self.effects[n][0].unit for n in fitted}
            out = out - np.asarray(effect_columns(obs, theta, fitted, params).offset, float)
        return out

    def residual_z(self, obs: Any, model: Any) -> np.ndarray | None:
        """Each residual coordinate over its own σ under ``model``: z = r / √(diag Σ_r), (R, K, 2) one
        row per observation, NaN where that σ is 0; None without a noise model.

        The marginal σ per coordinate (every error of the noise model at that observation, the
        correlations between observations ignored); not ``whitened_residual_norm``, which is
        the whitened norm per landmark. Only the diagonal of the residual covariance is built
        (``gls.structure.residual_variances``): memory linear in the observations.
        """
        if model is None:
            return None
        from boresight.core.gls.structure import residual_variances

        res = self.focal_plane_residuals(obs)
        sd = np.sqrt(residual_variances(obs, self.theta_rad(obs.runs), model)).reshape(res.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            z: np.ndarray = np.where(sd > 0, res / sd, np.nan)
        return z

    def chi2_test(self, run: int = 0) -> tuple[float, int, float, float, bool] | None:
        """The χ² test of ``run`` under the noise model: (χ², dof, lower, upper, outside) — ``chi2_model`` on
        ``dof_model`` degrees of freedom, its expected χ²/dof range at ``CHI2_LEVEL`` (``boresight.stats.chi2_band``)
        and whether it falls outside (``boresight.stats.chi2_outside``: the test of the warning). None without a
        noise model or without degrees of freedom (no test). ``chi2_text`` prints it."""
        if self.chi2_model is None:
            return None
        c2m, dofm = float(np.atleast_1d(self.chi2_model)[run]), int(np.atleast_1d(self.dof_model)[run])
        if dofm <= 0:
            return None
        lo, hi = chi2_band(dofm)
        return c2m, dofm, float(lo), float(hi), bool(chi2_outside(c2m, dofm))

    def chi2_test_json(self, run: int = 0) -> dict[str, Any]:
        """The χ² test of ``run`` as JSON values: what ``chi2_text`` renders (the ``chi2 / dof`` line) and ``boresight
        estimate --json`` writes under ``chi2_test`` (``docs/data-format.md``, "Command outputs (JSON)").

        Returns
        -------
        dict
            ``noise_model`` (bool): whether the test is under a noise model; ``chi2``, ``dof``: the statistic tested
            (``chi2_model`` on ``dof_model``; without a noise model the plain sum of squares ``chi2`` on ``dof``, in
            ``residual_unit`` squared); ``chi2_per_dof`` (null without degrees of freedom); ``expected_per_dof``:
            [lower, upper] of χ²/dof at ``level`` (``CHI2_LEVEL``, ``boresight.stats.chi2_band``), ``outside`` (bool:
            ``boresight.stats.chi2_outside``, the test of the warning), each null when there is no test (no noise
            model, no degrees of freedom); ``kept_observations``: the observations a robust fit's χ² is over
            (z ≤ ``CHI2_INLIER_Z``), else null; ``unit_slip``: the most likely unit slip when outside, else null."""
        test = self.chi2_test(run)
        if self.chi2_model is None:
            chi2, dof = float(np.atleast_1d(self.chi2)[run]), int(np.atleast_1d(self.dof)[run])
        else:
            chi2, dof = float(np.atleast_1d(self.chi2_model)[run]), int(np.atleast_1d(self.dof_model)[run])
        kept = self.chi2_kept_observations
        outside = None if test is None else test[4]
        return {
            "noise_model": self.chi2_model is not None,
            "chi2": chi2,
            "dof": dof,
            "chi2_per_dof": chi2 / dof if dof > 0 else None,
            "expected_per_dof": None if test is None else [test[2], test[3]],
            "level": None if test is None else float(CHI2_LEVEL),
            "outside": outside,
            "kept_observations": None if kept is None or test is None else int(np.atleast_1d(kept)[run]),
            "unit_slip": self.unit_slips[0] if outside and self.unit_slips else None,
        }

    def chi2_text(self, run: int = 0) -> str:
        """χ²/dof of ``run`` under the noise model with its expected band (``chi2_test``: ``boresight.stats.chi2_band``
        at ``CHI2_LEVEL``) and, when outside, the flag — the same test as the warning, so the command
        line prints what the library decided; without a noise model, the plain sum of squares. The rendering of
        ``chi2_test_json`` (one implementation)."""
        t = self.chi2_test_json(run)
        c2m, dofm = t["chi2"], t["dof"]
        if not t["noise_model"]:
            return (
                f"{c2m:.4g} / {dofm} (no noise model: a plain sum of squares in {self.residual_unit or 'residual units'}², "
                "no expected range)"
            )
        if t["outside"] is None:
            return f"{c2m:.4g} / {dofm} under the noise model (no degrees of freedom: no expected range)"
        lo, hi = t["expected_per_dof"]
        kept = t["kept_observations"]
        what = "" if kept is None else f" of the {kept} observations kept (z ≤ {CHI2_INLIER_Z:.1f})"
        slip = t["unit_slip"]
        flag = (
            "  <-- OUTSIDE the expected range: the noise model does not describe these residuals"
            + (f" — most likely a unit slip: {slip}" if slip else "")
            if t["outside"]
            else ""
        )
        return f"{t['chi2_per_dof']:.3f} ({c2m:.4g} / {dofm}) under the noise model{what}; expected {lo:.3f}..{hi:.3f} ({t['level']:.1%}){flag}"

    def downweighted_json(self) -> dict[str, Any] | None:
        """The robust loss's down-weighted observations of the first run as JSON values: what ``boresight estimate``
        prints on its ``robust`` line (frame) or ``loss`` line (pushbroom) and writes under ``downweighted`` with
        ``--json`` (``docs/data-format.md``, "Command outputs (JSON)"). None for least squares (no loss).

        Returns
        -------
        dict or None
            ``loss`` (str); ``z_threshold``: the loss's constant (``core.losses.LOSSES``) above which an observation's
            z (``whitened_residual_norm``) is down-weighted; ``count``: how many (``downweighted_count``);
            ``observations``: the frame fit's down-weighted observations, largest z first (``downweighted``), each
            ``{"image": n, "landmark": id, "z": z, "weight": w}`` — empty for a pushbroom fit, whose detections are
            counted but not listed (``largest_residuals`` names its worst)."""
        if self.loss is None:
            return None
        from boresight.core.losses import LOSSES

        count = self.downweighted_count()
        rows = [{"image": int(d[0]), "landmark": str(d[1]), "z": float(d[2]), "weight": float(d[3])} for d in self.downweighted]
        return {
            "loss": self.loss,
            "z_threshold": float(LOSSES[self.loss]),
            "count": len(rows) if count is None else count,
            "observations": rows,
        }


#: the deprecated ``Estimate.extra`` key of each typed field (the algorithm's own result is keyed by its name)
_EXTRA_KEYS = {
    "loss": "loss",
    "chi2_model": "chi2_model",
    "dof_model": "dof_model",
    "chi2_kept_observations": "chi2_kept_observations",
    "normalised_residuals": "whitened_residual_norm",
    "largest_residuals": "largest_residuals",
    "robust_weights": "robust_weights",
    "joint_covariance": "joint_covariance",
    "joint_labels": "joint_labels",
    "joint_units": "joint_units",
    "effect_status": "effect_status",
    "truth_arcsec": "truth_arcsec",
    "unit_slips": "unit_slips",
    "noise_free": "noise_free",
    "rejected": "rejected",
    "nees": "nees",
    "planar_model_error_arcsec": "planar_model_error_arcsec",
}


def _pixel_part(model: Any, rows_sigma_m: Any) -> str | None:
    """The pixel noise in words: the model's σK, or with the rows' own σ (``ObservationSet.sigma_xy_m``, NaN:
    σK) their range and how many rows have one, e.g. ``'pixel each row's own 0.41–2.6 µm (442 of 442 rows)'``."""
    own = None if rows_sigma_m is None else np.asarray(rows_sigma_m, float)
    if own is None or not np.any(np.isfinite(own)):
        return f"pixel {model.sigma_pixel_m:.3g} m" if model.sigma_pixel_m > 0 else None
    has = np.all(np.isfinite(own), axis=-1)
    lo, hi = float(np.nanmin(own)), float(np.nanmax(own))
    text = f"pixel each row's own σ {lo:.3g}..{hi:.3g} m ({int(has.sum())} of {has.size} rows"
    if not has.all() and model.sigma_pixel_m > 0:
        text += f"; the others {model.sigma_pixel_m:.3g} m"
    return text + ")"


def model_parts(model: Any, rows_sigma_m: Any = None) -> list[str]:
    """The non-zero error sources of a ``DisturbanceModel`` in plain words, e.g. ``'GNSS 15 m (both)'``;
    ``rows_sigma_m`` (K, 2): the observations' own pixel σ where they carry one (``ObservationSet.sigma_xy_m``)."""
    parts = []
    pixel = _pixel_part(model, rows_sigma_m)
    if pixel:
        parts.append(pixel)
    st = np.asarray(model.sigma_star_tracker_rad) / ARCSEC
    if np.any(st > 0):
        parts.append(f"star tracker [{', '.join(f'{v:.4g}' for v in st)}]″ ({model.star_tracker_mode})")
    gm = np.asarray(getattr(model, "sigma_star_tracker_correlated_rad", (0.0,) * 3)) / ARCSEC
    if np.any(gm > 0):
        tau = model.star_tracker_correlation_time_s
        parts.append(f"star tracker Gauss–Markov [{', '.join(f'{v:.4g}' for v in gm)}]″, τ {tau:g} s (over the tracker samples)")
    if model.sigma_gnss_m > 0:
        parts.append(f"GNSS {model.sigma_gnss_m:.3g} m ({model.gnss_mode})")
    if model.sigma_catalogue_m > 0:
        parts.append(f"catalogue {model.sigma_catalogue_m:.3g} m")
    return parts


def model_unit_slips(model: Any) -> list[str]:
    """Each σ of a ``DisturbanceModel`` more than 100× outside its typical range, with the unit
    that would fit (``orbits.sensors.unit_slip``): ``["star-tracker σ 0.0011 arcsec is 455× below …;
    if it was in degrees, … = 3.96 arcsec"]``. When χ² is outside its band such a slip is the most
    likely cause, so it is named before "outliers?"."""
    from orbits.sensors import unit_slip

    if model is None:
        return []
    out = []
    for key, what, values in (
        ("pixel", "pixel σ", model.sigma_pixel_m),
        ("star_tracker", "star-tracker σ", np.asarray(model.sigma_star_tracker_rad) / ARCSEC),
        ("gnss", "GNSS σ", model.sigma_gnss_m),
        ("catalogue", "catalogue σ", model.sigma_catalogue_m),
    ):
        for v in np.unique(np.atleast_1d(np.asarray(values, dtype=np.float64))):
            why = unit_slip(key, float(v))
            if why:
                out.append(f"{what} {why}")
                break
    return out


def noise_model_text(model: Any, rows_sigma_m: Any = None) -> str:
    """A ``DisturbanceModel`` in plain words: its non-zero sources (``model_parts``, with the rows' own pixel σ
    ``rows_sigma_m`` where given) and those it leaves out."""
    if model is None:
        return "no noise model"
    st = np.asarray(model.sigma_star_tracker_rad) / ARCSEC
    own = rows_sigma_m is not None and bool(np.any(np.isfinite(np.asarray(rows_sigma_m, float))))
    missing = [
        n
        for n, v in (
            ("pixel", 1.0 if own else model.sigma_pixel_m),
            ("star tracker", max(np.max(st), np.max(getattr(model, "sigma_star_tracker_correlated_rad", (0.0,))))),
            ("GNSS", model.sigma_gnss_m),
            ("catalogue", model.sigma_catalogue_m),
        )
        if not v > 0
    ]
    parts = model_parts(model, rows_sigma_m)
    text = ", ".join(parts) if parts else "every σ zero"
    return text + (" (not included: " + ", ".join(missing) + ")" if missing and parts else "")


def sigma_includes(model: Any, weighting: str, prior: bool, K: int, loss: str | None, rows_sigma_m: Any = None) -> str:
    """What σθ contains, in plain words (``Estimate.sigma_includes``, printed as is by the command
    line); ``model`` None: no noise model; ``rows_sigma_m`` the observations' own pixel σ (K, 2) or None."""
    if model is None:
        text = "scatter only — star-tracker and GNSS errors not included (no noise model; σ from the residual scatter)"
    else:
        how = "GLS under" if weighting == "gls" else f"{weighting}-weighted fit, sandwich covariance under"
        text = f"{how} the noise model: " + noise_model_text(model, rows_sigma_m)
    if K:
        text += "; the floated effects' uncertainty (fitted jointly)"
    if prior:
        text += "; the prior on θ"
    if loss and model is not None and weighting == "gls":
        text += f"; {loss} loss: M-estimator sandwich (outliers' own influence, inliers at the loss's expected constants)"
    elif loss:
        text += f"; {loss} reweighting treated as fixed weights"
    return text


#: the χ²-too-high warning's hint for a least-squares fit without a loss
OUTLIER_HINT = "outliers? a robust loss, huber or cauchy, down-weights them"


def _chi2_warning(
    obs: Any, c2: float, d: float, loss: str | None, kept: int | None, outlier_hint: str = OUTLIER_HINT, cause: str = ""
) -> str | None:
    """The χ²/dof-outside-its-band warning of one run (``boresight.stats.chi2_outside``), or None."""
    if not chi2_outside(c2, d):
        return None
    lo, hi = (float(v) * d for v in chi2_band(d))
    if kept is not None:
        return (
            f"χ²/dof = {c2 / d:.3g} under the noise model, of the {kept} observations the {loss} fit kept "
            f"(pixel-level z ≤ {CHI2_INLIER_Z:.1f}; {obs.n_observations - kept} left out as outliers), is outside its "
            f"{CHI2_LEVEL:.1%} range {lo / d:.3f}..{hi / d:.3f}: the noise model does not describe the inliers"
            + (f" ({cause})" if cause else "")
        )
    return (
        f"χ²/dof = {c2 / d:.3g} under the noise model is outside its {CHI2_LEVEL:.1%} range "
        f"{lo / d:.3f}..{hi / d:.3f}: the noise model does not describe these residuals"
        + (f" ({cause})" if cause else f" ({outlier_hint})" if c2 > hi and loss is None and outlier_hint else "")
    )


def _prior_warnings(prior_info: np.ndarray, cov_r: np.ndarray) -> list[str]:
    """The prior-dominates-an-axis warnings of one run (``prior_info`` in rad⁻², ``cov_r`` rad²)."""
    P = np.diag(prior_info)[:3]
    share = P * np.diag(cov_r)[:3]  # prior information × posterior variance ≈ the prior's share
    return [
        f"the prior dominates θ{'xyz'[k]}: it carries {share[k]:.0%} of the information "
        f"(prior σ {1 / np.sqrt(P[k]) / ARCSEC:.3g}″, posterior σ {np.sqrt(cov_r[k, k]) / ARCSEC:.3g}″)"
        for k in np.flatnonzero(share > PRIOR_DOMINANCE)
    ]


def _unmodelled_warning(obs: Any) -> str:
    if getattr(obs, "noise", None) is not None:
        # the observations carry a noise model the caller did not pass: say so, never silently
        return (
            "the observations carry a noise model that was NOT used (weighting='unit', or no pixel σ to weight "
            "with): σ is the residual scatter only and does not include star-tracker or GNSS errors (pass "
            "model=DisturbanceModel.from_observations(obs) for its sandwich σ, or leave weighting=None for GLS)"
        )
    return (
        "no noise model: σ is the residual scatter only and does not include star-tracker or GNSS errors "
        "(give model=DisturbanceModel(...) or a file with a noise model)"
    )


def estimate_warnings(
    obs: Any,
    theta: np.ndarray,
    cov: np.ndarray,
    prior_info: np.ndarray | None,
    converged: np.ndarray,
    last_step: np.ndarray,
    iterations: int,
    chi2m: Any,
    dofm: Any,
    modelled: bool,
    loss: str | None,
    status: dict[str, str],
    kept: Any = None,
    *,
    tolerance_rad: float,
    outlier_hint: str = OUTLIER_HINT,
    unit_slips: list[str] | tuple[str, ...] = (),
) -> list[str]:
    """``Estimate.warnings``: plain-language reasons not to trust a fit (θ (R, 3) rad, ``cov`` (R, n, n)
    rad² for θ, ``prior_info`` rad⁻² or None, ``status`` {effect: "ok" | why not fitted}); every
    algorithm with a noise-model χ² calls it (the least-squares loop and the Kalman filter), so the
    verdict is worded once. ``outlier_hint``: what a χ² too high suggests (the algorithm's own remedy);
    ``unit_slips`` (``model_unit_slips``): σ of the noise model that look like a unit slip — warned
    first, and named instead of the outlier hint as the χ² verdict's most likely cause."""
    out = [f"{w} — check the unit of this σ" for w in unit_slips]
    cause = f"most likely the unit slip above: {unit_slips[0].split(' is ')[0]}" if unit_slips else ""
    R = theta.shape[0]
    tag = (lambda r: "") if R == 1 else (lambda r: f"run {r}: ")
    if chi2m is not None:
        # the χ² test of every run at once (one vectorised ppf, not two per run: 40 % of a batched call)
        outside = chi2_outside(
            np.broadcast_to(np.asarray(chi2m, np.float64), (R,)), np.broadcast_to(np.asarray(dofm, np.float64), (R,))
        )
    robust = ", or 1e-3 σ" if loss else ""
    changing = " or the robust weights still changing" if loss else ""
    for r in range(R):
        if not converged[r]:
            out.append(
                f"{tag(r)}did not converge in {iterations} iteration(s): last θ correction {last_step[r] / ARCSEC:.3g}″ "
                f"(tolerance {tolerance_rad / ARCSEC:.0e}″{robust}){changing}"
            )
        big = small_angle_warning(theta[r] / ARCSEC, tag(r))
        if big is not None:
            out.append(big)
        if chi2m is not None:
            c2, d = np.float64(np.atleast_1d(chi2m)[r]), np.float64(np.atleast_1d(dofm)[r])
            k = None if kept is None else int(np.atleast_1d(kept)[r])
            msg = _chi2_warning(obs, c2, d, loss, k, outlier_hint, cause) if outside[r] else None
            if msg is not None:
                out.append(tag(r) + msg)
        if prior_info is not None:
            out += [tag(r) + msg for msg in _prior_warnings(prior_info, cov[r])]
    if not modelled:
        out.append(_unmodelled_warning(obs))
    for nm, st in status.items():
        if st != "ok":
            out.append(f"effect {nm}: {st}")
    return out


def top_residuals(index: Any, labels: Any, z: Any, count: int = 5) -> tuple[tuple[int, str, float], ...]:
    """(index, label, z) of the ``count`` largest normalised residuals ``z`` (K,) of one run, largest first
    — ``Estimate.largest_residuals``, for frame images (``index`` the image, ``labels`` the landmark ids per
    observation) and pushbroom lines (the row of the stacked strips, labels naming strip, line and point) alike."""
    zz = np.asarray(z, float)
    top = np.argsort(zz, kind="stable")[::-1][:count]
    return tuple((int(index[k]), str(labels[k]), float(zz[k])) for k in top)
