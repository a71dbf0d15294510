"""The calibration campaign planner: what to fly to reach a target σθ and separate the effects
that matter (``docs/planning.md``).

``plan(PLAN.toml)`` builds every pass option of the search space as a one-pass scenario
(``options``), computes each option's Fisher information block of [θ, required effects] with
the sensor nuisances marginalised (``fisher``) and the same with only the per-image errors
marginalised (the diagnosis' whitening), scores every candidate campaign by summing its passes'
blocks — σθ, detectable sizes and whether ``boresight.diagnose`` would name each required
effect (``naming``) — and returns the Pareto front and the cheapest campaign that meets every
requirement (``search``). ``report`` writes the front (ECSV), the chosen campaign (a scenario
TOML that ``boresight simulate`` runs as is), a plot and a Markdown summary that says why;
``checks`` confirms predictions by Monte Carlo (simulate + estimate).

Example
-------
>>> from boresight.studies.planning import plan
>>> result = plan("plans/kiev680.toml", max_candidates=2000)   # doctest: +SKIP
>>> result.describe(result.chosen)                                       # doctest: +SKIP
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from boresight.studies.planning.fisher import (
    information_block,
    noise_free_observations,
)
from boresight.studies.planning.options import PassOption, pass_options
from boresight.studies.planning.search import PlanResult, pareto_front, run_search
from boresight.studies.planning.spec import PlanError, PlanSpec, load_plan, plan_from_dict

__all__ = [
    "plan",
    "PlanResult",
    "PlanSpec",
    "PlanError",
    "PassOption",
    "load_plan",
    "plan_from_dict",
    "option_blocks",
    "pareto_front",
]


def option_blocks(spec: PlanSpec, options) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple]:
    """Information blocks (O, P, P) of the pass options, the same with only the per-image
    errors marginalised (O, P, P), the residual counts (O,) and the parameter labels (P,)."""
    blocks, raws, rows, labels = [], [], [], None
    with single_thread_blas():
        for o in options:
            b, r, n, labels = _option_block(spec, o)
            blocks.append(b)
            raws.append(r)
            rows.append(n)
    return np.stack(blocks), np.stack(raws), np.array(rows), labels


class single_thread_blas:
    """DECISION: the blocks are products of small matrices (a few hundred rows); a threaded
    BLAS on a busy machine spends 100× longer synchronising than computing (measured: a 200×200
    Cholesky 0.4 s threaded on a loaded 2-core machine, 1.4 ms on one thread). threadpoolctl is
    optional: without it the BLAS keeps its own setting."""

    def __enter__(self):
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:
            self._ctx = None
            return self
        self._ctx = threadpool_limits(limits=1, user_api="blas")
        return self

    def __exit__(self, *exc):
        if self._ctx is not None:
            self._ctx.unregister()
        return False


def _option_block(spec, o):
    from boresight.studies.planning.options import scenario_document
    from orbits.scenario import scenario_from_dict

    star = o.kind == "stars"
    doc = scenario_document(spec, [] if star else [o.entry], name="option", star_entries=[o.entry] if star else ())
    sc = scenario_from_dict(doc, source=f"{spec.source}: option {o.label}")
    obs, model = noise_free_observations(sc)
    if obs.n_observations == 0:
        raise PlanError(
            f"{spec.source}: {'star segment' if star else 'pass option'} {o.label} sees no "
            f"{'star' if star else 'landmark'} (field of view {spec.scenario_base['camera']['fov_deg']}°)"
        )
    return information_block(obs, model, list(spec.effect_names) + list(spec.lookalikes), raw=True)


def plan(spec, *, max_candidates: int | None = None) -> PlanResult:
    """Plan a calibration campaign: which passes to fly for a target σθ and separable effects.

    Parameters
    ----------
    spec : str or path or dict or PlanSpec
        A plan file (TOML, ``docs/planning.md``), its parsed document, or a ``PlanSpec``.
    max_candidates : int, optional
        Overrides the plan's ``[search] max_candidates`` (how many candidate campaigns are scored).

    Returns
    -------
    PlanResult
        The scored candidates, their Pareto front and the chosen campaign (``chosen`` is None when
        no candidate meets every requirement; the front still shows the best trade-offs).

    Raises
    ------
    PlanError
        The plan file is missing or invalid, or ``spec`` is of another type (a ``BoresightError``).
    """
    if isinstance(spec, (str, Path)):
        spec = load_plan(spec)
    elif isinstance(spec, dict):
        spec = plan_from_dict(spec)
    elif not isinstance(spec, PlanSpec):
        raise PlanError(f"plan: expected a plan file path, a dict or a PlanSpec, got {type(spec).__name__}")
    if max_candidates is not None and (
        isinstance(max_candidates, bool) or not isinstance(max_candidates, (int, np.integer)) or max_candidates < 1
    ):
        raise PlanError(f"plan: max_candidates must be an integer ≥ 1, got {max_candidates!r}")
    timings = {}
    t0 = time.perf_counter()
    options = pass_options(spec)
    blocks, raw, rows, labels = option_blocks(spec, options)
    timings["blocks_s"] = time.perf_counter() - t0
    return run_search(
        spec, options, blocks, labels, max_candidates=max_candidates, timings=timings, raw_blocks=raw, option_rows=rows
    )
