"""Errors and small helpers shared by the ingestion readers."""

from __future__ import annotations

import importlib

from orbits.errors import BoresightError

__all__ = ["IngestError", "InterpolationError", "require_extra"]


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
