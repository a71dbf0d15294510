"""The USV sea-sky line measurements (USV sea-sky Table 1), shipped as package data.

``load_sea_sky()`` reads the paper's 120 measured frames (``boresight/data/usv_sea_sky_line.csv``,
described in ``boresight/data/usv_sea_sky_line.md``) or any CSV with the same columns, validates
it, and returns a :class:`SeaSkyScan` of plain float arrays whose names carry the unit.

Example
-------
>>> from boresight.pointing import load_sea_sky
>>> scan = load_sea_sky()
>>> scan.n, round(float(scan.h_meas_deg[0]), 6)
(120, 0.925417)
>>> scan.as_table()["azimuth_deg"].unit
Unit("deg")
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from boresight.errors import InputValueError, ObservationFileError

__all__ = [
    "SEA_SKY_COLUMNS",
    "SEA_SKY_N_FRAMES",
    "TV_ROWS_PX",
    "TV_FOV_V_DEG",
    "SeaSkyScan",
    "load_sea_sky",
    "sea_sky_data_path",
]

#: Columns of the sea-sky CSV, in order (USV sea-sky Table 1).
SEA_SKY_COLUMNS = (
    "frame",
    "azimuth_deg",
    "pitch_deg",
    "roll_deg",
    "delta_eps_deg",
    "pixels",
    "h_meas_deg",
)
#: Number of frames in the paper's scan (USV sea-sky section 6, Table 1).
SEA_SKY_N_FRAMES = 120
#: Vertical resolution N_h of the TV sensor, pixels (USV sea-sky eq 28).
TV_ROWS_PX = 576
#: Vertical field of view omega_y of the TV sensor, degrees (USV sea-sky eq 28).
TV_FOV_V_DEG = 5.0
# DECISION: eq 28 is checked to 1e-6 deg, the README's tolerance; the table's h' carries 9
# significant digits, so a larger mismatch means a wrong column, not rounding.
_EQ28_TOL_DEG = 1e-6


@dataclass(frozen=True)
class SeaSkyScan:
    """One circumferential scan of sea-sky line frames; every array has shape ``(n,)``.

    Attributes carry their unit in the name; ``frame`` and ``pixels`` are integers.
    Frames are kept in file order, which in the paper is scan (time) order and increasing azimuth.
    """

    frame: np.ndarray
    azimuth_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    delta_eps_deg: np.ndarray
    pixels: np.ndarray
    h_meas_deg: np.ndarray
    source: str = "<memory>"

    @property
    def n(self) -> int:
        """Number of frames."""
        return int(self.azimuth_deg.shape[0])

    def as_table(self):
        """The scan as an astropy ``QTable`` with units (deg, pix)."""
        import astropy.units as u
        from astropy.table import QTable

        return QTable(
            {
                "frame": self.frame,
                "azimuth_deg": self.azimuth_deg * u.deg,
                "pitch_deg": self.pitch_deg * u.deg,
                "roll_deg": self.roll_deg * u.deg,
                "delta_eps_deg": self.delta_eps_deg * u.deg,
                "pixels": self.pixels * u.pix,
                "h_meas_deg": self.h_meas_deg * u.deg,
            },
            meta={"source": self.source},
        )

    def subset(self, mask: np.ndarray) -> "SeaSkyScan":
        """A scan holding only the frames where boolean ``mask`` (shape ``(n,)``) is true."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.n,):
            raise InputValueError(f"mask: expected shape ({self.n},), got {mask.shape}")
        return SeaSkyScan(**{c: getattr(self, c)[mask] for c in SEA_SKY_COLUMNS}, source=self.source)


def sea_sky_data_path() -> Path:
    """Path of the packaged ``usv_sea_sky_line.csv`` (USV sea-sky Table 1)."""
    return Path(str(resources.files("boresight") / "data" / "usv_sea_sky_line.csv"))


def load_sea_sky(path: str | Path | None = None, *, expected_rows: int | None = None) -> SeaSkyScan:
    """Read and validate a sea-sky line CSV (columns :data:`SEA_SKY_COLUMNS`).

    Parameters
    ----------
    path : str or Path, optional
        CSV file; default the packaged measurements of USV sea-sky Table 1 (then
        ``expected_rows`` defaults to 120).
    expected_rows : int, optional
        If given, the number of data rows the file must hold.

    Returns
    -------
    SeaSkyScan
        Arrays of shape ``(n,)``.

    Raises
    ------
    ObservationFileError
        (a ``ValueError``) Missing or extra column, an empty / non-numeric / non-finite cell, a wrong row count,
        fewer than 3 rows, a repeated frame number, or a row breaking USV sea-sky eq 28
        (h' = pixels/576 * 5 deg + delta_eps); the message names the column, the frame and the value.
    FileNotFoundError
        If ``path`` does not exist.
    """
    if path is None:
        path = sea_sky_data_path()
        if expected_rows is None:
            expected_rows = SEA_SKY_N_FRAMES
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"sea-sky file not found: {path}")
    header, body = _sea_sky_rows(path, expected_rows)
    arrays = _sea_sky_columns(path, header, body)
    _check_sea_sky_values(path, arrays)
    return SeaSkyScan(**arrays, source=str(path))


def _sea_sky_rows(path: Path, expected_rows: int | None) -> tuple[list[str], list[list[str]]]:
    """The header (checked against :data:`SEA_SKY_COLUMNS`) and the non-blank data rows (counted)."""
    text = path.read_text(encoding="utf-8")
    reader = csv.reader(io.StringIO(text))
    rows = [r for r in reader if r and any(c.strip() for c in r)]
    if not rows:
        raise ObservationFileError(f"{path}: empty file, expected a header {','.join(SEA_SKY_COLUMNS)}")
    header = [c.strip() for c in rows[0]]
    missing = [c for c in SEA_SKY_COLUMNS if c not in header]
    if missing:
        raise ObservationFileError(f"{path}: missing column(s) {missing}; got header {header}")
    extra = [c for c in header if c not in SEA_SKY_COLUMNS]
    if extra:
        raise ObservationFileError(f"{path}: unexpected column(s) {extra}; expected {list(SEA_SKY_COLUMNS)}")
    body = rows[1:]
    if expected_rows is not None and len(body) != expected_rows:
        raise ObservationFileError(f"{path}: expected {expected_rows} data rows, got {len(body)}")
    if len(body) < 3:
        raise ObservationFileError(f"{path}: need at least 3 data rows to fit (alpha, beta), got {len(body)}")
    return header, body


def _sea_sky_cell(path: Path, name: str, lineno: int, cell: str) -> float:
    try:
        value = float(cell.strip().replace("\u2212", "-"))
    except ValueError:
        raise ObservationFileError(f"{path}: column {name!r} line {lineno}: not a number: {cell!r}") from None
    if not np.isfinite(value):
        raise ObservationFileError(f"{path}: column {name!r} line {lineno}: non-finite value {value}")
    return value


def _sea_sky_columns(path: Path, header: list[str], body: list[list[str]]) -> dict[str, np.ndarray]:
    """The cells as float columns (``frame`` and ``pixels`` as integers), refusing a bad cell by line."""
    cols: dict[str, list[float]] = {c: [] for c in SEA_SKY_COLUMNS}
    for lineno, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise ObservationFileError(f"{path}: line {lineno} has {len(row)} cells, expected {len(header)}")
        for name, cell in zip(header, row):
            cols[name].append(_sea_sky_cell(path, name, lineno, cell))
    arrays = {c: np.asarray(v, dtype=float) for c, v in cols.items()}
    for name in ("frame", "pixels"):
        a = arrays[name]
        bad = np.flatnonzero(a != np.round(a))
        if bad.size:
            raise ObservationFileError(f"{path}: column {name!r} line {bad[0] + 2}: expected an integer, got {a[bad[0]]}")
        arrays[name] = a.astype(int)
    return arrays


def _check_sea_sky_values(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Unique frames, angles within ±90°, and every row on USV sea-sky eq 28."""
    frames, counts = np.unique(arrays["frame"], return_counts=True)
    if np.any(counts > 1):
        raise ObservationFileError(f"{path}: column 'frame': repeated frame number {frames[counts > 1][0]}")
    for name, lo, hi in (("pitch_deg", -90, 90), ("roll_deg", -90, 90), ("h_meas_deg", -90, 90)):
        a = arrays[name]
        bad = np.flatnonzero((a < lo) | (a > hi))
        if bad.size:
            raise ObservationFileError(
                f"{path}: column {name!r} frame {arrays['frame'][bad[0]]}: value {a[bad[0]]} outside [{lo}, {hi}] deg"
            )
    # USV sea-sky eq 28: h'_i = n_yi / N_h * omega_y + delta_eps_i
    h28 = arrays["pixels"] / TV_ROWS_PX * TV_FOV_V_DEG + arrays["delta_eps_deg"]
    dev = np.abs(h28 - arrays["h_meas_deg"])
    if np.any(dev > _EQ28_TOL_DEG):
        i = int(np.argmax(dev))
        raise ObservationFileError(
            f"{path}: column 'h_meas_deg' frame {arrays['frame'][i]}: value {arrays['h_meas_deg'][i]} "
            f"breaks USV sea-sky eq 28 (pixels/576*5 + delta_eps = {h28[i]:.9f})"
        )
