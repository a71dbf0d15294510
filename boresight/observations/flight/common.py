"""Errors and small helpers shared by the ingestion readers."""

from __future__ import annotations

import importlib

import numpy as np

from boresight.errors import IngestError, InterpolationError, extra_hint

__all__ = [
    "IngestError",
    "InterpolationError",
    "require_extra",
    "distinct_times",
    "sample_offsets",
    "segment_of",
    "by_start",
    "time_slip_hint",
]


# package -> the extra that brings it (pyproject.toml [project.optional-dependencies]): reading needs
# `flight` (permissive licences only); writing CCSDS files needs `flight-export` (ccsds-ndm is GPL-3.0-or-later)
_EXTRAS = {"oem": "flight-export", "ccsds_ndm": "flight-export", "sgp4": "flight", "lxml": "flight", "spiceypy": "spice"}


def require_extra(module: str):
    """Import an optional dependency or raise ``IngestError`` saying how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - depends on the environment
        extra = _EXTRAS.get(module.split(".")[0], "flight")
        raise IngestError(
            f"{'writing' if extra == 'flight-export' else 'reading'} this format needs the optional package "
            f"{module.split('.')[0]!r}, {extra_hint(extra)}"
        ) from exc


def distinct_times(time_utc, source: str):
    """(distinct time strings (F,), their astropy ``Time`` (F,)) of a ``time_utc`` column, in time
    order (ties kept in string order) — the frames of a detection or centroid table; a string that
    is not a UTC time is an ``IngestError`` naming ``source`` and the column."""
    from astropy.time import Time

    uniq = np.unique(np.asarray(time_utc, dtype=str))
    try:
        tt = Time(list(uniq), scale="utc")
    except ValueError as exc:
        raise IngestError(f"{source}: column 'time_utc': {exc}") from exc
    order = np.argsort((tt - tt[0]).to_value("s"), kind="stable")
    return uniq[order], tt[order]


def sample_offsets(samples, times, useable, source: str, what: str, time_system: tuple = ()):
    """Seconds from the first sample: (node times (K,), query times (Q,)), after refusing any query
    outside the samples (or their ``useable`` (start, stop) span) with an ``InterpolationError``
    naming ``source`` and the first offending image time (and, when ``time_system`` = (declared
    TIME_SYSTEM, its line) is given, a time-system slip that would put every time inside:
    ``time_slip_hint``). Shared by the orbit and attitude tracks."""
    t = (times - samples[0]).to_value("s")
    tn = (samples - samples[0]).to_value("s")
    lo, hi = tn[0], tn[-1]
    if useable is not None:
        lo = max(lo, (useable[0] - samples[0]).to_value("s"))
        hi = min(hi, (useable[1] - samples[0]).to_value("s"))
    bad = (t < lo - 1e-6) | (t > hi + 1e-6)
    if np.any(bad):
        from astropy import units as u

        k = int(np.argmax(bad))
        raise InterpolationError(
            f"{source}: image time {times[k].isot} is outside the {what} data ({samples[0].isot} .. {samples[-1].isot}"
            + (", useable span" if useable is not None else "")
            + ")"
            + time_slip_hint(times, samples[0] + lo * u.s, samples[0] + hi * u.s, time_system)
        )
    return tn, t


#: how close (s) the times must come to the samples, shifted by a time-system difference, to name it
SLIP_TOLERANCE_S = 1e-3


def time_slip_hint(times, start, stop, time_system: tuple = ()) -> str:
    """``"; …"`` naming a time-system slip when ``times`` (astropy Time, UTC) fall outside the samples'
    span [``start``, ``stop``] but would all be inside it had the file's epochs been read in another
    CCSDS time system than the declared one; else ``""``. ``time_system`` = (declared name, its line,
    ((alt, δ s), …)) as the OEM and AEM readers record it (``ccsds.time_system_shifts``).

    An epoch e written in system S′ but read in the declared S lands at t(e, S) = t(e, S′) − δ: the
    samples appear δ early (TAI declared for UTC epochs: δ = TAI − UTC = 37 s since 2017, 33 s in
    2006; GPS: 18 s; TT: 69.184 s). So the test is: every time in [start + δ, stop + δ] (±
    ``SLIP_TOLERANCE_S``). Each system that passes is named, smallest |δ| first."""
    if len(time_system) < 3 or not time_system[2]:
        return ""
    from astropy import units as u

    declared, line, shifts = time_system
    found = []
    for alt, d in shifts:
        lo = ((start + d * u.s) - times).to_value("s")
        hi = (times - (stop + d * u.s)).to_value("s")
        if np.all(lo <= SLIP_TOLERANCE_S) and np.all(hi <= SLIP_TOLERANCE_S):
            found.append((abs(d), alt, d))
    if not found:
        return ""
    found.sort()
    named = " or ".join(f"{alt} ({d:+.6g} s)" for _, alt, d in found)
    return (
        f"; every time would be inside the samples were the file's epochs in {named}: a likely time-system slip — "
        f"TIME_SYSTEM = {declared} (line {line}) for epochs written in {found[0][1]}?"
    )


def segment_of(times, spans, source: str, what: str) -> np.ndarray:
    """Index (Q,) of the segment whose useable ``spans`` [(start, stop)] holds each image time.

    DECISION: where useable spans overlap, the later segment is used (Orekit's aggregate
    ephemeris does the same: a later segment supersedes an earlier one). An image time in no span
    is refused, naming the gap's two spans (or the first / last span)."""
    starts = np.array([(s[0] - times[0]).to_value("s") for s in spans])
    stops = np.array([(s[1] - times[0]).to_value("s") for s in spans])
    t = (times - times[0]).to_value("s")
    inside = (t[:, None] >= starts[None] - 1e-6) & (t[:, None] <= stops[None] + 1e-6)
    k = np.where(inside.any(axis=1), len(spans) - 1 - np.argmax(inside[:, ::-1], axis=1), -1)
    if np.any(k < 0):
        q = int(np.argmax(k < 0))
        span = lambda j: f"segment {j + 1} useable {spans[j][0].isot} .. {spans[j][1].isot}"  # noqa: E731
        before = [j for j in range(len(spans)) if stops[j] < t[q]]
        after = [j for j in range(len(spans)) if starts[j] > t[q]]
        b = max(before, key=lambda j: stops[j]) if before else None
        a = min(after, key=lambda j: starts[j]) if after else None
        where = (
            f"in the gap between {span(b)} and {span(a)}"
            if b is not None and a is not None
            else f"before {span(a)}"
            if a is not None
            else f"after {span(b)}"
        )
        raise InterpolationError(f"{source}: image time {times[q].isot} is {where}: no {what} data there")
    return k


def by_start(tracks):
    """Per-segment tracks (orbit or attitude, each with ``useable`` and ``times``) sorted by the start
    of their useable span, and their sample times concatenated (UTC Time, for inspection). Shared by
    the orbit and attitude readers."""
    from astropy.time import Time

    first = tracks[0].useable[0]
    tracks = sorted(tracks, key=lambda t: (t.useable[0] - first).to_value("s"))
    t_all = Time(
        np.concatenate([t.times.utc.jd1 for t in tracks]),
        np.concatenate([t.times.utc.jd2 for t in tracks]),
        format="jd",
        scale="utc",
    )
    return tracks, t_all
