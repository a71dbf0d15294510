"""Residual consistency when σ comes from the scatter: a robust outlier test that needs no noise model.

With a noise model, ``estimate`` checks χ²/dof against its quantiles. Without one (a format-1.0
file, Algorithm 1, an all-zero noise model) σ is the residual scatter, and one gross point
inflates that scatter just enough to hide itself: a 2000 px point moved θ by ~1 000″ with
exit 0 and no warning. Here each residual component is compared with the residuals'
own robust scale (1.4826 × MAD, ``boresight.stats.robust_sigma``), which one point cannot move.

DECISION: the threshold is the two-sided Gaussian quantile at a family-wise false-alarm
probability ``ALPHA`` = 10⁻³ over the n residual components, widened by 1 + 3.5 × 1.166/√n for
the MAD's own sampling error (its relative standard error is 1.166/√n for Gaussian data): about
5.98 for the 160 components of kiev2012-kalman20. ``tests/project/test_hostile.py`` counts the alarms on
clean simulated files (0 in 600 runs), and the fuzz (``tests/project/test_fuzz.py``) on damaged ones.
A scale below ``FLOOR_M`` (1 nm on the focal plane) is round-off: the floor keeps a noise-free
file from flagging its own last bits, while a real slip on it (−0.0 for x) is still > 10⁶ floors.
The same floor says when a fit is noise-free (every run's RMS residual below it): σ from the
scatter is then round-off, and the result says so in one sentence instead of a σ multiple of 0/0
(``round_off_rms``).
"""

from __future__ import annotations

import math
from statistics import NormalDist
from typing import Any

import numpy as np

__all__ = ["scatter_outliers", "with_scatter_check", "round_off_rms", "threshold", "ALPHA", "FLOOR_M", "NOISE_FREE_SIGMA"]

#: family-wise probability that a clean file is flagged
ALPHA = 1e-3
#: residual scale floor (m on the focal plane)
FLOOR_M = 1e-9
#: DECISION: the test needs at least 16 residual components (8 landmark observations). With
#: fewer, the fit's 3 parameters leave so few degrees of freedom that the MAD of the residuals
#: can be 10× below σ by chance (one image of 4 landmarks: 1 false alarm in 200 clean runs)
MIN_COMPONENTS = 16


def threshold(n: int, alpha: float = ALPHA) -> float:
    """The |robust z| above which one of ``n`` residual components is an outlier.

    >>> round(threshold(160), 2)
    5.98
    """
    k = NormalDist().inv_cdf(1 - alpha / (2 * max(n, 1)))
    return k * (1 + 3.5 * 1.166 / math.sqrt(max(n, 1)))


def scatter_outliers(obs: Any, theta_rad: Any, alpha: float = ALPHA) -> tuple[str, Any] | None:
    """``None``, or (warning text, [(run, image, landmark id, |r| m, z), …]) when some residual
    component lies beyond ``threshold`` robust scales in some run (details from the first such run)."""
    from boresight.stats import robust_sigma

    res, (nn, mm) = _row_residuals(obs, theta_rad)
    runs_hit, found = [], None
    for r in range(obs.runs):
        comps = res[r]  # (K, 2)
        flat = comps.ravel()
        if flat.size < MIN_COMPONENTS or not np.all(np.isfinite(flat)):
            continue
        scale = max(robust_sigma(flat), FLOOR_M)
        z = np.abs(flat - np.median(flat)) / scale
        t = threshold(flat.size, alpha)
        if not np.any(z > t):
            continue
        runs_hit.append(r)
        if found is None:
            zz = z.reshape(-1, 2).max(axis=1)
            order = np.argsort(-zz)
            worst = [
                (r, int(nn[i]), str(obs.landmark_ids[mm[i]]), float(np.linalg.norm(comps[i])), float(zz[i]))
                for i in order
                if zz[i] > t
            ]
            found = (worst, scale, t)
    if found is None:
        return None
    worst, scale, t = found
    shown = "; ".join(f"image {n} landmark {lm!r} |r| = {rr:.3g} m ({z:.3g} scales)" for _, n, lm, rr, z in worst[:3])
    more = f" and {len(worst) - 3} more" if len(worst) > 3 else ""
    where = f"run {runs_hit[0]}: " if obs.runs > 1 else ""
    runs = f" ({len(runs_hit)} of {obs.runs} runs)" if obs.runs > 1 else ""
    text = (
        f"{len(worst)} observation(s) lie beyond {t:.3g}× the residuals' robust scale {scale:.3g} m{runs} — {where}{shown}{more}; "
        "σ comes from the residual scatter (no noise model), which such points inflate and hide behind: "
        "check those rows, or try --loss cauchy"
    )
    return text, worst


def _row_residuals(obs: Any, theta_rad: Any) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Focal-plane residuals at θ per observation (R, K, 2) m and the rows' (image, target) indices
    (``core.measurement``: no images × targets array)."""
    from boresight.core.measurement import measured_rows, observation_rows, predict_rows

    theta_rad = np.broadcast_to(np.asarray(theta_rad, float).reshape(-1, 3), (obs.runs, 3))
    with np.errstate(all="ignore"):
        res = measured_rows(obs) - predict_rows(obs, theta_rad)
    return res, observation_rows(obs)


def _scatter_only(model: Any, obs: Any = None) -> bool:
    """True when σ comes from the residual scatter: no noise model, or one with every σ zero and no row of
    ``obs`` with its own pixel σ (``gls.structure.has_pixel_noise``)."""
    from boresight.core.gls.structure import has_pixel_noise

    if model is None:
        return True
    if obs is not None and has_pixel_noise(obs, model):
        return False
    sigmas = [model.sigma_pixel_m, model.sigma_gnss_m, model.sigma_catalogue_m, *np.ravel(model.sigma_star_tracker_rad)]
    return not any(float(v) > 0 for v in sigmas)


def with_scatter_check(obs: Any, est: Any, model: Any) -> Any:
    """``est`` with the checks every algorithm gets (``estimate`` calls it on every result): the
    small-angle warning when the algorithm did not give it (Algorithm 1, registered estimators),
    and, when σ comes from the scatter, the robust outlier test's warning (with a noise model
    the χ²/dof test applies instead)."""
    from dataclasses import is_dataclass, replace

    if not (is_dataclass(est) and not isinstance(est, type) and hasattr(est, "theta") and hasattr(est, "warnings")):
        return est  # a registered estimator's own result type: left as it is
    theta = np.asarray(est.theta.to_value("rad"), float).reshape(-1, 3)
    if not np.all(np.isfinite(theta)):
        return est
    added = []
    if not any("small-angle range" in w for w in est.warnings):
        from boresight.core.result import small_angle_warning
        from orbits.rotations import ARCSEC

        for r in range(theta.shape[0]):
            w = small_angle_warning(theta[r] / ARCSEC, f"run {r}: " if theta.shape[0] > 1 else "")
            if w is not None:
                added.append(w)
                break
    if _scatter_only(model, obs):
        rms = round_off_rms(obs, theta)
        if rms is not None:
            return _noise_free(est, rms, added)
        found = scatter_outliers(obs, theta)
        if found is not None:
            added.append(found[0])
    return replace(est, warnings=tuple(est.warnings) + tuple(added)) if added else est


def round_off_rms(obs: Any, theta_rad: Any) -> float | None:
    """The largest per-run RMS focal-plane residual (m) when every run's is below ``FLOOR_M`` —
    noise-free input, residuals at round-off — else None."""
    res, _ = _row_residuals(obs, theta_rad)
    worst = 0.0
    for r in range(obs.runs):
        comps = res[r]
        if comps.size == 0 or not np.all(np.isfinite(comps)):
            return None
        worst = max(worst, float(np.sqrt(np.mean(comps**2))))
    return worst if worst < FLOOR_M else None


#: ``Estimate.sigma_includes`` of a noise-free fit
NOISE_FREE_SIGMA = (
    "not meaningful: the residuals are at round-off (noise-free input), so the scatter they give σ is round-off too"
)


def _noise_free(est: Any, rms_m: float, added: list[str]) -> Any:
    """``est`` of a noise-free input: σ from the scatter is round-off, so it is called not
    meaningful in plain words (one warning replaces the scatter-only ones) and
    ``Estimate.noise_free`` is set for the command line."""
    from dataclasses import replace

    kept = [w for w in est.warnings if "noise model" not in w or "χ²" in w]  # the scatter-only wording is moot
    warning = (
        f"the residuals are at round-off (RMS {rms_m:.2g} m on the focal plane, below {FLOOR_M:g} m): the input is "
        "noise-free, θ fits it exactly and σ is not meaningful — give the noise (the scenario's σ, or a noise model in "
        "the file or on the command line) for an uncertainty"
    )
    return replace(est, warnings=tuple(kept + added + [warning]), sigma_includes=NOISE_FREE_SIGMA, noise_free=True)
