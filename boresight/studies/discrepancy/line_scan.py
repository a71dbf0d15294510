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
4. **Separability** (the frame diagnosis' rule, ``linear``: ``SEPARABILITY_RHO``): with G the reduced information
   of step 3, b the base columns and c a candidate's, the canonical correlations ρ of c with the base are the
   generalised eigenvalues 1 − ρ² of G_cc − G_cb G_bb⁻¹ G_bc against G_cc (``linear.separable_basis``). A candidate with
   no direction of ρ ≤ 0.995 is **not separable** on this strip/campaign: it is not tested (its Δχ² would be noise
   or second-order detail) and never reported "not significant"; the report gives ρ, its correlation with θ alone
   and the θ shift it causes unfitted at its typical size, R_θ c with R = G_bb⁻¹ G_bc (the regression of c on the
   base, ``linear``'s "θ shift"), and what separates it (``LINE_EFFECTS[…].separated_by``). One with some separable
   directions is tested on them (its Δχ² has that many degrees of freedom), unless, as in the frame diagnosis
   (``naming.identifiability``), the smallest size it could name (power 0.8) lies outside its physical range: then it
   is not separable too. On one strip a line-time offset is a
   pitch rotation v δt/ρ_slant to ~1e-4 (ρ > 0.9999: not separable, it moves θy); strips at several roll angles
   separate it (``tests/studies/test_line_diagnose.py``).
5. **Naming rounds** (``rule.classify``): K candidate families in play (the jitter one family) at the Holm level α/K;
   the jitter's level is further divided by the grid's size (Bonferroni over the scan: conservative, the grid is
   oversampled). The best named candidate is named unless another significant candidate is within
   2·``AMBIGUITY_DLOGL`` of its Δχ² (ambiguous: nothing more is named); a named one joins the base and the next round
   tests the rest at α/(K − 1).

Several strips (a list of ``ObservationSet``) are diagnosed as one campaign: θ and the candidates common, the rows of
``core.line_scan.stacked_rows`` (strip k the pass k).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.campaign import single_threaded_blas
from boresight.core.gls.rows import RowColumns, row_gls
from boresight.core.line_scan import LineScanFit, LineScanUnknowns, estimate_line_scan, stacked_rows
from boresight.stats import chi2_sf
from boresight.studies.discrepancy.linear import SEPARABILITY_RHO, canonical_correlation, separable_basis
from boresight.studies.discrepancy.rule import (
    AMBIGUITY_DLOGL,
    NAMED,
    NOT_SIGNIFICANT,
    classify,
    critical_value,
    nameable_noncentrality,
)
from orbits.effects import LINE_EFFECTS
from orbits.rotations import ARCSEC

__all__ = ["LineCandidate", "LineDiagnosis", "diagnose_line_scan", "JITTER_OVERSAMPLING"]

#: a candidate's verdict when no direction of it is separable from θ and the base unknowns (``SEPARABILITY_RHO``)
NOT_SEPARABLE = "not separable"

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
    #: canonical correlations with θ and the base unknowns (descending), and the largest with θ alone
    rho: tuple[float, ...] = ()
    corr_theta: float = 0.0
    #: directions of the candidate separable from the base (ρ ≤ ``SEPARABILITY_RHO``); 0: not separable
    separable_rank: int = 0
    #: θ's shift (3,) in arcsec were the candidate present unfitted at its typical size (its largest-shift parameter)
    theta_shift_arcsec: tuple[float, ...] = ()
    #: that parameter and its typical size, in its catalogue unit
    shift_parameter: str = ""
    typical_size: float = 0.0
    separated_by: str = ""
    #: why a candidate is not separable (the frame's two reasons, ``naming.identifiability``)
    reason: str = ""


@dataclass
class LineDiagnosis:
    """The base fit, every candidate's test, the named effects in naming order and the rows."""

    base: LineScanFit
    candidates: list[LineCandidate]
    named: list[str]
    n_rows: int
    jitter_grid_hz: np.ndarray = field(repr=False)
    n_strips: int = 1

    @property
    def not_separable(self) -> list[LineCandidate]:
        """The candidates no direction of which is separable from θ and the base unknowns on this data."""
        return [c for c in self.candidates if c.verdict == NOT_SEPARABLE]

    def text(self) -> str:
        """A plain-text report: the base χ² and each candidate's verdict."""
        lines = [
            f"base fit: θ = {np.array2string(self.base.theta_arcsec, precision=3)}″, χ² = {self.base.chi2:.1f} on "
            f"{self.base.dof} degrees of freedom ({self.n_rows} residual components)"
        ]
        where = "strip" if self.n_strips == 1 else f"campaign of {self.n_strips} strips"
        for c in sorted(self.candidates, key=lambda c: (c.verdict == NOT_SEPARABLE, -c.delta_chi2)):
            if c.verdict == NOT_SEPARABLE:
                th = np.asarray(c.theta_shift_arcsec)
                a = int(np.argmax(np.abs(th)))
                lines.append(
                    f"  {c.label:<22} not separable on this {where}: canonical correlation {c.rho[-1]:.5f} with θ and the "
                    f"base unknowns ({c.corr_theta:.5f} with θ alone; {c.reason}); unfitted at {c.shift_parameter} = {c.typical_size:g} it "
                    f"moves θ{'xyz'[a]} by {th[a]:+.3f}″ (θ shift {np.array2string(th, precision=3)}″). Not tested: fly "
                    f"another roll/strip. Separated by: {c.separated_by}"
                )
                continue
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


def _chi2(B: np.ndarray, y: np.ndarray, s: float, T: np.ndarray) -> float:
    """The GLS χ² of the columns X T (T (p, m): indices as unit columns, or separable directions): s − yᵀT (TᵀBT)⁻¹ Tᵀy."""
    yT = T.T @ y
    return float(s - yT @ np.linalg.solve(T.T @ B @ T, yT))


def _unit(p: int, idx: list[int]) -> np.ndarray:
    """The (p, len(idx)) selection of the columns ``idx``."""
    out = np.zeros((p, len(idx)))
    out[idx, np.arange(len(idx))] = 1.0
    return out


def _typical_si(label: str, name: str) -> tuple[list[str], np.ndarray]:
    """The candidate's parameter names (catalogue units) and typical sizes in the unknowns' SI units."""
    e = LINE_EFFECTS[name]
    si = np.array([v * (ARCSEC if u == "arcsec" else 1.0) for v, u in zip(e.scale, e.unit_names)])
    return [f"{label}.{p}" for p in e.param_names], si


def _undetectable(name: str, info: np.ndarray, rank: int, level: float, n_rows: int, power: float) -> bool:
    """The frame diagnosis' second reason for "not separable" (``naming.identifiability``): every parameter's minimum
    detectable size √(λ*/F_jj) (λ* the naming rule's nameable non-centrality at ``level`` and ``power``, F = C⊥ᵀC⊥ in
    SI) lies outside its physical range."""
    e = LINE_EFFECTS[name]
    lam = nameable_noncentrality(max(rank, 1), level, n_rows, power)
    Fd = np.diag(info)
    mde = np.where(Fd > 0, np.sqrt(lam / np.where(Fd > 0, Fd, 1.0)), np.inf)
    reach = np.array(
        [max(abs(lo), abs(hi)) * (ARCSEC if u == "arcsec" else 1.0) for (lo, hi), u in zip(e.physical_range, e.unit_names)]
    )
    return bool(np.all(mde > reach))


def diagnose_line_scan(
    obs: Any,
    model: DisturbanceModel,
    base: LineScanUnknowns = LineScanUnknowns(),
    sigma_pixel_px: float | None = None,
    alpha: float = 0.01,
    jitter: bool = True,
    power: float = 0.8,
) -> LineDiagnosis:
    """Name the line-scanner effects the residuals of a θ (+ ``base``) fit hold (module docstring); ``alpha`` the
    family-wise level of the naming rounds, ``power`` that of the minimum detectable sizes the separability check
    compares with the physical ranges (the frame diagnosis' default)."""
    with single_threaded_blas():
        return _diagnose(obs, model, base, sigma_pixel_px, alpha, jitter, power)


def _diagnose(
    obs: Any,
    model: DisturbanceModel,
    base: LineScanUnknowns,
    sigma_pixel_px: float | None,
    alpha: float,
    jitter: bool,
    power: float,
) -> LineDiagnosis:
    strips = list(obs) if isinstance(obs, (list, tuple)) else [obs]
    n_chips = strips[0].line_scan.sensor.n_chips
    fit = estimate_line_scan(strips if len(strips) > 1 else strips[0], base, model, sigma_pixel_px)
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
    st, cols = stacked_rows(strips, x_full, full, model, sigma_pixel_px)
    X = cols.X
    # DECISION: the jitter is scanned on one strip only: across strips days apart its phase is not common, and a
    # per-strip amplitude and phase at each frequency is 6 columns a strip a grid point (not built)
    jitter = jitter and len(strips) == 1
    t = np.asarray(strips[0].t_s)[np.asarray(strips[0].image_index)]
    T = float(np.ptp(t)) if t.size > 1 else 1.0
    lo, hi = LINE_EFFECTS["jitter"].scan_range
    grid = np.arange(lo, hi + 1e-12, 1.0 / (JITTER_OVERSAMPLING * T)) if jitter else np.zeros(0)
    tt = t - t.mean()
    Xj = [X[..., :3] * f(2 * np.pi * fr * tt)[None, :, None, None] for fr in grid for f in (np.sin, np.cos)]
    Xall = np.concatenate([X] + Xj, axis=-1) if Xj else X
    fitall = row_gls(st, RowColumns(X=Xall, q=cols.q, A=cols.A, B=cols.B, C=cols.C))
    ne = fitall.normal_equations
    Bm, y, s = ne.data_information[0], ne.vector[0], float(ne.weighted_sum_squares[0])
    p = Bm.shape[0]
    n_rows = int(ne.n_residuals[0])
    col = {nm: j for j, nm in enumerate(names_full)}
    base_idx = [col[nm] for nm in names_base]
    fam_idx = {label: [col[nm] for nm in u.names[3:]] for label, _, u in fams}
    fam_name = {label: name for label, name, _ in fams}
    n0 = len(names_full)
    jit_idx = [list(range(n0 + 6 * m, n0 + 6 * m + 6)) for m in range(grid.size)]
    results: dict[str, LineCandidate] = {}
    n_families = len(fam_idx) + (1 if grid.size else 0)
    # separability from θ and the base unknowns (module docstring, step 4): each family's separable directions
    Gbb = Bm[np.ix_(base_idx, base_idx)]
    fam_dirs: dict[str, np.ndarray] = {}
    for label in fam_idx:
        c = fam_idx[label]
        Gcc, Gbc = Bm[np.ix_(c, c)], Bm[np.ix_(base_idx, c)]
        R = np.linalg.solve(Gbb, Gbc)  # regression of the candidate's columns on the base's
        info = Gcc - Gbc.T @ R  # C⊥ᵀC⊥: what the data keep of the candidate once the base has taken its share
        rho, V = separable_basis(Gcc, info, SEPARABILITY_RHO)
        reason = f"above the cut {SEPARABILITY_RHO}"
        if V.shape[1] and _undetectable(fam_name[label], info, V.shape[1], alpha / n_families, n_rows, power):
            V = V[:, :0]
            reason = "the smallest detectable size lies outside the physical range"
        fam_dirs[label] = V
        pnames, size = _typical_si(label, fam_name[label])
        shift = np.degrees(R[:3] * size[None, :]) * 3600.0  # θ shift (arcsec) per parameter at its typical size
        jmax = int(np.argmax(np.linalg.norm(shift, axis=0)))
        unit = LINE_EFFECTS[fam_name[label]].scale[jmax]
        results[label] = LineCandidate(
            label,
            fam_name[label],
            len(c),
            0.0,
            1.0,
            0.0,
            NOT_SEPARABLE if V.shape[1] == 0 else "",
            rho=tuple(float(r) for r in rho),
            corr_theta=canonical_correlation(Gbb[:3, :3], Gcc, Gbc[:3]),
            separable_rank=int(V.shape[1]),
            theta_shift_arcsec=tuple(float(v) for v in shift[:, jmax]),
            shift_parameter=pnames[jmax],
            typical_size=float(unit),
            separated_by=LINE_EFFECTS[fam_name[label]].separated_by,
            reason=reason if V.shape[1] == 0 else "",
        )
    in_play = [lb for lb in fam_idx if fam_dirs[lb].shape[1] > 0] + (["jitter"] if grid.size else [])
    named: list[str] = []
    current = _unit(p, base_idx)
    # Holm: a not-separable candidate is a hypothesis never rejected (p = 1), so it stays in every round's count
    n_untested = sum(1 for c in results.values() if c.verdict == NOT_SEPARABLE)
    while in_play:
        K = len(in_play) + n_untested
        chi0 = _chi2(Bm, y, s, current)
        tests: dict[str, tuple[float, int, float, float | None]] = {}
        for label in in_play:
            if label == "jitter":
                dj = np.array([chi0 - _chi2(Bm, y, s, np.hstack([current, _unit(p, j)])) for j in jit_idx])
                m = int(np.argmax(dj))
                tests[label] = (float(dj[m]), 6, alpha / K / grid.size, float(grid[m]))
            else:
                D = _unit(p, fam_idx[label]) @ fam_dirs[label]
                tests[label] = (chi0 - _chi2(Bm, y, s, np.hstack([current, D])), D.shape[1], alpha / K, None)
        for label, (d, k, level, fr) in tests.items():
            old = results.get(label)
            kw = {} if old is None else {f: getattr(old, f) for f in _SEPARABILITY_FIELDS}
            results[label] = LineCandidate(
                label,
                "jitter" if label == "jitter" else fam_name[label],
                k,
                d,
                float(chi2_sf(d, k)),
                level,
                classify(d, k, level, n_rows),
                fr,
                **kw,
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
            add = _unit(p, jit_idx[int(np.argmin(np.abs(grid - f_best)))])
        else:
            add = _unit(p, fam_idx[best]) @ fam_dirs[best]
        current = np.hstack([current, add])
    # a candidate never tested (not separable) keeps its separability verdict
    return LineDiagnosis(fit, list(results.values()), named, n_rows, grid, len(strips))


_SEPARABILITY_FIELDS = (
    "rho",
    "corr_theta",
    "separable_rank",
    "theta_shift_arcsec",
    "shift_parameter",
    "typical_size",
    "separated_by",
    "reason",
)
