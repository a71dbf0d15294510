"""``diagnose`` on pushbroom lines: which line-scanner effect (``orbits.effects.LINE_EFFECTS``) the residuals of a θ fit
hold, named by the one naming rule (``rule``: significant at the Holm level and decisive by BIC, not ambiguous).

1. **Base fit.** θ (and the ``base`` unknowns) by ``boresight.core.line_scan.estimate_line_scan``: the GLS on rows
   with the noise model's nuisances on the attitude-sample table.
2. **Candidates' columns at the base solution.** The line-time offset, the line-period error, the focal scale and each
   chip's (along, across) look-angle offset by the model's own central differences (``line_scan_rows``); the jitter at
   each frequency f of a grid over its ``scan_range`` (step 1/(4 T), T the strip's duration: the Rayleigh resolution
   1/T oversampled four times) as six columns, X_θ sin 2πft and X_θ cos 2πft per camera axis (the jitter is a rotation
   in camera axes like θ: its derivative at zero amplitude is θ's, to O(θ) ≈ 1e-4 relative, times the sinusoid).
3. **One GLS with every column.** ``row_gls`` with x = [base, candidates, jitter grid] gives the reduced information
   B, right-hand side y and weighted sum of squares s at the base solution; the GLS χ² of any set S of columns is
   s − y_Sᵀ B_SS⁻¹ y_S, so each candidate's likelihood-ratio statistic Δχ² = χ²(base) − χ²(base ∪ candidate) is a small
   solve (linearised at the base solution: the effects are small against the model's curvature, module docstring of
   ``line_scan``). The jitter's Δχ² is the largest over the grid, at its frequency.
4. **Naming rounds** (``rule.classify``): K candidate families in play (the jitter one family) at the Holm level α/K;
   the jitter's level is further divided by the grid's size (Bonferroni over the scan: conservative, the grid is
   oversampled). The best named candidate is named unless another significant candidate is within
   2·``AMBIGUITY_DLOGL`` of its Δχ² (ambiguous: nothing more is named); a named one joins the base and the next round
   tests the rest at α/(K − 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.campaign import single_threaded_blas
from boresight.core.gls.rows import RowColumns, row_gls
from boresight.core.line_scan import LineScanFit, LineScanUnknowns, estimate_line_scan, line_scan_rows
from boresight.stats import chi2_sf
from boresight.studies.discrepancy.rule import AMBIGUITY_DLOGL, NAMED, NOT_SIGNIFICANT, classify, critical_value
from orbits.effects import LINE_EFFECTS

__all__ = ["LineCandidate", "LineDiagnosis", "diagnose_line_scan", "JITTER_OVERSAMPLING"]

#: the jitter scan's grid step is the Rayleigh resolution 1/T divided by this
JITTER_OVERSAMPLING = 4


@dataclass
class LineCandidate:
    """One candidate's test in the last round it was tested: ``label`` (``chip_offset[1]``, ``jitter``), its effect
    ``name``, rank ``k``, ``delta_chi2``, p-value, the ``level`` it was tested at, its ``verdict`` (``rule``: named,
    significant not decisive, not significant; or ``ambiguous``), and for the jitter the scanned ``frequency_hz``."""

    label: str
    name: str
    k: int
    delta_chi2: float
    p_value: float
    level: float
    verdict: str
    frequency_hz: float | None = None


@dataclass
class LineDiagnosis:
    """The base fit, every candidate's test, the named effects in naming order and the rows."""

    base: LineScanFit
    candidates: list[LineCandidate]
    named: list[str]
    n_rows: int
    jitter_grid_hz: np.ndarray = field(repr=False)

    def text(self) -> str:
        """A plain-text report: the base χ² and each candidate's verdict."""
        lines = [
            f"base fit: θ = {np.array2string(self.base.theta_arcsec, precision=3)}″, χ² = {self.base.chi2:.1f} on "
            f"{self.base.dof} degrees of freedom ({self.n_rows} residual components)"
        ]
        for c in sorted(self.candidates, key=lambda c: -c.delta_chi2):
            at = f" at {c.frequency_hz:.3f} Hz" if c.frequency_hz is not None else ""
            lines.append(
                f"  {c.label:<22} k={c.k}  Δχ² = {c.delta_chi2:9.2f}{at}  p = {c.p_value:.2e} (level {c.level:.1e}): {c.verdict}"
            )
        lines.append("named: " + (", ".join(self.named) if self.named else "nothing"))
        return "\n".join(lines)


def _families(unknowns: LineScanUnknowns, n_chips: int) -> list[tuple[str, str, LineScanUnknowns]]:
    """(label, effect name, the unknowns it adds) for every candidate not in the base."""
    out = []
    if not unknowns.line_time_offset:
        out.append(("line_time_offset", "line_time_offset", LineScanUnknowns(line_time_offset=True)))
    if not unknowns.line_period_error:
        out.append(("line_period_error", "line_period_error", LineScanUnknowns(line_period_error=True)))
    if not unknowns.focal_scale:
        out.append(("focal_scale", "focal_scale", LineScanUnknowns(focal_scale=True)))
    for c in range(n_chips):
        pair = ((c, 0), (c, 1))
        if not set(pair) & set(unknowns.chip_offsets):
            out.append((f"chip_offset[{c}]", "chip_offset", LineScanUnknowns(chip_offsets=pair)))
    return out


def _chi2(B: np.ndarray, y: np.ndarray, s: float, idx: list[int]) -> float:
    """The GLS χ² of the columns ``idx``: s − y_Sᵀ B_SS⁻¹ y_S."""
    i = np.asarray(idx)
    return float(s - y[i] @ np.linalg.solve(B[np.ix_(i, i)], y[i]))


def diagnose_line_scan(
    obs: Any,
    model: DisturbanceModel,
    base: LineScanUnknowns = LineScanUnknowns(),
    sigma_pixel_px: float | None = None,
    alpha: float = 0.01,
    jitter: bool = True,
) -> LineDiagnosis:
    """Name the line-scanner effects the residuals of a θ (+ ``base``) fit hold (module docstring); ``alpha`` the
    family-wise level of the naming rounds."""
    with single_threaded_blas():
        return _diagnose(obs, model, base, sigma_pixel_px, alpha, jitter)


def _diagnose(
    obs: Any, model: DisturbanceModel, base: LineScanUnknowns, sigma_pixel_px: float | None, alpha: float, jitter: bool
) -> LineDiagnosis:
    ls = obs.line_scan
    n_chips = ls.sensor.n_chips
    fit = estimate_line_scan(obs, base, model, sigma_pixel_px)
    fams = _families(base, n_chips)
    full = LineScanUnknowns(
        line_time_offset=True,
        line_period_error=True,
        focal_scale=True,
        chip_offsets=tuple(base.chip_offsets) + tuple(p for _, _, u in fams for p in u.chip_offsets),
    )
    # x of the full unknowns at the base solution: θ, then each scalar as the base has it, chips in ``full``'s order
    names_full, names_base = full.names, base.names
    x_full = np.zeros(len(names_full))
    for j, nm in enumerate(names_full):
        if nm in names_base:
            x_full[j] = fit.x[names_base.index(nm)]
    st, cols = line_scan_rows(obs, x_full, full, model, sigma_pixel_px)
    X = cols.X
    t = np.asarray(obs.t_s)[np.asarray(obs.image_index)]
    T = float(np.ptp(t)) if t.size > 1 else 1.0
    lo, hi = LINE_EFFECTS["jitter"].scan_range
    grid = np.arange(lo, hi + 1e-12, 1.0 / (JITTER_OVERSAMPLING * T)) if jitter else np.zeros(0)
    tt = t - t.mean()
    Xj = [X[..., :3] * f(2 * np.pi * fr * tt)[None, :, None, None] for fr in grid for f in (np.sin, np.cos)]
    Xall = np.concatenate([X] + Xj, axis=-1) if Xj else X
    fitall = row_gls(st, RowColumns(X=Xall, q=cols.q, A=cols.A, B=cols.B, C=cols.C))
    ne = fitall.normal_equations
    Bm, y, s = ne.data_information[0], ne.vector[0], float(ne.weighted_sum_squares[0])
    n_rows = int(ne.n_residuals[0])
    col = {nm: j for j, nm in enumerate(names_full)}
    base_idx = [col[nm] for nm in names_base]
    fam_idx = {label: [col[nm] for nm in u.names[3:]] for label, _, u in fams}
    fam_name = {label: name for label, name, _ in fams}
    n0 = len(names_full)
    jit_idx = [list(range(n0 + 6 * m, n0 + 6 * m + 6)) for m in range(grid.size)]
    in_play = [label for label, _, _ in fams] + (["jitter"] if grid.size else [])
    named: list[str] = []
    results: dict[str, LineCandidate] = {}
    current = list(base_idx)
    while in_play:
        K = len(in_play)
        chi0 = _chi2(Bm, y, s, current)
        tests: dict[str, tuple[float, int, float, float | None]] = {}
        for label in in_play:
            if label == "jitter":
                dj = np.array([chi0 - _chi2(Bm, y, s, current + j) for j in jit_idx])
                m = int(np.argmax(dj))
                tests[label] = (float(dj[m]), 6, alpha / K / grid.size, float(grid[m]))
            else:
                k = len(fam_idx[label])
                tests[label] = (chi0 - _chi2(Bm, y, s, current + fam_idx[label]), k, alpha / K, None)
        for label, (d, k, level, fr) in tests.items():
            results[label] = LineCandidate(
                label,
                "jitter" if label == "jitter" else fam_name[label],
                k,
                d,
                float(chi2_sf(d, k)),
                level,
                classify(d, k, level, n_rows),
                fr,
            )
        significant = [lb for lb in in_play if results[lb].verdict != NOT_SIGNIFICANT]
        winners = [lb for lb in significant if results[lb].verdict == NAMED]
        if not winners:
            break
        best = max(
            winners, key=lambda lb: results[lb].delta_chi2 - float(critical_value(results[lb].k, results[lb].level, n_rows))
        )
        rivals = [
            lb for lb in significant if lb != best and results[best].delta_chi2 - results[lb].delta_chi2 < 2 * AMBIGUITY_DLOGL
        ]
        if rivals:
            for lb in [best] + rivals:
                results[lb].verdict = "ambiguous"
            break
        named.append(best)
        in_play.remove(best)
        f_best = results[best].frequency_hz
        if f_best is not None:  # the jitter, at its scanned frequency
            current = current + jit_idx[int(np.argmin(np.abs(grid - f_best)))]
        else:
            current = current + fam_idx[best]
    return LineDiagnosis(fit, list(results.values()), named, n_rows, grid)
