"""Candidate effects as the diagnosis sees them: metadata plus a column function.

A ``Candidate`` is what the naming step needs of an effect: its name, parameters, units, a
typical size (the unit the columns are scaled to, and the size at which a non-separable
effect's θ shift is quoted), the physical range of each parameter, what causes it and what
data separate it, and ``columns(obs, theta_rad, params) -> (offset, jacobian, status)`` with
``offset`` (R, K, 2) m the predicted image-plane offset at ``params`` and ``jacobian``
(R, K, 2, k) m per unit of each parameter, one row per observation (``docs/architecture.md``,
"The row model").

``catalogue_candidates()`` wraps the effects catalogue (``orbits.effects.EFFECTS`` and
``boresight.core.effect_model.effect_columns``: one definition serves the simulator and the
estimators). Tests and other models may pass their own ``Candidate`` objects.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Candidate", "ColumnSet", "catalogue_candidates", "catalogue_available", "columns_for"]


@dataclass(frozen=True)
class ColumnSet:
    """One candidate's columns at one estimate: ``offset`` (R, K, 2) m, ``jacobian``
    (R, K, 2, k) m per unit (one row per observation), ``status`` ("ok" or "needs velocity"), ``scales`` (k,) a typical
    size per parameter (None: keep the candidate's)."""

    offset: np.ndarray
    jacobian: np.ndarray
    status: str = "ok"
    scales: np.ndarray | None = None


@dataclass(frozen=True)
class Candidate:
    name: str
    param_names: tuple
    units: tuple  # unit string per parameter
    scales: np.ndarray | None  # (k,) typical size per parameter, in ``units``; None: the columns give it
    physical_range: np.ndarray  # (k, 2) [low, high] per parameter, in ``units``
    columns: Callable  # (obs, theta_rad, params (k,) or None) -> ColumnSet
    cause: str = ""
    separated_by: str = ""
    needs_velocity: bool = False
    extra: dict = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.param_names)


def catalogue_available() -> bool:
    """True when the effects catalogue (``orbits.effects``, ``boresight.core.effect_model``) is installed."""
    from importlib.util import find_spec

    return find_spec("boresight.core.effect_model") is not None and find_spec("orbits.effects") is not None


def _unit_str(u) -> str:
    s = str(u)
    return s if s else "1"


def _range_array(effect, k):
    rng = getattr(effect, "physical_range", None)
    if rng is None:
        return np.tile([-np.inf, np.inf], (k, 1))
    a = np.asarray(rng, dtype=object)
    out = np.empty((k, 2))
    vals = []
    if isinstance(rng, dict):
        vals = [rng.get(p, (-np.inf, np.inf)) for p in effect.param_names]
    elif a.ndim == 1 and a.size == 2:
        vals = [rng] * k
    else:
        vals = list(rng)
    for i, v in enumerate(vals[:k]):
        lo, hi = v
        out[i] = [getattr(lo, "value", lo), getattr(hi, "value", hi)]
    return out


def catalogue_candidates(names=None) -> list[Candidate]:
    """The catalogue effects as candidates (all of them, or ``names`` in that order)."""
    from boresight.core.effect_model import check_effect_names, effect_columns, effect_names
    from orbits.effects import EFFECTS

    names = list(effect_names()) if names is None else check_effect_names(names)
    out = []
    for name in names:
        eff = EFFECTS[name]
        if getattr(eff, "scan", ""):
            out.append(scan_candidate(eff))
            continue
        k = int(eff.n_params)

        def columns(obs, theta_rad, params, _name=name, _k=k):
            p = None if params is None else {_name: np.atleast_2d(np.asarray(params, float))}
            ec = effect_columns(obs, theta_rad, [_name], params=p)
            status = ec.status.get(_name, "ok") if isinstance(ec.status, dict) else str(ec.status)
            sc = getattr(ec, "scales", None)
            return ColumnSet(
                np.asarray(ec.offset), np.asarray(ec.jacobian), status, None if sc is None else np.asarray(sc, float)
            )

        # typical size: the catalogue's ``scale`` (one per parameter)
        scales = getattr(eff, "scale", None)
        units = tuple(
            _unit_str(getattr(u, "to_string", lambda: u)())
            for u in (eff.unit if isinstance(eff.unit, (list, tuple)) else [eff.unit])
        )
        if len(units) == 1 and k > 1:
            units = units * k
        out.append(
            Candidate(
                name=name,
                param_names=tuple(eff.param_names),
                units=units,
                scales=None
                if scales is None
                else np.broadcast_to(np.asarray([getattr(s, "value", s) for s in np.atleast_1d(scales)], float), (k,)).copy(),
                physical_range=_range_array(eff, k),
                columns=columns,
                cause=str(getattr(eff, "cause", "")),
                extra={"catalogue": True, "look_alikes": tuple(getattr(eff, "look_alikes", ()))},
                separated_by=str(getattr(eff, "separated_by", "")),
                needs_velocity=bool(getattr(eff, "needs_velocity", False)),
            )
        )
    return out


def scan_boundaries(obs) -> np.ndarray:
    """The candidate values of a scanned boundary (``Effect.scan``, in the images' time axis): the
    midpoints of the gaps between consecutive passes in time order; (B,)."""
    passes = np.unique(obs.pass_index)
    if passes.size < 2:
        return np.zeros(0)
    first = np.array([obs.t_s[obs.pass_index == p].min() for p in passes])
    last = np.array([obs.t_s[obs.pass_index == p].max() for p in passes])
    order = np.argsort(first)
    first, last = first[order], last[order]
    return 0.5 * (last[:-1] + first[1:])


def scan_candidate(eff) -> Candidate:
    """A catalogue effect with a scanned parameter (``Effect.scan``: ``alignment_step``'s boundary) as
    a candidate of its other parameters. ``columns(obs, θ, params, at=None)``: with ``at`` the
    columns at that boundary value; without, those of every boundary of ``scan_boundaries`` side
    by side (k = B × the fitted parameters): the naming tests each block and corrects over the
    scan (``naming.scan_blocks``). ``extra["scan"]`` = the scanned parameter's name."""
    from boresight.core.effect_model import effect_columns

    j = list(eff.param_names).index(eff.scan)
    fit = [i for i in range(eff.n_params) if i != j]
    name = eff.name

    def columns(obs, theta_rad, params, at=None):
        ats = scan_boundaries(obs) if at is None else np.atleast_1d(float(at))
        offs, jacs = [], []
        for a in ats:
            p = np.zeros(eff.n_params)
            if params is not None and at is not None:
                p[fit] = np.asarray(params, float)
            p[j] = a
            ec = effect_columns(obs, theta_rad, [name], params={name: p[None]})
            offs.append(np.asarray(ec.offset))
            jacs.append(np.asarray(ec.jacobian)[..., fit])
        if not jacs:
            shape = (obs.runs, obs.n_observations, 2)
            return ColumnSet(np.zeros(shape), np.zeros(shape + (0,)))
        return ColumnSet(offs[0] if at is not None else np.zeros_like(offs[0]), np.concatenate(jacs, axis=-1))

    scales = np.asarray([eff.scale[i] for i in fit], float)
    return Candidate(
        name=name,
        param_names=tuple(eff.param_names[i] for i in fit),
        units=tuple(eff.unit_names[i] or "1" for i in fit),
        scales=scales,
        physical_range=np.asarray([eff.physical_range[i] for i in fit], float),
        columns=columns,
        cause=str(eff.cause),
        separated_by=str(eff.separated_by),
        needs_velocity=bool(eff.needs_velocity),
        extra={"catalogue": False, "scan": eff.scan, "look_alikes": tuple(eff.look_alikes)},
    )


def columns_for(obs, theta_rad, candidates) -> dict:
    """name → ``ColumnSet`` at parameter 0 for several candidates; the catalogue's are computed in
    one ``effect_columns`` call (the velocity and attitude-rate context is built once)."""
    cat = [c for c in candidates if c.extra.get("catalogue")]
    out = {}
    if cat:
        from boresight.core.effect_model import effect_columns

        ec = effect_columns(obs, theta_rad, [c.name for c in cat])
        for c in cat:
            sl = ec.slices[c.name]
            out[c.name] = ColumnSet(
                np.zeros_like(ec.offset),
                np.asarray(ec.jacobian[..., sl]),
                ec.status.get(c.name, "ok"),
                np.asarray(ec.scales[sl], float),
            )
    for c in candidates:
        if c.name not in out:
            out[c.name] = c.columns(obs, theta_rad, None)
    return out
