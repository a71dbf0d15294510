"""Residual tests against the noise model, and the collocation view of unexplained structure.

Every test is computed in the whitened space of :mod:`.linear` (residuals divided by the noise
model's Cholesky factor, shared errors marginalised), so its null distribution is exact to
first order whatever the correlations of the errors:

* ``chi2``: χ² of the fit against χ²(dof) — "the residuals are as large as the noise model says";
* ``normalised residuals``: the largest |r_i| / sqrt(1 − h_ii) (h the hat matrix), with the
  Bonferroni p-value min(1, n · 2Φ(−max)) — one observation that does not fit;
* ``whiteness``: Ljung–Box(10) of the whitened data residuals in acquisition order;
* structure **probes**: generic image-plane patterns (``CampaignProblem._probe_columns``:
  radial displacement by image-radius quartile, radial/tangential harmonics of position
  angle, rotations varying with time in pass, argument of latitude, pass, campaign time, attitude law, image
  scale by pass) added to the model; the likelihood-ratio Δχ² against χ²(rank) says whether
  the residuals hold that structure.

The family is judged with Holm's step-down procedure at family-wise level α (1 % by default):
the residuals "pass" when no test is rejected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from boresight.stats import chi2_sf
from boresight.stats.residuals import ljung_box
from boresight.studies.discrepancy.linear import BaseFit, lr_test

__all__ = ["ResidualTest", "residual_tests", "holm_rejections", "CollocationView", "collocation_view"]


@dataclass(frozen=True)
class ResidualTest:
    name: str
    statistic: float
    dof: float
    p_value: float
    detail: str = ""
    rejected: bool = False

    def as_dict(self) -> dict:
        return {
            "test": self.name,
            "statistic": self.statistic,
            "dof": self.dof,
            "p_value": self.p_value,
            "rejected": self.rejected,
            "detail": self.detail,
        }


def holm_rejections(p_values, alpha: float) -> np.ndarray:
    """Holm's step-down at family-wise ``alpha``: boolean (m,) of rejected hypotheses.

    >>> holm_rejections([0.001, 0.04, 0.2], 0.05).tolist()
    [True, False, False]
    """
    p = np.asarray(p_values, float)
    m = p.size
    order = np.argsort(p)
    rej = np.zeros(m, bool)
    for i, j in enumerate(order):
        if p[j] <= alpha / (m - i):
            rej[j] = True
        else:
            break
    return rej


def residual_tests(base: BaseFit, probes: dict, alpha: float = 0.01) -> list[ResidualTest]:
    """The battery of the module docstring on a fitted base model; ``probes`` name → whitened columns."""
    out = []
    out.append(ResidualTest("chi2", base.chi2, base.dof, base.p_value, f"χ²/dof = {base.chi2_dof:.3f}"))
    nd = base.lin.n_data
    r = base.residual[:nd]
    h = base.leverage(nd)
    t = r / np.sqrt(np.clip(1.0 - h, 1e-12, None))
    tmax = float(np.max(np.abs(t)))
    p_norm = float(min(1.0, nd * 2.0 * stats.norm.sf(tmax)))
    out.append(ResidualTest("normalised residuals", tmax, float(nd), p_norm, f"largest |normalised residual| {tmax:.2f} of {nd}"))
    if nd > 12:
        q, p_lb = ljung_box(base.innovations[:nd], 10)
        out.append(ResidualTest("whiteness", q, 10.0, p_lb, "Ljung–Box(10) of the whitened residuals in time order"))
    for name, P in probes.items():
        rank, dchi2 = lr_test(base, P)
        if rank == 0:
            continue
        p_lr = float(chi2_sf(dchi2, rank))
        out.append(ResidualTest(name, dchi2, float(rank), p_lr, f"Δχ² = {dchi2:.1f} on {rank} dof"))
    rej = holm_rejections([x.p_value for x in out], alpha)
    return [ResidualTest(x.name, x.statistic, x.dof, x.p_value, x.detail, bool(k)) for x, k in zip(out, rej)]


@dataclass(frozen=True)
class CollocationView:
    """Tang 2014 semi-parametric collocation of the field residuals, on a grid of image cells.

    ``x_m``, ``y_m`` (c,) cell centres; ``mean_xy_m`` (c, 2) mean field residual per cell;
    ``h_xy_m`` (c, 2) the fitted smooth signal h (eq 18) per component; ``smoothing`` (2,) the
    leave-one-out smoothing factors; ``explained`` the fraction of the cell means' weighted
    sum of squares that h reproduces.
    """

    x_m: np.ndarray
    y_m: np.ndarray
    mean_xy_m: np.ndarray
    h_xy_m: np.ndarray
    count: np.ndarray
    smoothing: np.ndarray
    explained: float

    @property
    def h_rms_m(self) -> float:
        return float(np.sqrt(np.mean(np.sum(self.h_xy_m**2, axis=-1))))


def _cell_fit(x, y, f, cells):
    """Mean field residual in a cells × cells grid, then eq 18 with LOO smoothing per component."""
    from boresight.pointing.collocation import fit_semiparametric

    ex = np.linspace(x.min(), x.max() + 1e-12, cells + 1)
    ey = np.linspace(y.min(), y.max() + 1e-12, cells + 1)
    ix = np.clip(np.searchsorted(ex, x, side="right") - 1, 0, cells - 1)
    iy = np.clip(np.searchsorted(ey, y, side="right") - 1, 0, cells - 1)
    cell = ix * cells + iy
    count = np.bincount(cell, minlength=cells * cells)
    use = count >= 2
    if use.sum() < 6:
        return None
    mean = np.stack([np.bincount(cell, f[:, k], cells * cells) for k in range(2)], -1)[use] / count[use, None]
    cx = (0.5 * (ex[:-1] + ex[1:]))[np.arange(cells * cells) // cells][use]
    cy = (0.5 * (ey[:-1] + ey[1:]))[np.arange(cells * cells) % cells][use]
    G = np.ones((cx.size, 1))
    h = np.empty_like(mean)
    smooth = np.empty(2)
    sx, sy = cx / max(np.ptp(cx), 1e-300), cy / max(np.ptp(cy), 1e-300)
    for k in range(2):
        model = fit_semiparametric(G, mean[:, k], sx, sy)
        h[:, k] = model.fit.X[0] + model.fit.h  # G X + h: the smooth field
        smooth[k] = model.fit.smoothing
    return cx, cy, mean, h, count[use], smooth


def collocation_view(x_m, y_m, field_xy_m, cells: int = 6) -> CollocationView | None:
    """Fit the field residuals (n, 2) over the image plane with Tang 2014's collocation."""
    res = _cell_fit(np.asarray(x_m, float), np.asarray(y_m, float), np.asarray(field_xy_m, float), cells)
    if res is None:
        return None
    cx, cy, mean, h, count, smooth = res
    ss = float(np.sum(count[:, None] * mean**2))
    resid = float(np.sum(count[:, None] * (mean - h) ** 2))
    return CollocationView(cx, cy, mean, h, count, smooth, 1.0 - resid / ss if ss > 0 else 0.0)
