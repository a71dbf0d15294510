"""How many pushbroom strips, at which roll angles, separate θ from the line's own unknowns: the information of each
strip's ``[estimate]`` unknowns (``boresight.core.line_scan``: θ, the line-time offset δt, the focal scale, chips'
look-angle offsets), added over strips, inverted.

**A strip's Fisher block.** A strip is drawn noise-free at the scenario's truth x* (``orbits.strip.simulate_strip``,
pixel and tracker noise zero) and its rows are built at x* by the estimator's own row builder
(``core.line_scan.stacked_rows``: central-difference Jacobians of the simulator's forward model, each row whitened by
its (line, pixel) noise, the star tracker's per-sample errors as nuisance columns on the attitude-sample table). The
one GLS on rows (``core.gls.rows.row_gls``) eliminates those nuisances exactly and leaves the reduced information

    I_k = X_kᵀ Σ_k⁻¹ X_k        (n × n, SI units of x)

— the inverse of the covariance ``estimate_line_scan`` reports for that strip at x*. Every nuisance of the pushbroom
noise model belongs to one strip (a strip's tracker samples, its own ground-control points: ``stacked_rows`` puts
strips side by side), so **the information of a campaign is the sum of its strips' blocks**, I = Σ_k I_k (tested
against ``estimate_line_scan`` on the stacked strips), exactly as the frame planner's passes add
(``studies.planning.fisher``). Each campaign's covariance P = I⁻¹ comes from ``fisher.covariance_batch`` (the
planner's one inverse: unit-diagonal scaling, a 1e-12 ridge, "not determined" flagged).

Two questions use the blocks:

* ``plan_strips(sc)``: every non-empty subset of a pushbroom scenario's own strips (``[[strips]]``: days, sites,
  rolls), scored by its largest σ of θ; the best subset of each size is marked.
* ``plan_rolls(sc, rolls_deg, max_strips, target_theta_arcsec, target_chip_arcsec)``: candidate strips generated on
  the scenario's orbit over its site (its first strip's ``[strip]`` values) at each roll of a grid, and every
  campaign of 1 … ``max_strips`` strips drawn from the grid (a roll may be flown on several days: multisets) scored;
  the chosen campaign is the **fewest strips** whose largest σ of θ is ≤ ``target_theta_arcsec`` and whose chip
  offsets' largest σ is ≤ ``target_chip_arcsec`` (when given), and among those the smallest largest σ of θ.
  ``chosen_document`` writes it as a pushbroom scenario (``boresight simulate``/``estimate``/``montecarlo`` run it as
  is) and ``roll_check`` confirms its σ by a Monte Carlo of that scenario (``studies.montecarlo.line_scan``).

Why rolls: on one strip the pitch θy and δt move the image along-track alike (by ρ θy and v δt, ρ the slant range),
corr(θy, δt) → 1 (``docs/effects.md``); strips whose slant ranges differ separate them, so the rolls' |φ| must differ
(``docs/pushbroom.md``).

DECISION: every candidate strip draws its ground-control points from the same seed (the same (line, pixel, height)
layout at every roll: common random numbers, so two rolls differ by their geometry, not by their GCP draw), and a roll
flown on k days counts its block k times — the same geometry on another day, with its own tracker errors and
pixel noise. The written campaign puts strip k on the first strip's epoch + k days; ``roll_check`` simulates those
days, so the check covers this approximation too.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from boresight.core.gls.campaign import single_threaded_blas
from boresight.core.gls.rows import row_gls
from boresight.core.line_scan import LineScanUnknowns, stacked_rows
from boresight.errors import InputValueError
from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns

__all__ = [
    "StripSubset",
    "plan_strips",
    "strip_information",
    "RollCandidate",
    "RollCampaign",
    "RollPlan",
    "roll_grid",
    "roll_candidates",
    "plan_rolls",
    "chosen_document",
    "RollCheck",
    "roll_check",
]

_ARCSEC = np.pi / 180.0 / 3600.0
#: the largest number of campaigns ``plan_rolls`` scores (a multiset of ``max_strips`` of G rolls: C(G + m − 1, m))
MAX_CAMPAIGNS = 2_000_000


def strip_information(obs: Any, unknowns: LineScanUnknowns, model: Any, x: Any) -> np.ndarray:
    """(n, n) the information of the unknowns x (SI, ``unknowns.names``' order) from one strip ``obs`` at x: the GLS on
    its rows with the noise model's nuisances eliminated (module docstring)."""
    with single_threaded_blas():
        st, cols = stacked_rows([obs], np.asarray(x, float), unknowns, model)
        out: np.ndarray = row_gls(st, cols).normal_equations.information[0]
    return 0.5 * (out + out.T)


def _truth_x(sc: Any, unknowns: LineScanUnknowns) -> np.ndarray:
    from boresight.studies.montecarlo.line_scan import truth_vector

    return truth_vector(sc, unknowns.names)


def _covariances(info: np.ndarray, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """σ (C, n), corr(θy, δt) (C,) (NaN when δt is not estimated), the 'not determined' flag (C,) and the largest
    |corr| of a chip offset with an axis of θ (C,) (NaN when no chip offset is estimated) of a batch of information
    matrices (``fisher.covariance_batch``)."""
    from boresight.studies.planning.fisher import covariance_batch

    cov, singular = covariance_batch(info)
    sigma = np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    corr_all = cov / (sigma[:, :, None] * sigma[:, None, :])
    if "line_time_offset_s" in names:
        corr = corr_all[:, 1, names.index("line_time_offset_s")]
    else:
        corr = np.full(info.shape[0], np.nan)
    chips = [j for j, n in enumerate(names) if n.startswith("chip")]
    chip_theta = np.max(np.abs(corr_all[:, :3][:, :, chips]), axis=(1, 2)) if chips else np.full(info.shape[0], np.nan)
    return sigma, corr, singular, chip_theta


# ---------------------------------------------------------------------------- the subsets of a scenario's strips


@dataclass
class StripSubset:
    """One subset of the scenario's strips (``strips``, indices), its rolls, the unknowns' ``names`` and ``sigma`` (SI),
    the correlation of θy with the line-time offset (NaN when δt is not estimated), and ``best`` for its size."""

    strips: tuple[int, ...]
    rolls_deg: tuple[float, ...]
    names: list[str]
    sigma: np.ndarray
    corr_pitch_time: float
    best: bool = False

    @property
    def worst_theta_arcsec(self) -> float:
        return float(np.max(self.sigma[:3]) / _ARCSEC)


def plan_strips(sc: Any, seed: int = 1) -> list[StripSubset]:
    """Every non-empty subset of ``sc``'s strips, scored by the sum of their blocks (module docstring); in order of size,
    then score. The strips are one noise-free draw of the scenario (``simulate_campaign`` from ``default_rng(seed)``)."""
    from orbits.strip import TrackerNoise, simulate_campaign

    geos = sc.geometries()
    sims = simulate_campaign(geos, [sc.truth()] * len(geos), np.random.default_rng(seed), sc.layout, TrackerNoise(), 0.0)
    model, unknowns = strip_noise_model(sc), strip_unknowns(sc)
    names, x = unknowns.names, _truth_x(sc, unknowns)
    blocks = np.stack([strip_information(strip_observations(s), unknowns, model, x) for s in sims])
    out: list[StripSubset] = []
    for size in range(1, len(sims) + 1):
        subs = list(itertools.combinations(range(len(sims)), size))
        sigma, corr, _, _ = _covariances(blocks[np.array(subs)].sum(axis=1), names)
        group = [
            StripSubset(sub, tuple(sc.strips[k].roll_deg for k in sub), names, sigma[i], float(corr[i]))
            for i, sub in enumerate(subs)
        ]
        group.sort(key=lambda g: g.worst_theta_arcsec)
        group[0].best = True
        out += group
    return out


# ---------------------------------------------------------------------------- the search over roll angles


def roll_grid(max_roll_deg: float = 30.0, step_deg: float = 5.0) -> tuple[float, ...]:
    """The rolls −max … +max every ``step_deg`` (0 included), in degrees.

    >>> roll_grid(30, 15)
    (-30.0, -15.0, 0.0, 15.0, 30.0)
    """
    if not (np.isfinite(max_roll_deg) and 0 <= max_roll_deg < 60):
        raise InputValueError(f"roll grid: the largest roll must be in [0°, 60°), got {max_roll_deg!r}°")
    if not (np.isfinite(step_deg) and step_deg > 0):
        raise InputValueError(f"roll grid: the step must be > 0°, got {step_deg!r}°")
    k = int(np.floor(max_roll_deg / step_deg + 1e-9))
    return tuple(float(v) for v in step_deg * np.arange(-k, k + 1))


@dataclass(frozen=True)
class RollCandidate:
    """A candidate strip: the scenario's first strip turned to ``roll_deg``, its Fisher block ``information`` (n, n)
    and how many detections its noise-free draw holds."""

    roll_deg: float
    information: np.ndarray
    n_detections: int


def roll_candidates(sc: Any, rolls_deg: Any, seed: int = 1) -> list[RollCandidate]:
    """One candidate strip per roll (the scenario's first strip with ``roll_deg`` replaced), each drawn noise-free from
    ``default_rng(seed)`` (the same GCP layout at every roll) and its block computed at the truth."""
    from orbits.strip import TrackerNoise, simulate_strip, strip_geometry

    model, unknowns = strip_noise_model(sc), strip_unknowns(sc)
    x, truth = _truth_x(sc, unknowns), sc.truth()
    out = []
    for r in rolls_deg:
        geo = strip_geometry(replace(sc.strips[0], roll_deg=float(r)))
        sim = simulate_strip(geo, truth, np.random.default_rng(seed), sc.layout, TrackerNoise(), 0.0)
        obs = strip_observations(sim)
        out.append(RollCandidate(float(r), strip_information(obs, unknowns, model, x), int(obs.n_observations)))
    return out


@dataclass(frozen=True)
class RollCampaign:
    """One campaign of strips: its rolls (degrees, one per strip, ascending), σ of each unknown (SI), corr(θy, δt), whether
    its information is (nearly) singular, whether it meets the requirement, and the largest |corr| of a chip offset
    with an axis of θ (how far the chips are told from θ; NaN without chip offsets)."""

    rolls_deg: tuple[float, ...]
    sigma: np.ndarray
    corr_pitch_time: float
    singular: bool
    meets: bool
    corr_chip_theta: float = float("nan")

    @property
    def n_strips(self) -> int:
        return len(self.rolls_deg)

    @property
    def worst_theta_arcsec(self) -> float:
        """The largest σ of θ, arcsec."""
        return float(np.max(self.sigma[:3]) / _ARCSEC)


@dataclass
class RollPlan:
    """The result of ``plan_rolls``: the unknowns' ``names``, the ``candidates``, every scored campaign (``campaigns``,
    by number of strips, then largest σ of θ), the best campaign of each size (``best``), the requirement and the
    ``chosen`` campaign (None when no campaign of at most ``max_strips`` strips meets it)."""

    scenario: str
    names: list[str]
    candidates: list[RollCandidate]
    campaigns: list[RollCampaign]
    best: list[RollCampaign]
    chosen: RollCampaign | None
    target_theta_arcsec: float
    target_chip_arcsec: float | None
    max_strips: int
    seed: int

    def chip_columns(self) -> list[int]:
        """Indices of the chip offsets among the unknowns."""
        return [j for j, n in enumerate(self.names) if n.startswith("chip")]

    def worst_chip_arcsec(self, c: RollCampaign) -> float:
        """The largest σ of the chip offsets of campaign c, arcsec (NaN when none is estimated)."""
        j = self.chip_columns()
        return float(np.max(c.sigma[j]) / _ARCSEC) if j else float("nan")

    def requirement_text(self) -> str:
        out = f"largest σθ ≤ {self.target_theta_arcsec:g}″"
        if self.target_chip_arcsec is not None:
            out += f" and largest σ of the chip offsets ≤ {self.target_chip_arcsec:g}″"
        return out


def _meets(sigma: np.ndarray, singular: np.ndarray, chips: list[int], theta_max: float, chip_max: float | None) -> np.ndarray:
    ok = (np.max(sigma[:, :3], axis=1) <= theta_max * _ARCSEC) & ~singular
    if chip_max is not None:
        ok &= np.max(sigma[:, chips], axis=1) <= chip_max * _ARCSEC
    out: np.ndarray = ok
    return out


def plan_rolls(
    sc: Any,
    rolls_deg: Any = None,
    max_strips: int = 4,
    target_theta_arcsec: float = 1.0,
    target_chip_arcsec: float | None = None,
    seed: int = 1,
    candidates: list[RollCandidate] | None = None,
) -> RollPlan:
    """Search the campaigns of 1 … ``max_strips`` strips at the rolls ``rolls_deg`` (default ``roll_grid()``: −30° …
    +30° every 5°) for the fewest strips meeting the requirement (module docstring). ``candidates`` given: their blocks
    are used (from ``roll_candidates``; the rolls are theirs)."""
    if not (np.isfinite(target_theta_arcsec) and target_theta_arcsec > 0):
        raise InputValueError(f"plan_rolls: the target σθ must be > 0 arcsec, got {target_theta_arcsec!r}")
    if target_chip_arcsec is not None and not (np.isfinite(target_chip_arcsec) and target_chip_arcsec > 0):
        raise InputValueError(f"plan_rolls: the target σ of the chip offsets must be > 0 arcsec, got {target_chip_arcsec!r}")
    if isinstance(max_strips, bool) or not isinstance(max_strips, (int, np.integer)) or max_strips < 1:
        raise InputValueError(f"plan_rolls: max_strips must be an integer ≥ 1, got {max_strips!r}")
    unknowns = strip_unknowns(sc)
    names = unknowns.names
    chips = [j for j, n in enumerate(names) if n.startswith("chip")]
    if target_chip_arcsec is not None and not chips:
        raise InputValueError(
            f"plan_rolls: a target σ of the chip offsets was given but {sc.source}'s [estimate] floats no chip offset "
            "(chip_offsets = [[chip, axis], …])"
        )
    if candidates is None:
        candidates = roll_candidates(sc, roll_grid() if rolls_deg is None else rolls_deg, seed)
    if not candidates:
        raise InputValueError("plan_rolls: no candidate roll")
    blocks = np.stack([c.information for c in candidates])
    rolls = [c.roll_deg for c in candidates]
    from math import comb

    total = sum(comb(len(rolls) + m - 1, m) for m in range(1, max_strips + 1))
    if total > MAX_CAMPAIGNS:
        raise InputValueError(
            f"plan_rolls: {len(rolls)} rolls and up to {max_strips} strips make {total} campaigns (> {MAX_CAMPAIGNS}): "
            "take a coarser roll grid or fewer strips"
        )
    campaigns: list[RollCampaign] = []
    best: list[RollCampaign] = []
    for m in range(1, max_strips + 1):
        idx = np.array(list(itertools.combinations_with_replacement(range(len(rolls)), m)))
        sigma, corr, singular, chip_theta = _covariances(blocks[idx].sum(axis=1), names)
        meets = _meets(sigma, singular, chips, target_theta_arcsec, target_chip_arcsec)
        worst = np.where(singular, np.inf, np.max(sigma[:, :3], axis=1))
        group = [
            RollCampaign(
                tuple(rolls[k] for k in idx[i]), sigma[i], float(corr[i]), bool(singular[i]), bool(meets[i]), float(chip_theta[i])
            )
            for i in np.argsort(worst, kind="stable")
        ]
        best.append(group[0])
        campaigns += group
    chosen = next((c for c in campaigns if c.meets), None)  # fewest strips first, then the smallest largest σθ
    return RollPlan(
        sc.name, names, candidates, campaigns, best, chosen, target_theta_arcsec, target_chip_arcsec, int(max_strips), seed
    )


def chosen_document(source_document: dict[str, Any], plan: RollPlan, campaign: RollCampaign) -> dict[str, Any]:
    """The pushbroom scenario document of ``campaign``: the source scenario's document with its ``[[strips]]`` replaced
    by one strip per roll, strip k on the first strip's epoch + k days, every other value the first strip's (the
    candidates' geometry)."""
    from datetime import datetime, timedelta

    doc = {k: v for k, v in source_document.items() if k != "strips"}
    first = dict(source_document.get("strips", [{}])[0])
    base = {**dict(source_document.get("strip", {})), **first}
    epoch = datetime.fromisoformat(str(base.pop("epoch", "2024-06-01T03:00:00")))
    base.pop("roll_deg", None)
    doc["strip"] = base
    rolls = ", ".join(f"{r:+g}°" for r in campaign.rolls_deg)
    doc["name"] = f"{plan.scenario}-plan"
    doc["description"] = (
        f"planned by boresight plan {plan.scenario}: {campaign.n_strips} strips at rolls {rolls} on successive days "
        f"({plan.requirement_text()})"
    )
    doc["strips"] = [
        {"epoch": (epoch + timedelta(days=k)).isoformat(), "roll_deg": float(r)} for k, r in enumerate(campaign.rolls_deg)
    ]
    return doc


# ---------------------------------------------------------------------------- the Monte Carlo check


@dataclass(frozen=True)
class RollCheck:
    """A Monte Carlo of the chosen campaign: per unknown the predicted σ (the plan's), the scatter of the estimates about
    the truth with its interval (level ``level`` per unknown), the mean reported σ; ``agrees`` when every predicted σ
    lies in its interval. SI units, in ``names``' order."""

    runs: int
    seed: int
    names: list[str]
    predicted: np.ndarray
    scatter: np.ndarray
    low: np.ndarray
    high: np.ndarray
    reported: np.ndarray
    level: float
    agrees: bool

    def as_dict(self) -> dict[str, Any]:
        return dict(
            runs=self.runs,
            seed=self.seed,
            names=self.names,
            predicted=self.predicted.tolist(),
            scatter=self.scatter.tolist(),
            interval_low=self.low.tolist(),
            interval_high=self.high.tolist(),
            mean_reported_sigma=self.reported.tolist(),
            level=self.level,
            agrees=self.agrees,
        )


def roll_check(document: dict[str, Any], plan: RollPlan, campaign: RollCampaign, runs: int, seed: int = 1) -> RollCheck:
    """Simulate the campaign's scenario ``document`` (``chosen_document``) ``runs`` times with its noise, fit each with
    ``estimate_line_scan`` (``studies.montecarlo.line_scan``) and compare the scatter with the predicted σ.

    DECISION: the interval of each unknown's scatter is the χ² interval of a standard deviation (``stats.sigma_interval``)
    at level 1 − 0.05/n (Bonferroni over the n unknowns): an honest prediction then agrees on every unknown in ≥ 95 % of
    checks, where 95 % per unknown would fail one of seven in 30 %."""
    from boresight.stats import sigma_interval
    from boresight.studies.montecarlo.line_scan import line_scan_montecarlo
    from orbits.strip import strip_scenario_from_dict

    sc = strip_scenario_from_dict(document, source=f"{plan.scenario}: the planned campaign")
    mc = line_scan_montecarlo(sc, runs, seed)
    level = 1.0 - 0.05 / len(mc.names)
    lo, hi = sigma_interval(mc.scatter, runs, level)
    pred = campaign.sigma
    return RollCheck(
        runs,
        seed,
        list(mc.names),
        pred,
        mc.scatter,
        np.asarray(lo),
        np.asarray(hi),
        mc.sigmas.mean(axis=0),
        level,
        bool(np.all((lo <= pred) & (pred <= hi))),
    )
