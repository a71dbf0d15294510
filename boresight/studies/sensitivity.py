"""Sensitivity of the θ accuracy to each disturbance (Kiev 2012 eq 28), error budgets, the CRLB.

Kiev 2012 eq 28 tabulates ∂σθi/∂σs for s ∈ {β1, β2, β3, P, R, K} and checks
σθi ≈ sqrt(Σ_s (∂σθi/∂σs · σs)²). For an estimator that is linear in the errors (all of ours to
first order) the error is θ̂ − θ = Σ_s K_s ε_s, so σθi² = Σ_s a_is² σs² with

    a_is = sqrt(∂σθi² / ∂(σs²))  — the σθi that source s alone causes per unit of its σ,

which is what the seminar's table holds (its rows reproduce its σθ in quadrature). The
ordinary derivative of the total is ∂σθi/∂σs = a_is² σs / σθi; both are reported.

Three routes, which must agree:

* **Finite differences of Monte Carlo** with common random numbers (``fd_sensitivities``): one
  run of the engine draws each run's errors once and estimates θ for the base case and for
  each source scaled by (1 + h) (``montecarlo.scale_errors``). Then
  a_is² = (σ̂²_{θi}(σs(1+h)) − σ̂²_{θi}(σs)) / (σs² ((1+h)² − 1)), with the Monte Carlo standard
  error from the per-run spread of e_scaled² − e_base².
* **Linear covariance propagation** (``linear_sensitivities``): θ̂ − θ = K L J_s ε_s with the
  estimator's gain K = (GᵀG)⁻¹Gᵀ, its residual map L (``residual_map``) and the error Jacobians
  J_s (``disturbances.error_jacobians``) at the nominal geometry; each source's covariance
  carries its structure over images (per image / per pass / per landmark,
  ``crlb.full_residual_covariance``).
* **Cramér–Rao bound** (``method = "crlb"``): the same propagation through the optimal (GLS)
  gain (GᵀΣ⁻¹G)⁻¹GᵀΣ⁻¹ with the full residual covariance Σ; its contributions add in quadrature
  to the bound ``crlb.cramer_rao_bound``.

Units: β sensitivities in ″/″, P, R and K sensitivities in ″/m.

Example
-------
>>> t = linear_sensitivities("scenarios/kiev2012-sensitivity.toml", ["image_plane"])
>>> row = t[(t["source"] == "R") & (t["method"] == "analytic")][0]
>>> round(float(row["coef_x"]), 2), str(row["unit"])
(0.3, 'arcsec/m')
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from boresight.core import error_sources
from boresight.errors import InputValueError, StudyError
from boresight.studies import montecarlo as mc
from orbits.rotations import ARCSEC

__all__ = [
    "SOURCES",
    "source_sigmas",
    "linear_sensitivities",
    "fd_sensitivities",
    "error_budget",
    "scaled_scenario",
    "SensitivityResult",
    "sensitivity_study",
    "CHECKPOINT_OPTIONS",
]

#: the smallest finite-difference step ``rel_step`` accepted (see ``fd_sensitivities``)
MIN_REL_STEP = 1e-6

#: the sensitivity study's checkpoint identity fields that are not the montecarlo ones, named as
#: the user wrote them (``montecarlo.checkpoint.Checkpoint``)
CHECKPOINT_OPTIONS = {"rel_step": "--rel-step", "variants": None}

#: the seminar's disturbance sources (eq 28), in its order (``boresight.core.error_sources``)
SOURCES = error_sources.SOURCES
_UNITS = {s.symbol: s.sensitivity_unit for s in error_sources.ERROR_SOURCES.values()}
_LABELS = {s.symbol: s.label for s in error_sources.ERROR_SOURCES.values()}


def _scenario(scenario):
    import orbits

    return scenario if isinstance(scenario, orbits.Scenario) else orbits.load_scenario(scenario)


def _algorithms(sc, algorithms, pool) -> tuple:
    """The algorithms of ``pool`` asked for; with ``[[star_frames]]`` (targets at infinity) or a corrected
    ``landmark_sight`` without those that need each target's geometric position (``montecarlo.study.NEEDS_POSITIONS``)
    unless named (then the study refuses them)."""
    from boresight.studies.montecarlo.study import NEEDS_POSITIONS

    names = tuple(a for a in mc.resolve_algorithms(algorithms) if a in pool)
    asked = [algorithms] if isinstance(algorithms, str) else list(algorithms)
    if (sc.star_frames or sc.landmark_sight != "geometric") and all(a in ("all", "least_squares") for a in asked):
        names = tuple(a for a in names if a not in NEEDS_POSITIONS)
    return names


def _n_images(sc) -> int:
    """The campaign's images: its passes' times, and with ``[[star_frames]]`` the frames that see a star."""
    import orbits

    return int(orbits.campaign_arrays(sc)["t_s"].size) if sc.star_frames else sum(len(p.t_s) for p in sc.passes)


def _scenario_sigma(sc, src) -> float:
    v = getattr(sc, src.scenario_field)
    return float(v if src.axis is None else v[src.axis])


def source_sigmas(scenario) -> dict:
    """σs of each source in display units: β in arcsec, P, R, K in m.

    >>> source_sigmas("scenarios/kiev2012-sensitivity.toml")["K"]
    3e-06
    """
    sc = _scenario(scenario)
    return {s.symbol: _scenario_sigma(sc, s) for s in error_sources.ERROR_SOURCES.values()}


def scaled_scenario(scenario, source: str, factor: float):
    """The scenario with source ``source`` (``SOURCES``) scaled by ``factor`` (same seed ⇒ common random numbers).

    >>> scaled_scenario("scenarios/kiev2012-sensitivity.toml", "beta2", 2.0).sigma_star_tracker_arcsec
    (4.0, 8.0, 4.0)
    """
    sc = _scenario(scenario)
    src = error_sources.source(source)
    if not (np.isfinite(factor) and factor >= 0):
        raise InputValueError(f"factor must be a finite number ≥ 0, got {factor!r}")
    v = getattr(sc, src.scenario_field)
    if src.axis is None:
        return replace(sc, **{src.scenario_field: v * factor})
    st = [float(x) for x in v]
    st[src.axis] *= factor
    return replace(sc, **{src.scenario_field: tuple(float(x) for x in st)})


def _unit_model(base, source):
    """The disturbance model with only ``source`` on, at σ = 1 display unit (1″ or 1 m)."""
    from boresight.core.disturbances import DisturbanceModel

    kw = dict(star_tracker_mode=base.star_tracker_mode, gnss_mode=base.gnss_mode)
    src = error_sources.source(source)
    if src.axis is None:
        return DisturbanceModel(**{src.model_field: 1.0}, **kw)
    st = [0.0, 0.0, 0.0]
    st[src.axis] = ARCSEC
    return DisturbanceModel(**{src.model_field: tuple(st)}, **kw)


def _unit_rows(nom, model, unit: dict) -> dict:
    """Per source the nominal rows, the model and the divisor its unit propagation (``_unit_model``: σ = 1 display
    unit) is computed with. A set whose rows carry their own pixel σ (star centroids by magnitude,
    ``sigma_xy_m``): the pixel source scales every row's σ together, as the Monte Carlo variant scales every
    row's drawn noise, so its unit contribution is that of the rows' own σ (the model's σK on the others)
    divided by σK²; every other source is propagated on the rows without their own σ (a unit model has σK = 0)."""
    if nom.sigma_xy_m is None:
        return {s: (nom, unit[s], 1.0) for s in SOURCES}
    scale = model.sigma_pixel_m if model.sigma_pixel_m > 0 else 1.0
    plain = nom.with_sigma_xy(None)
    return {
        s: (nom, replace(unit[s], sigma_pixel_m=scale), scale**2)
        if error_sources.source(s).noise_key == "pixel"
        else (plain, unit[s], 1.0)
        for s in SOURCES
    }


def _gls_weighted_jacobian(nom, model_full):
    """Σ⁻¹ G (1, K, 2, 3) per observation and the information GᵀΣ⁻¹G (3, 3) of the nominal run,
    through the one GLS on rows (``gls.campaign.fit_rows``): no 2K × 2K covariance.

    ``gls.rows.row_residuals`` at a correction dx returns (y − U ν̂)/σK with y = q − G dx and ν̂ the
    MAP nuisances given y; by Woodbury y − U ν̂ = σK² Σ⁻¹ y. With q = 0 and dx = −e_i, y = G e_i, so
    column i of Σ⁻¹ G is that residual / σK (each row's own σ where the set has one: the whitening is
    then diag(1/σ_k) and y − U ν̂ = D Σ⁻¹ y, D the rows' pixel covariance).
    """
    from boresight.core.gls.campaign import fit_rows, single_threaded_blas
    from boresight.core.gls.rows import row_residuals
    from boresight.core.gls.structure import row_pixel_sigma
    from boresight.core.measurement import linearize

    G, _ = linearize(nom, np.zeros(3))  # (1, K, 2, 3)
    fit = fit_rows(nom, np.zeros(3), G, np.zeros(G.shape[:-1]), model_full)
    info = fit.normal_equations.data_information[0]
    with single_threaded_blas():
        SiG = np.stack([row_residuals(fit, -np.eye(3)[i : i + 1]) for i in range(3)], axis=-1)
    sig = row_pixel_sigma(nom, model_full)  # each row's own σ (star rows by magnitude), or the one σK
    SiG = SiG / (model_full.sigma_pixel_m if sig is None else sig[None, :, :, None])
    return SiG, 0.5 * (info + info.T)


def _gains(nom, algorithms, model_full):
    """Per algorithm (+ "crlb"): the weighted Jacobian WG (1, K, 2, 3) per observation whose
    transpose is the gain from the algorithm's residuals to θ̂ − θ, θ̂ − θ = (WG)ᵀ q, and its residual
    map L (1, K, 2, 2) (None: image plane); and the CRLB covariance (3, 3) rad².

    Least squares: WG = G (GᵀG)⁻¹ (the unit-weight gain); the CRLB: WG = Σ⁻¹G (GᵀΣ⁻¹G)⁻¹ (the GLS
    gain, through the GLS on rows). Sizes: a few arrays of K × 2 × 3.
    """
    import importlib

    from boresight.core import registry

    out = {}
    for name in algorithms:
        row = registry.lookup(name)  # the one table of algorithms: its module, linearize and residual map
        mod = importlib.import_module(row.module)
        G, _ = getattr(mod, row.function)(nom, np.zeros(3))
        L = getattr(mod, row.residual_map)(nom, np.zeros(3))
        Gf = G.reshape(-1, 3)
        out[name] = (G @ np.linalg.inv(Gf.T @ Gf), L)
    SiG, info = _gls_weighted_jacobian(nom, model_full)
    crlb_cov = np.linalg.inv(info)
    out["crlb"] = (SiG @ crlb_cov, None)
    return out, crlb_cov


#: working-set bytes of the linear propagation per observation (row) of the nominal run, beside the
#: GLS's own (``gls.rows.row_gls_bytes``): the error Jacobians and scaled columns, the weighted
#: Jacobians and the sandwich's per-row products — campaign-6pass on rows: 5.4 MB traced for its
#: 1 320 rows, 4.3 kB a row (2026-11-27; on the dense images × landmarks layout it was 11.3 MB), × 2
LINEAR_BYTES_PER_ROW = 9000


#: CPU seconds of the linear propagation per observation (row), all algorithms and sources together
#: (campaign-6pass on rows: 0.13 s for 1 320 rows on the loaded project machine, 2026-11-27), × 2
LINEAR_SECONDS_PER_ROW = 2e-4


def _check_linear_memory(sc, nom) -> float:
    from orbits.limits import check_memory

    nbytes = linear_bytes(nom)
    check_memory(
        f"{sc.source}: the linear propagation and the CRLB ({nom.n_images} images, {nom.n_landmarks} landmarks, "
        f"{nom.n_observations} observations)",
        nbytes,
        hint="fewer images or landmarks",
    )
    return nbytes


def linear_bytes(nom) -> float:
    """Estimated peak bytes of ``linear_sensitivities`` on the nominal observations ``nom`` (one run,
    on rows): ``LINEAR_BYTES_PER_ROW`` per observation plus the GLS on rows (``gls.rows.row_gls_bytes``
    of the CRLB's fit: 3 columns, per-image and per-pass nuisances up to 6 and 9 wide)."""
    from boresight.core.gls.rows import RowStructure, row_gls_bytes

    return float(LINEAR_BYTES_PER_ROW * nom.n_observations + row_gls_bytes(RowStructure.of(nom), 1, 3, 6, 9))


#: the leading columns of the FD and linear tables: which estimate, of which source, ∂σθ/∂σs per axis
_COEF_COLUMNS = ("method", "algorithm", "source", "coef_x", "coef_y", "coef_z", "coef_norm", "unit")


def linear_sensitivities(scenario, algorithms=mc.LEAST_SQUARES):
    """Eq 28 sensitivities a_is by linear covariance propagation, and the CRLB's; an astropy Table.

    One row per (method, algorithm, source): ``method`` "analytic" (the algorithm's own
    unit-weight gain) or "crlb" (the optimal GLS gain; ``algorithm`` = "crlb"); ``coef_{x,y,z}``
    and ``coef_norm`` = a_is (``unit``: ″/″ or ″/m); ``contribution_{x,y,z}`` = a_is σs (″).
    ``meta``: ``sigma_theta_arcsec`` {algorithm: [x, y, z, total]} from all sources, and the
    CRLB's ``crlb_sigma_arcsec``.
    """
    from astropy.table import Table

    from boresight.core.disturbances import DisturbanceModel
    from boresight.core.gls.campaign import sandwich_middle

    sc = _scenario(scenario)
    algorithms = _algorithms(sc, algorithms, mc.LEAST_SQUARES)
    nom = mc.nominal_observations(sc)
    _check_linear_memory(sc, nom)
    model = DisturbanceModel.from_scenario(sc)
    gains, crlb_cov = _gains(nom, algorithms, model)
    sig = source_sigmas(sc)
    rows, totals = [], {}
    # DECISION: no source's covariance is formed: its contribution to cov(θ̂) is the sandwich
    # (WG)ᵀ Σ_s (WG) accumulated block by block (per image, per pass, per landmark;
    # ``gls.campaign.sandwich_middle``), linear in images — the dense 2NM × 2NM Σ_s of the
    # 6-pass campaign was 7 GiB per source
    unit = {s: _unit_model(model, s) for s in SOURCES}
    at = _unit_rows(nom, model, unit)
    for name, (WG, L) in gains.items():
        var = np.zeros(3)
        for s in SOURCES:
            rows_s, model_s, divisor = at[s]
            mid = sandwich_middle(rows_s, np.zeros(3), model_s, WG, L)[0] / divisor
            coef = np.sqrt(np.maximum(np.diag(mid), 0.0)) / ARCSEC  # ″ per display unit
            contrib = coef * sig[s]
            var += contrib**2
            rows.append(
                ("crlb" if name == "crlb" else "analytic", name, s, *coef, float(np.linalg.norm(coef)), _UNITS[s], *contrib)
            )
        totals[name] = [*np.sqrt(var), float(np.sqrt(var.sum()))]
    t = Table(
        rows=rows,
        names=[
            *_COEF_COLUMNS,
            "contribution_x",
            "contribution_y",
            "contribution_z",
        ],
    )
    for c in ("contribution_x", "contribution_y", "contribution_z"):
        t[c].unit = "arcsec"
    crlb_sd = np.sqrt(np.diag(crlb_cov)) / ARCSEC
    t.meta.update(
        scenario=sc.name,
        sigma_theta_arcsec=totals,
        crlb_sigma_arcsec=[*crlb_sd, float(np.sqrt((crlb_sd**2).sum()))],
        sources={s: _LABELS[s] for s in SOURCES},
        source_sigmas=sig,
        note="a_is = sqrt(d sigma_theta_i^2 / d sigma_s^2): sigma_theta_i from source s alone per unit sigma_s",
    )
    return t


def fd_sensitivities(scenario, algorithms=mc.LEAST_SQUARES, runs: int = 45000, seed: int = 1, rel_step: float = 1.0, **engine):
    """Eq 28 sensitivities by finite differences of Monte Carlo with common random numbers.

    One engine pass (``montecarlo.montecarlo_study`` with one variant per source) draws every run once and
    estimates the base case and each source scaled by (1 + ``rel_step``).
    DECISION: ``rel_step`` = 1 (σs → 2σs). For an estimator linear in the errors the variance
    difference is exactly a_is² σs² ((1+h)² − 1) plus a cross term 2h cov(ε_s-part, rest) with
    zero mean, so there is no truncation error to trade against, and the larger step shrinks
    the cross term's relative noise.

    Returns ``(table, result)``: rows (method "fd", algorithm, source) with ``coef_*``,
    ``coef_se_*`` (Monte Carlo standard error), ``derivative_*`` = ∂σθi/∂σs = a_is² σs/σθi, and
    the engine's ``MonteCarloResult`` (base σθ in ``moments[algorithm]``). ``engine`` takes
    ``montecarlo.montecarlo_study``'s engine options, ``checkpoint`` (a folder or a ``Checkpoint``) and
    ``resume`` among them: an interrupted study resumes to the same numbers, bit for bit.
    """
    from astropy.table import Table

    from boresight.studies.montecarlo.checkpoint import Checkpoint

    sc = _scenario(scenario)
    # DECISION: H ≥ 1e-6: the denominator (1 + H)² − 1 must be resolved in float64 (below ~1e-16
    # it is 0 and the derivative is inf/nan; at 1e-6 its rounding error is ~1e-10 relative).
    try:
        ok = not isinstance(rel_step, (bool, str)) and np.ndim(rel_step) == 0 and bool(MIN_REL_STEP <= float(rel_step) < np.inf)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise StudyError(f"rel_step must be a finite number ≥ {MIN_REL_STEP:g}, got {rel_step!r}")
    algorithms = _algorithms(sc, algorithms, mc.ALGORITHMS)
    sig = source_sigmas(sc)
    active = [s for s in SOURCES if sig[s] > 0]
    variants = {s: {s: 1.0 + rel_step} for s in active}
    ck = engine.get("checkpoint")
    if ck is not None:
        ck = ck if isinstance(ck, Checkpoint) else Checkpoint(ck, "sensitivity", CHECKPOINT_OPTIONS)
        engine["checkpoint"] = ck.with_extra(rel_step=float(rel_step))
    res = mc.montecarlo_study(sc, algorithms, runs, seed, variants=variants, image_counts=[_n_images(sc)], **engine)
    den_f = (1.0 + rel_step) ** 2 - 1.0
    rows = []
    for name in algorithms:
        base = res.moments[name]
        sd = base.std[0]
        for s in SOURCES:
            if s not in active:
                rows.append(("fd", name, s, *[np.nan] * 4, _UNITS[s], *[np.nan] * 9))
                continue
            dv = res.moments[f"{name}@{s}"].variance[0] - base.variance[0]
            dsq = res.moments[f"{name}@{s}:dsq"]
            se_dv = dsq.std[0] / np.sqrt(dsq.count)
            den = sig[s] ** 2 * den_f
            coef = np.sqrt(np.maximum(dv, 0.0) / den)
            # delta method; where coef ≈ 0 the standard error of coef² is converted directly
            # (an SE of coef² of v gives at most sqrt(v) on coef, the bound used where coef ≈ 0)
            bound = np.sqrt(se_dv / den)
            delta = np.divide(se_dv, 2.0 * coef * den, out=np.full(3, np.inf), where=coef * den > 0)
            se = np.minimum(delta, bound)
            deriv = coef**2 * sig[s] / sd
            rows.append(("fd", name, s, *coef, float(np.linalg.norm(coef)), _UNITS[s], *se, *deriv, *(coef * sig[s])))
    t = Table(
        rows=rows,
        names=[
            *_COEF_COLUMNS,
            "coef_se_x",
            "coef_se_y",
            "coef_se_z",
            "derivative_x",
            "derivative_y",
            "derivative_z",
            "contribution_x",
            "contribution_y",
            "contribution_z",
        ],
    )
    for c in ("contribution_x", "contribution_y", "contribution_z"):
        t[c].unit = "arcsec"
    t.meta.update(scenario=sc.name, runs=int(runs), seed=int(seed), rel_step=float(rel_step), source_sigmas=sig)
    return t, res


def error_budget(linear_table, algorithm: str = "image_plane"):
    """Each source's share of σθi² per axis (linear propagation), plus the star tracker together.

    >>> t = error_budget(linear_sensitivities("scenarios/kiev2012-sensitivity.toml", ["image_plane"]))
    >>> float(round(sum(t["share_z"][:6]), 6))
    1.0
    """
    from astropy.table import Table

    sel = linear_table[(linear_table["algorithm"] == algorithm)]
    if len(sel) == 0:
        raise InputValueError(f"algorithm {algorithm!r} is not in the table (has {sorted(set(linear_table['algorithm']))})")
    c2 = np.array([[row[f"contribution_{a}"] ** 2 for a in "xyz"] for row in sel])
    tot = c2.sum(axis=0)
    rows = []
    for row, v in zip(sel, c2):
        rows.append((row["source"], _LABELS[row["source"]], *(v / tot), *np.sqrt(v)))
    st = np.array([v for row, v in zip(sel, c2) if row["source"].startswith("beta")]).sum(axis=0)
    rows.append(("beta", "star tracker (β1-β3)", *(st / tot), *np.sqrt(st)))
    rows.append(("total", "all sources", 1.0, 1.0, 1.0, *np.sqrt(tot)))
    t = Table(rows=rows, names=["source", "label", "share_x", "share_y", "share_z", "sigma_x", "sigma_y", "sigma_z"])
    for a in "xyz":
        t[f"sigma_{a}"].unit = "arcsec"
    t.meta.update(algorithm=algorithm, note="share of sigma_theta_i^2 from each source (linear covariance propagation)")
    return t


@dataclass
class SensitivityResult:
    """What ``boresight.sensitivity_study`` returns: the Kiev 2012 eq 28 study.

    Attributes
    ----------
    scenario_name : str
        The scenario's name.
    fd : astropy.table.Table
        ∂σθ/∂σs by finite differences of Monte Carlo (common random numbers), with standard errors,
        one row per algorithm and source.
    linear : astropy.table.Table
        The same by linear covariance propagation, with the CRLB rows (``algorithm == "crlb"``).
    budget : astropy.table.Table
        Each source's share of σθ² (linear propagation) for the first least-squares algorithm.
    mc : MonteCarloResult
        The Monte Carlo study behind ``fd``.
    agreement : dict
        Per algorithm, max over sources and axes of abs(FD − analytic) / SE(FD).
    """

    scenario_name: str
    fd: Any  # astropy Table
    linear: Any  # astropy Table
    budget: Any  # astropy Table
    mc: Any  # the Monte Carlo result
    agreement: dict = field(default_factory=dict)

    def montecarlo_sigma_arcsec(self, algorithm: str = "image_plane") -> list[float]:
        """σθ of ``algorithm``'s Monte Carlo at the nominal noise, [x, y, z, total] in arcsec (total: the root sum of
        squares of the three axes), beside ``linear.meta["sigma_theta_arcsec"]`` and ``crlb_sigma_arcsec`` in the
        same form."""
        sd = np.asarray(self.mc.moments[algorithm].std[0], dtype=float)
        return [*(float(v) for v in sd), float(np.sqrt((sd**2).sum()))]

    def comparison(self, algorithm: str = "image_plane"):
        """FD vs analytic vs CRLB, one row per source (x, y, z coefficients); the seminar's column is
        added by ``boresight.reproductions.kiev2012.eq28_comparison``."""
        from astropy.table import Table

        rows = []
        for s in SOURCES:
            fd = self.fd[(self.fd["algorithm"] == algorithm) & (self.fd["source"] == s)][0]
            an = self.linear[(self.linear["algorithm"] == algorithm) & (self.linear["source"] == s)][0]
            cr = self.linear[(self.linear["algorithm"] == "crlb") & (self.linear["source"] == s)][0]
            row = [s, _UNITS[s]]
            for a in "xyz":
                row += [fd[f"coef_{a}"], fd[f"coef_se_{a}"], an[f"coef_{a}"], cr[f"coef_{a}"]]
            rows.append(row)
        names = ["source", "unit"]
        for a in "xyz":
            names += [f"fd_{a}", f"fd_se_{a}", f"analytic_{a}", f"crlb_{a}"]
        return Table(rows=rows, names=names, meta={"algorithm": algorithm})


def sensitivity_study(
    scenario, algorithms=mc.LEAST_SQUARES, runs: int = 45000, seed: int = 1, rel_step: float = 1.0, **engine
) -> SensitivityResult:
    """The whole Kiev 2012 eq 28 study: sensitivities ∂σθ/∂σs by Monte Carlo finite differences
    (common random numbers) and by linear propagation, the CRLB and the error budget.

    Parameters
    ----------
    scenario : orbits.Scenario or str or path
        The scenario or its TOML file; it must have pixel noise (the linear propagation weights by
        the residual covariance).
    algorithms : sequence of str
        Least-squares algorithms (default all of ``montecarlo.LEAST_SQUARES``).
    runs : int
        Monte Carlo runs per case (the base case and one per source, on the same draws).
    seed : int
        The random seed.
    rel_step : float
        Finite-difference step: each σs is scaled by 1 + ``rel_step`` (default 1: doubled).
    **engine
        ``montecarlo_study``'s engine options (``workers``, ``engine``, ``chunk_runs``,
        ``checkpoint``, ``resume``, ``progress``, …); a ``preflight`` callback gets the Monte
        Carlo's sizes with the linear propagation's memory and time included.

    Returns
    -------
    SensitivityResult
        The FD and linear tables, the budget, the Monte Carlo result and ``agreement[algorithm]``
        (max over sources and axes of abs(FD − analytic) / SE(FD)).

    Raises
    ------
    MemoryBudgetError
        The linear propagation or the Monte Carlo would exceed the memory budget (refused before
        anything runs).
    StudyError, ObservabilityError, ResumeError, UnknownAlgorithmError
        As ``montecarlo_study``; ``StudyError`` too for a ``rel_step`` that is not a finite number ≥ 1e-6.
    """
    sc = _scenario(scenario)
    # the linear propagation's memory is checked before the Monte Carlo starts (refused up front)
    nom = mc.nominal_observations(sc)
    lin_bytes = _check_linear_memory(sc, nom)
    pf = engine.pop("preflight", None)
    if pf is not None:
        lin_s = LINEAR_SECONDS_PER_ROW * nom.n_observations
        engine["preflight"] = lambda d: pf(
            {**d, "memory_bytes": max(d["memory_bytes"], lin_bytes), "seconds": d["seconds"] + lin_s}
        )
    fd, res = fd_sensitivities(sc, algorithms, runs, seed, rel_step, **engine)
    lin = linear_sensitivities(sc, [a for a in res.algorithms if a in mc.LEAST_SQUARES])
    agreement = {}
    for name in res.algorithms:
        if name not in mc.LEAST_SQUARES:
            continue
        z = []
        for s in SOURCES:
            f = fd[(fd["algorithm"] == name) & (fd["source"] == s)][0]
            a = lin[(lin["algorithm"] == name) & (lin["source"] == s)][0]
            for ax in "xyz":
                if np.isfinite(f[f"coef_{ax}"]) and f[f"coef_se_{ax}"] > 0:
                    z.append(abs(f[f"coef_{ax}"] - a[f"coef_{ax}"]) / f[f"coef_se_{ax}"])
        agreement[name] = float(max(z)) if z else float("nan")
    first = next(a for a in res.algorithms if a in mc.LEAST_SQUARES)
    return SensitivityResult(sc.name, fd, lin, error_budget(lin, first), res, agreement)


# ---------------------------------------------------------------------------- pushbroom lines


#: the error sources of pushbroom lines (``boresight.observations.strip.line_noise_model``): label, unit of σ, unit of a
LINE_SOURCES = {
    "pixel": ("pixel noise on line and column (px)", "px", "arcsec/px"),
    "star_tracker": ("star tracker, white per sample (″)", "arcsec", "arcsec/arcsec"),
    "star_tracker_gm": ("star tracker, Gauss–Markov (″)", "arcsec", "arcsec/arcsec"),
}


@dataclass
class LineScanSensitivity:
    """Eq 28's sensitivities of pushbroom lines: for each source s of ``LINE_SOURCES`` (σ ``sigma[s]`` in its unit)
    ``coef[s]`` (3,) a_is = √(∂σθi²/∂σs²) (″ per unit σ) by linear propagation through the GLS gain, ``contribution[s]``
    a_is σs (″), ``sigma_theta_arcsec`` (3,) the GLS σ of θ (the contributions add to it in quadrature); by finite
    differences of ``runs`` resimulations with common random numbers (σs × (1 + ``rel_step``)): ``fd_coef[s]``,
    ``fd_se[s]`` (NaN with ``runs`` = 0); ``names`` the unknowns fitted (θ first)."""

    names: list[str]
    sigma: dict[str, float]
    coef: dict[str, np.ndarray]
    contribution: dict[str, np.ndarray]
    sigma_theta_arcsec: np.ndarray
    fd_coef: dict[str, np.ndarray]
    fd_se: dict[str, np.ndarray]
    runs: int
    seed: int
    rel_step: float
    theta_arcsec: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def sources(self) -> list[str]:
        """The sources of ``LINE_SOURCES`` this model has (the Gauss–Markov tracker error only when it has one)."""
        return [s for s in LINE_SOURCES if s in self.coef]

    def share(self, source: str) -> np.ndarray:
        """(3,) the share of σθi² that ``source`` holds."""
        out: np.ndarray = self.contribution[source] ** 2 / self.sigma_theta_arcsec**2
        return out


def _line_gain(strips, x, unknowns, model, model_unit):
    """(the GLS gain WG (K, 2, n) from the whitened residuals to x̂ − x, its covariance (n, n), the unit-σ tracker
    columns (K, 2, 3) and the row structure): through the one GLS on rows, as ``_gls_weighted_jacobian`` does for a
    frame camera (``gls.rows.row_residuals`` at q = 0, dx = −e_i gives column i of Σ̃⁻¹X, Σ̃ = E + ÃÃᵀ in the
    rows' whitened units)."""
    from boresight.core.gls.campaign import single_threaded_blas
    from boresight.core.gls.rows import RowColumns, row_gls, row_residuals
    from boresight.core.line_scan import stacked_rows

    st, cols = stacked_rows(strips, x, unknowns, model)
    _, unit = stacked_rows(strips, x, unknowns, model_unit)
    n = x.size
    with single_threaded_blas():
        fit = row_gls(st, RowColumns(cols.X, np.zeros_like(cols.q), cols.A, cols.B, cols.C))
        SiX = np.stack([row_residuals(fit, -np.eye(n)[i : i + 1]) for i in range(n)], axis=-1)[0]
    info = fit.normal_equations.data_information[0]
    cov = np.linalg.inv(0.5 * (info + info.T))
    return SiX @ cov, cov, unit.A[0], st


def line_scan_sensitivities(
    strips, unknowns, model, runs: int = 0, seed: int = 1, rel_step: float = 1.0, x=None
) -> LineScanSensitivity:
    """Eq 28 on pushbroom lines (``strips``: one ``ObservationSet`` of lines or several; ``unknowns`` the
    ``LineScanUnknowns`` floated with θ; ``model`` from ``line_noise_model``), about the fit of the strips (``x`` given:
    about x). Two routes:

    * **linear propagation through the GLS gain**: x̂ − x = WGᵀ q̃ with q̃ the rows whitened by their pixel noise
      (``core.line_scan.line_scan_rows``), so the pixel noise's part of cov(x̂) is WGᵀWG and the tracker's
      Σ_s M_s M_sᵀ with M_s = Σ_k w_ks WG_kᵀ Ã_k (each row's tracker columns Ã_k at unit σ, sample s's weight w_ks in
      its line: ``StripTrajectory.tracker_sample_weights``) times σ²; the two add up to the GLS covariance (the gain
      is the optimal one: this is also the CRLB's split);
    * **finite differences of Monte Carlo** (``runs`` > 0): run k resimulates the strips about the fit
      (``montecarlo.line_scan.resimulate_lines``, run k of strip j from ``default_rng([seed, j, k])``) once as the
      model is and once per source with its σ × (1 + ``rel_step``), the same random numbers (common random numbers:
      the draws are standard normals times σ), and refits each; a_is² = (mean e_s² − mean e_0²) / (σs² ((1 + h)² − 1))
      with its standard error from the per-run spread of e_s² − e_0².
    """
    from boresight.core.gls.rows import row_sandwich_middle
    from boresight.core.line_scan import estimate_line_scan
    from boresight.observations.strip import line_noise_model

    strips = list(strips) if isinstance(strips, (list, tuple)) else [strips]
    pitch = strips[0].line_scan.sensor.pixel_pitch_m
    sig = {"pixel": model.sigma_pixel_m / pitch, "star_tracker": float(model.sigma_star_tracker_rad[0] / ARCSEC)}
    if model.has_correlated_tracker:
        sig["star_tracker_gm"] = float(model.sigma_star_tracker_correlated_rad[0] / ARCSEC)
    fit = estimate_line_scan(strips, unknowns, model) if x is None else None
    x = fit.x if fit is not None else np.asarray(x, float)
    WG, cov, A1, st = _line_gain(strips, x, unknowns, model, line_noise_model(sig["pixel"], 1.0, pitch))
    n = x.size
    Wf = WG.reshape(-1, n)
    parts = {"pixel": (Wf.T @ Wf) / sig["pixel"] ** 2}
    M = np.einsum("kjn,kja->kna", WG, A1)  # per row: its image's tracker error (unit σ) → x̂
    S = np.zeros((int(st.n_samples), n, 3))
    img = st.image_index
    for i in range(2):
        np.add.at(S, st.sample_index[img, i], st.sample_weight[img, i][:, None, None] * M)
    parts["star_tracker"] = np.einsum("sna,sma->nm", S, S)
    if "star_tracker_gm" in sig:
        # the Gauss–Markov part: the same unit columns under the samples' AR(1) correlation K (its last three columns'
        # φ), Σ_a T_aᵀ K T_a — the one GLS's sandwich middle (``gls.rows.row_sandwich_middle``, a banded solve)
        assert st.sample_correlation is not None
        gm_st = replace(st, sample_correlation=st.sample_correlation[:, -3:])
        parts["star_tracker_gm"] = row_sandwich_middle(gm_st, WG[None], np.zeros((2, 2)), A1[None], None, None)[0]
    coef = {s: np.sqrt(np.maximum(np.diag(P)[:3], 0.0)) / ARCSEC for s, P in parts.items()}
    contribution = {s: coef[s] * sig[s] for s in coef}
    fd_coef = {s: np.full(3, np.nan) for s in coef}
    fd_se = {s: np.full(3, np.nan) for s in coef}
    if runs > 0:
        fd_coef, fd_se = _line_fd(strips, unknowns, model, x, sig, runs, seed, rel_step, pitch, estimate_line_scan)
    return LineScanSensitivity(
        list(unknowns.names),
        sig,
        coef,
        contribution,
        np.sqrt(np.diag(cov)[:3]) / ARCSEC,
        fd_coef,
        fd_se,
        int(runs),
        int(seed),
        float(rel_step),
        np.degrees(x[:3]) * 3600.0,
    )


def _line_fd(strips, unknowns, model, x, sig, runs, seed, rel_step, pitch, estimate_line_scan):
    """The finite-difference route of ``line_scan_sensitivities``: (coef, se) per source (3,) each."""
    from boresight.observations.strip import line_noise_model
    from boresight.studies.montecarlo.line_scan import resimulate_lines, true_lines

    if not (isinstance(runs, (int, np.integer)) and runs >= 2):
        raise StudyError(f"--runs must be an integer ≥ 2 for the finite differences, got {runs!r}")
    n_chips = strips[0].line_scan.sensor.n_chips
    truth = [true_lines(o, unknowns.parameters(x, n_chips)) for o in strips]
    f = 1.0 + rel_step
    tau = model.star_tracker_correlation_time_s

    def scaled(source: str) -> Any:  # the model with one source's σ × f (the Gauss–Markov σ and τ kept)
        g = {k: v * (f if k == source else 1.0) for k, v in sig.items()}
        gm = g.get("star_tracker_gm", 0.0)
        return line_noise_model(
            g["pixel"], g["star_tracker"], pitch, sigma_star_tracker_correlated_arcsec=gm, correlation_time_s=tau
        )

    models = {"base": model, **{s: scaled(s) for s in sig}}
    e2 = {k: np.empty((runs, 3)) for k in models}
    for k in range(runs):
        for name, m in models.items():
            sims = [
                resimulate_lines(o, L, p, m, np.random.default_rng([seed, j, k]))
                for j, (o, (L, p)) in enumerate(zip(strips, truth))
            ]
            # every case refitted with the base model's weights: the estimator is fixed, only the errors grow
            e2[name][k] = ((estimate_line_scan(sims, unknowns, model).x[:3] - x[:3]) / ARCSEC) ** 2
    coef, se = {}, {}
    for s in sig:
        d = (e2[s] - e2["base"]) / (sig[s] ** 2 * (f**2 - 1.0)) if sig[s] > 0 else np.full((runs, 3), np.nan)
        a2 = d.mean(axis=0)
        coef[s] = np.sqrt(np.maximum(a2, 0.0))
        # SE of a = √a² by the delta method: se(a²) / (2a)
        se[s] = d.std(axis=0, ddof=1) / np.sqrt(runs) / np.maximum(2.0 * coef[s], 1e-300)
    return coef, se
