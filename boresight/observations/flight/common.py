"""Errors and small helpers shared by the ingestion readers."""

from __future__ import annotations

import importlib

import numpy as np

from orbits.errors import BoresightError

__all__ = ["IngestError", "InterpolationError", "require_extra", "merge_segments"]


class IngestError(BoresightError, ValueError):
    """A flight-data file cannot be ingested; the message names the file, the key/column, the row and the value."""


class InterpolationError(IngestError):
    """An image time is outside the data, or the interpolation error estimate exceeds the stated bound."""


# package -> the extra that brings it (pyproject.toml [project.optional-dependencies] flight)
_EXTRAS = {"oem": "flight", "ccsds_ndm": "flight", "sgp4": "flight"}


def require_extra(module: str):
    """Import an optional dependency or raise ``IngestError`` saying how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - depends on the environment
        extra = _EXTRAS.get(module.split(".")[0], "flight")
        raise IngestError(f"reading this format needs the optional package {module.split('.')[0]!r}: pip install 'boresight[{extra}]'") from exc


def merge_segments(times, where: str, what: str, hint: str = ""):
    """The epochs of a file's segments (a list of astropy ``Time``) as one UTC ``Time`` in time
    order and the sorting permutation; two epochs at or out of order are refused naming ``where``,
    ``what`` ("attitudes", "states") and the epoch. Shared by the orbit and attitude readers."""
    from astropy.time import Time

    t_all = Time(np.concatenate([t.jd1 for t in times]), np.concatenate([t.jd2 for t in times]), format="jd", scale="utc")
    order = np.argsort(t_all.jd1 + t_all.jd2, kind="stable")
    t_all = t_all[order]
    dt = np.diff((t_all - t_all[0]).to_value("s"))
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise IngestError(f"{where}: two {what} at or out of order near epoch {t_all[k].isot}{hint}")
    return t_all, order


def sample_offsets(samples, times, useable, source: str, what: str):
    """Seconds from the first sample: (node times (K,), query times (Q,)), after refusing any query
    outside the samples (or their ``useable`` (start, stop) span) with an ``InterpolationError``
    naming ``source`` and the first offending image time. Shared by the orbit and attitude tracks."""
    t = (times - samples[0]).to_value("s")
    tn = (samples - samples[0]).to_value("s")
    lo, hi = tn[0], tn[-1]
    if useable is not None:
        lo = max(lo, (useable[0] - samples[0]).to_value("s"))
        hi = min(hi, (useable[1] - samples[0]).to_value("s"))
    bad = (t < lo - 1e-6) | (t > hi + 1e-6)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise InterpolationError(f"{source}: image time {times[k].isot} is outside the {what} data ({samples[0].isot} .. {samples[-1].isot}"
                                 + (", useable span" if useable is not None else "") + ")")
    return tn, t
