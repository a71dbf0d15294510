"""Example flight data sets shipped with boresight, found by name like the scenarios.

``examples/<name>/`` in the repository is the one source; ``boresight/observations/flight/examples``
is a symlink to it, so a wheel carries the files as package data and ``example_dir("flight-pass")``
finds them in a checkout and after ``pip install`` alike. ``boresight ingest --example NAME`` takes
every input it is not given from there (``docs/tutorial-flight-data.md``).
"""

from __future__ import annotations

from pathlib import Path

from boresight.observations.flight.common import IngestError

__all__ = [
    "EXAMPLE_DIR",
    "EXAMPLE_FILES",
    "PUSHBROOM_EXAMPLE_FILES",
    "example_names",
    "example_dir",
    "example_kind",
    "example_files",
]

EXAMPLE_DIR = Path(__file__).resolve().parent / "examples"
#: the ingest option each file of an example data set feeds
EXAMPLE_FILES = {
    "oem": "orbit.oem",
    "aem": "attitude.aem",
    "landmarks": "landmarks.csv",
    "detections": "detections.csv",
    "camera": "camera.toml",
}

#: the files of a pushbroom example data set (``boresight ingest --example pushbroom-pass``, docs/tutorial-pushbroom.md)
PUSHBROOM_EXAMPLE_FILES = {
    "oem": "orbit.oem",
    "aem": "attitude.aem",
    "landmarks": "landmarks.csv",
    "line_detections": "line-detections.csv",
    "line_sensor": "line-sensor.toml",
}


def _kind(p: Path) -> str | None:
    for kind, files in (("frame", EXAMPLE_FILES), ("pushbroom", PUSHBROOM_EXAMPLE_FILES)):
        if p.is_dir() and all((p / f).is_file() for f in files.values()):
            return kind
    return None


def example_names() -> list[str]:
    """Names of the shipped example data sets (folders holding the five flight files of a frame camera or of a
    pushbroom strip)."""
    if not EXAMPLE_DIR.is_dir():
        return []
    return sorted(p.name for p in EXAMPLE_DIR.iterdir() if _kind(p) is not None)


def example_kind(name: str) -> str:
    """``"frame"`` or ``"pushbroom"``: which files the shipped example data set ``name`` holds."""
    kind = _kind(example_dir(name))
    assert kind is not None  # example_dir lists only folders of a kind
    return kind


def example_files(name: str) -> dict[str, str]:
    """The ingest option → file name mapping of the shipped example data set ``name``."""
    return PUSHBROOM_EXAMPLE_FILES if example_kind(name) == "pushbroom" else EXAMPLE_FILES


def example_dir(name: str) -> Path:
    """The folder of the shipped example data set ``name``; an unknown name is refused listing the shipped ones.

    >>> example_dir("flight-pass").name
    'flight-pass'
    """
    from orbits.errors import did_you_mean

    names = example_names()
    if name in names:
        return EXAMPLE_DIR / name
    raise IngestError(
        f"--example {name}: not a shipped example data set{did_you_mean(name, names)} (shipped: {', '.join(names) or 'none'})"
    )
