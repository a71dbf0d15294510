"""What the sea-sky residuals say after the (alpha, beta) fit (beyond USV sea-sky).

:func:`analyse_sea_sky` runs the generic diagnostics of :mod:`boresight.stats.residuals`
on a :class:`~boresight.pointing.sea_sky_fit.SeaSkyFit`: robust outlier flags, residual
structure against azimuth (bins and harmonics), against hull pitch and roll, serial
correlation, and a nested test of whether the hull attitude terms of eq 12 are supported.

Example
-------
>>> from boresight.pointing import load_sea_sky
>>> d = analyse_sea_sky(load_sea_sky())
>>> [int(f) for f in d.outlier_frames]
[9, 15, 16, 87, 93, 94, 95, 96]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from boresight.pointing.data import SeaSkyScan
from boresight.pointing.sea_sky_fit import Geometry, SeaSkyFit, fit_least_squares
from boresight.stats.residuals import (
    BinnedResiduals,
    HarmonicFit,
    NestedTest,
    binned_residuals,
    harmonic_fit,
    ljung_box,
    nested_f_test,
    outlier_flags,
    robust_z,
)

__all__ = ["SeaSkyDiagnostics", "analyse_sea_sky"]


@dataclass(frozen=True)
class SeaSkyDiagnostics:
    """Residual analysis of a sea-sky fit. Angles in degrees."""

    fit: SeaSkyFit
    fit_no_attitude: SeaSkyFit
    fit_gain: SeaSkyFit
    outlier_frames: np.ndarray
    outlier_residuals_deg: np.ndarray
    outlier_z: np.ndarray
    attitude_effect_max_deg: float  # max |h'(with P, R) - h'(P = R = 0)| at the fitted (alpha, beta)
    attitude_test: NestedTest  # k = 0 vs free k, OLS on inliers, n = number of inliers
    attitude_test_neff: NestedTest  # the same with n replaced by the effective sample size
    by_azimuth: BinnedResiduals
    by_pitch: BinnedResiduals
    by_roll: BinnedResiduals
    harmonics: HarmonicFit
    ljung_box_q: float
    ljung_box_p: float
    inlier_rms_deg: float

    def report(self) -> str:
        f, g = self.fit, self.fit_gain
        lines = [
            f"least squares ({f.loss}): {f.summary()}",
            f"  without hull attitude (P = R = 0): alpha = {self.fit_no_attitude.alpha_deg:.4f}, "
            f"beta = {self.fit_no_attitude.beta_deg:.4f} deg",
            f"  attitude gain k (0 = none, 1 = eq 12): {g.params[2]:.2f} ± {g.se[2]:.2f}",
            f"  max |effect of P, R on fitted h'| = {self.attitude_effect_max_deg:.4f} deg"
            f" (inlier rms residual {self.inlier_rms_deg:.3f} deg)",
            f"  nested F-test k=0 vs free k: F = {self.attitude_test.f_stat:.2f}, p = {self.attitude_test.p_value:.3f}"
            f" (n_eff: p = {self.attitude_test_neff.p_value:.3f}), dAIC = {self.attitude_test.delta_aic:.1f}",
            "outliers (|robust z| > 3.5): "
            + ", ".join(
                f"frame {int(fr)} ({r:+.3f} deg, z={z:+.1f})"
                for fr, r, z in zip(self.outlier_frames, self.outlier_residuals_deg, self.outlier_z)
            ),
            f"serial correlation: lag-1 acf {f.acf[1]:.2f}, n_eff = {f.n_eff:.1f} of {f.n}, Ljung-Box(10) p = {self.ljung_box_p:.2g}",
            "residual harmonics vs azimuth (inliers): "
            + ", ".join(
                f"k={k}: {a:.3f}±{s:.3f} deg (p={p:.2g})"
                for k, a, s, p in zip(
                    self.harmonics.orders, self.harmonics.amplitude, self.harmonics.amplitude_se, self.harmonics.p_value
                )
            ),
            f"binned vs azimuth (30 deg, inliers): chi2/dof = {self.by_azimuth.chi2:.1f}/{self.by_azimuth.dof}, p = {self.by_azimuth.p_value:.2g}",
            f"binned vs pitch: p = {self.by_pitch.p_value:.2g}; vs roll: p = {self.by_roll.p_value:.2g}",
        ]
        return "\n".join(lines)


def analyse_sea_sky(scan: SeaSkyScan, *, loss: str = "huber", threshold: float = 3.5) -> SeaSkyDiagnostics:
    """Fit (alpha, beta) and diagnose the residuals; see :class:`SeaSkyDiagnostics`.

    # DECISION: the structure tests (bins, harmonics, attitude F-test) use the inliers only, so
    # that a handful of surge-blocked frames do not masquerade as structure; the bins' standard
    # errors are inflated by sqrt(n / n_eff) for the serial correlation.
    """
    fit = fit_least_squares(scan, loss=loss)
    fit0 = fit_least_squares(scan, loss=loss, use_attitude=False)
    fitk = fit_least_squares(scan, loss=loss, fit_attitude_gain=True)
    r = fit.residuals_deg
    out = outlier_flags(r, threshold)
    z = robust_z(r)
    inl = ~out
    geo1 = Geometry(scan.azimuth_deg, scan.pitch_deg, scan.roll_deg)
    geo0 = Geometry(scan.azimuth_deg, 0 * scan.pitch_deg, 0 * scan.roll_deg)
    effect = np.abs(geo1.elevation_deg(fit.alpha_deg, fit.beta_deg) - geo0.elevation_deg(fit.alpha_deg, fit.beta_deg))
    # nested OLS on inliers: k = 0 (2 params) vs free k (3 params)
    ols0 = fit_least_squares(scan, loss="linear", use_attitude=False, mask=inl)
    olsk = fit_least_squares(scan, loss="linear", fit_attitude_gain=True, mask=inl)
    n_in = int(inl.sum())
    test = nested_f_test(ols0.rss_deg2, olsk.rss_deg2, 2, 3, n_in)
    test_eff = nested_f_test(ols0.rss_deg2, olsk.rss_deg2, 2, 3, max(olsk.n_eff, 3.5))
    ri = r[inl]
    factor = min(1.0, fit.n_eff / fit.n)
    qdeg = scan.azimuth_deg[inl]
    by_az = binned_residuals(qdeg, ri, bins=np.arange(0.0, 361.0, 30.0), n_eff_factor=factor)
    edges = lambda v: np.quantile(v, np.linspace(0, 1, 7))  # noqa: E731
    by_p = binned_residuals(scan.pitch_deg[inl], ri, bins=edges(scan.pitch_deg[inl]), n_eff_factor=factor)
    by_r = binned_residuals(scan.roll_deg[inl], ri, bins=edges(scan.roll_deg[inl]), n_eff_factor=factor)
    harm = harmonic_fit(np.radians(qdeg), ri, max_order=4)
    q, p = ljung_box(r, 10)
    return SeaSkyDiagnostics(
        fit,
        fit0,
        fitk,
        scan.frame[out],
        r[out],
        z[out],
        float(effect.max()),
        test,
        test_eff,
        by_az,
        by_p,
        by_r,
        harm,
        q,
        p,
        float(np.sqrt(np.mean(ri**2))),
    )
