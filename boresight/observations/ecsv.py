"""Read and write ``ObservationSet`` as astropy ECSV, or Parquet (format in ``docs/data-format.md``).

One row per landmark observation (long format, easy to write by hand from flight data);
image-level columns (time, star-tracker quaternion, GNSS position and velocity, Earth rotation)
repeat on every row of the image and must agree. Floats are written with Python's shortest
round-trip repr, so write → read is bit-for-bit lossless for ``x y`` files.

The reader is a pipeline of small checks, each naming the file, the column or key as the user
wrote it, the row (0-based data row) and the value: header (duplicate YAML keys, duplicate column
names), integrity (a truncated last row), metadata, units (converted when the dimension is right,
refused otherwise), indices, image-level values, rotations (proper: det = +1), landmarks, image
points (``x y`` in metres or ``u v`` in pixels through the ``camera`` calibration), and the
geometry check shared with the in-memory ``ObservationSet`` (``observations.geometry_problem``).

The reader builds the row model's three tables straight from the rows (``_Index``: the canonical
(run, image, landmark) order by one ``lexsort``; image-level values scattered to (R, N), target
values to (R, T)), never an images × landmarks array: memory O(file rows).

Parquet (a path ending ``.parquet``, for large campaigns): the same columns, units and
metadata, written by astropy's Table (``format="parquet"``: astropy's own YAML header in the
file's schema metadata) and read with pyarrow (Apache-2.0, the optional extra ``parquet``), then
through the same checks. DECISION: astropy 8's Parquet *reader* also requires pandas; the file
is astropy's format, but it is read here with pyarrow and astropy's header parser
(``astropy.table.meta.get_header_from_yaml``), so the extra is pyarrow alone.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from boresight.core.error_sources import normalize_noise
from boresight.errors import InputTypeError, InputValueError
from boresight.files import atomic_path
from boresight.observations import model as _model
from boresight.observations.model import (
    FORMAT_NAME,
    FORMAT_VERSION,
    FORMAT_VERSION_LANDMARKS,
    FORMAT_VERSION_ROW_SIGMA,
    FORMAT_VERSION_STARS,
    LANDMARK_SIGHTS,
    LIMITS,
    READ_VERSIONS,
    SIGMA_XY_LIMITS_M,
    TARGET_KINDS,
    ObservationError,
    ObservationFileError,
    ObservationSet,
    catalogue_directions,
    rotation_problem,
)
from orbits.limits import check_memory

__all__ = ["write_ecsv", "read_ecsv", "COLUMNS"]

_CGI = "C_GI (Earth-fixed → inertial DCM) element {}; all nine or none: computed from astropy ITRS→GCRS if absent"

#: column -> (unit, required, meaning); unit "" = unitless (a unit there is refused)
COLUMNS = {
    "run": ("", False, "run index (Monte Carlo batches); 0 if absent"),
    "image": ("", True, "image index within the file"),
    "pass": ("", False, "pass index of a campaign; 0 if absent"),
    "t": ("s", False, "image time in seconds from the epoch_utc metadata (either t or time_utc)"),
    "time_utc": ("", False, "image time as an ISO UTC string (either t or time_utc)"),
    "q1": ("", True, "star-tracker attitude quaternion inertial → star tracker, vector part x"),
    "q2": ("", True, "… vector part y"),
    "q3": ("", True, "… vector part z"),
    "q4": ("", True, "… scalar part (scalar last)"),
    "r_x": ("m", True, "GNSS spacecraft position, inertial x"),
    "r_y": ("m", True, "… inertial y"),
    "r_z": ("m", True, "… inertial z"),
    "v_x": ("m / s", False, "GNSS spacecraft velocity, inertial x (format 1.1; all three or none)"),
    "v_y": ("m / s", False, "… inertial y"),
    "v_z": ("m / s", False, "… inertial z"),
    **{f"cgi{i}{j}": ("", False, _CGI.format(f"{i}{j}")) for i in (1, 2, 3) for j in (1, 2, 3)},
    "landmark": ("", True, "landmark identifier"),
    "X": ("m", True, "catalogue landmark position, Earth-fixed x"),
    "Y": ("m", True, "… Earth-fixed y"),
    "Z": ("m", True, "… Earth-fixed z"),
    "x": ("m", False, "measured image coordinate x on the focal plane (either x y or u v)"),
    "y": ("m", False, "measured image coordinate y on the focal plane"),
    "u": ("pix", False, "measured detector column coordinate, pixels (format 1.1, needs the camera metadata)"),
    "v": ("pix", False, "measured detector row coordinate, pixels"),
    "kind": ("", False, "target kind, 'landmark' or 'star' (format 1.2); 'landmark' if absent"),
    "hip": ("", False, "a star's Hipparcos number (format 1.2; star rows; −1 on landmark rows)"),
    "ra": (
        "deg",
        False,
        "a star's ICRS right ascension at the catalogue epoch star_epoch_jd_tt (star rows; NaN on landmark rows)",
    ),
    "dec": ("deg", False, "… its declination"),
    "parallax": ("mas", False, "… its parallax"),
    "pm_ra_cosdec": ("mas / yr", False, "… its proper motion in right ascension, μα cos δ"),
    "pm_dec": ("mas / yr", False, "… its proper motion in declination"),
    "mag": ("", False, "… its catalogue magnitude (Hipparcos Hp)"),
    "rv": ("km / s", False, "… its radial velocity (optional; 0 if absent)"),
    "sigma_x": (
        "m",
        False,
        "the row's own σ of x on the focal plane (format 1.3; both or neither; NaN: the noise model's pixel σ)",
    ),
    "sigma_y": ("m", False, "… of y"),
}

#: the star columns of format 1.2 (``rv`` optional), and their ``StarCatalogue.from_arrays`` arguments
_STAR_COLS = {
    "hip": "hip",
    "ra": "ra_deg",
    "dec": "dec_deg",
    "parallax": "parallax_mas",
    "pm_ra_cosdec": "pm_ra_cosdec_mas_yr",
    "pm_dec": "pm_dec_mas_yr",
    "mag": "magnitude_hp",
}

_CGI_COLS = [f"cgi{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]

#: column -> (largest magnitude in the format's unit, unit, meaning): the in-memory bounds
#: (``observations.LIMITS``) plus the unit-norm columns and pixels, checked on every row of every
#: run before anything is computed from the value
_COLUMN_LIMITS = {
    "t": LIMITS["t_s"],
    **{f"r_{a}": LIMITS["r_sc_i_m"] for a in "xyz"},
    **{f"v_{a}": LIMITS["v_sc_i_m_s"] for a in "xyz"},
    **{a: LIMITS["landmark_g_m"] for a in "XYZ"},
    **{a: LIMITS["xy_m"] for a in "xy"},
    # unit-norm values: a loose bound that only keeps the norm finite (the norm and rotation
    # checks then say what is wrong, e.g. "quaternion norm 2, expected 1")
    **{f"q{k}": (1e3, "", "an element of a unit quaternion") for k in (1, 2, 3, 4)},
    **{c: (1e3, "", "an element of a rotation matrix") for c in _CGI_COLS},
    "u": (1e9, "pix", "detector column"),
    "v": (1e9, "pix", "detector row"),
}


# ---------------------------------------------------------------------------- writing


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v


def write_ecsv(obs: ObservationSet, path, overwrite: bool = False, image_columns: str = "xy") -> Path:
    """Write every run of ``obs`` to ``path`` (ECSV, format 1.1, or 1.2 with star rows; Parquet for a ``.parquet`` path). Returns the path.

    ``image_columns``: ``"xy"`` (focal-plane metres, lossless) or ``"uv"`` (detector pixels through
    ``obs.camera``, distortion applied; reading back undistorts to within 1e-9 px). Only
    landmarks observed at least once are listed in ``landmark_order`` (an unobserved landmark has
    no row to carry its position).
    """
    if image_columns not in ("xy", "uv"):
        raise InputValueError(f"image_columns must be 'xy' or 'uv', got {image_columns!r}")
    if image_columns == "uv" and obs.camera is None:
        raise ObservationFileError(f"{path}: cannot write pixel columns u v: the ObservationSet has no camera calibration")
    empty = obs.rows_per_image == 0
    if np.any(empty):
        raise ObservationError(
            f"{path}: ObservationSet image {int(np.argmax(empty))} has no landmark observations (a row-per-observation file "
            "cannot carry it); drop it with obs.images(obs.rows_per_image > 0) before writing"
        )
    _check_ids_survive(obs, path)
    t = _table(obs, image_columns)
    t.meta.update({k: _jsonable(v) for k, v in _metadata(obs, len(t)).items()})
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and not overwrite:
        raise FileExistsError(17, "File exists (pass overwrite=True to replace it)", str(path))
    fmt = "parquet" if _is_parquet(path) else "ascii.ecsv"
    if fmt == "parquet":
        _pyarrow(path)
    with atomic_path(path) as tmp:  # an interrupted write leaves the old file or the new one
        t.write(tmp, format=fmt, overwrite=True)
    return path


def _check_ids_survive(obs: ObservationSet, path) -> None:
    """Refuse, before anything is written, a target id the file could not give back unchanged.

    DECISION: astropy's ECSV reader strips the spaces at either end of a string cell and cannot hold a
    line break in one; an empty id reads back as another value. Such an id was written and then
    refused by our own reader ("id 'sp' not in metadata landmark_order"), so a file we wrote could not
    be read. Refused here, for both formats (one file format, two encodings), naming the id as given
    and the target's index, rather than silently changed (ids are the user's keys).
    """
    ids = np.asarray(obs.landmark_ids).astype(str)
    seen = np.bincount(obs.target_index, minlength=obs.n_targets) > 0  # only observed targets are written
    unkeepable = (ids == "") | (np.char.strip(ids) != ids) | (np.char.find(ids, "\n") >= 0) | (np.char.find(ids, "\r") >= 0)
    bad = seen & unkeepable
    if np.any(bad):
        m = int(np.argmax(bad))
        lm = str(ids[m])
        why = (
            "it is empty"
            if lm == ""
            else "it has spaces at an end, which an ECSV reader strips"
            if lm != lm.strip()
            else "it holds a line break"
        )
        raise ObservationFileError(
            f"{path}: target id {lm!r} (target {m}) cannot be written: {why}; rename it (e.g. {lm.strip() or 'T' + str(m)!r})"
        )


def _is_parquet(path) -> bool:
    return Path(path).suffix.lower() == ".parquet"


def _pyarrow(path):
    """``pyarrow.parquet``, or a refusal naming the extra that provides it."""
    try:
        import pyarrow.parquet as pq
    except ImportError:
        from boresight.errors import MissingExtraError, extra_hint

        raise MissingExtraError(f"{path}: Parquet observation files need pyarrow, {extra_hint('parquet')}") from None
    return pq


def _load_parquet(path: Path) -> _File:
    """A Parquet observation file as an astropy Table (columns, units, metadata), with pyarrow."""
    from astropy.table import Table
    from astropy.table.meta import get_header_from_yaml

    pq = _pyarrow(path)
    try:
        pa_table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError and others for a damaged file
        raise ObservationFileError(f"{path}: not a readable Parquet file ({type(exc).__name__}: {exc})") from None
    md = {k.decode("utf-8"): v.decode("utf-8") for k, v in (pa_table.schema.metadata or {}).items()}
    header: dict = {}
    if "table_meta_yaml" in md:
        try:
            header = get_header_from_yaml(md["table_meta_yaml"].split("\n"))
        except Exception as exc:  # astropy raises YAML and its own errors for a bad header
            raise ObservationFileError(f"{path}: the Parquet file's astropy header is not readable ({exc})") from None
    units = {d.get("name"): d.get("unit") for d in header.get("datatype", []) if isinstance(d, dict)}
    tab = Table(meta=header.get("meta", {}))
    for name in pa_table.column_names:
        col = pa_table.column(name)
        if col.null_count:
            row = int(np.argmax(np.asarray(col.is_null())))
            raise ObservationFileError(f"{path}: column {name!r} row {row}: missing value")
        values = col.to_numpy()
        if values.dtype == object:
            values = values.astype(str)
        tab[name] = values
        if units.get(name):
            tab[name].unit = units[name]
        del col, values
    del pa_table
    return _File(path, tab, dict(tab.meta))


def _table(obs: ObservationSet, image_columns: str):
    """One row per (run, observation) in canonical order, image-level values repeated."""
    from astropy.table import Table

    K = obs.n_observations
    r_idx = np.repeat(np.arange(obs.runs), K)
    k_idx = np.tile(np.arange(K), obs.runs)
    n_idx, m_idx = obs.image_index[k_idx], obs.target_index[k_idx]
    t = Table()

    def put(name, values, unit=None):
        t[name] = values
        if unit:
            t[name].unit = unit

    put("run", r_idx.astype(np.int64))
    put("image", n_idx.astype(np.int64))
    put("pass", obs.pass_index[n_idx].astype(np.int64))
    put("t", obs.t_s[n_idx], "s")
    for k in range(4):
        put(f"q{k + 1}", obs.q_is[r_idx, n_idx, k])
    for k, ax in enumerate("xyz"):
        put(f"r_{ax}", obs.r_sc_i_m[r_idx, n_idx, k], "m")
    if obs.v_sc_i_m_s is not None:
        for k, ax in enumerate("xyz"):
            put(f"v_{ax}", obs.v_sc_i_m_s[r_idx, n_idx, k], "m / s")
    for k, name in enumerate(_CGI_COLS):
        put(name, obs.C_GI[n_idx, k // 3, k % 3])
    put("landmark", obs.landmark_ids.astype(str)[m_idx])
    for k, ax in enumerate("XYZ"):
        put(ax, obs.landmark_g_m[r_idx, m_idx, k], "m")
    if obs.stars is not None:
        _star_columns(obs, m_idx, put)
    xy = obs.xy_m.reshape(-1, 2)
    if image_columns == "uv" and obs.camera is not None:  # write_ecsv refused uv without a camera
        xy = obs.camera.focal_plane_to_pixels(xy)
    for k, ax in enumerate(image_columns):
        put(ax, xy[:, k], "m" if image_columns == "xy" else "pix")
    if obs.sigma_xy_m is not None:  # format 1.3: each row's own σ, the same in every run
        for k, ax in enumerate("xy"):
            put(f"sigma_{ax}", obs.sigma_xy_m[k_idx, k], "m")
    return t


def _star_columns(obs: ObservationSet, m_idx, put) -> None:
    """Format 1.2: ``kind`` and each star's astrometry on its rows (NaN, HIP −1 on landmark rows)."""
    put("kind", np.asarray(obs.target_kind).astype(str)[m_idx])
    rank = obs.star_rank()[m_idx]
    star = rank >= 0
    stars: Any = obs.stars
    hip = np.full(rank.size, -1, np.int64)
    hip[star] = stars.hip[rank[star]]
    put("hip", hip)
    values = {
        "ra": (np.degrees(stars.ra_rad), "deg"),
        "dec": (np.degrees(stars.dec_rad), "deg"),
        "parallax": (stars.parallax_mas, "mas"),
        "pm_ra_cosdec": (stars.pm_ra_cosdec_mas_yr, "mas / yr"),
        "pm_dec": (stars.pm_dec_mas_yr, "mas / yr"),
        "mag": (stars.magnitude_hp, None),
        "rv": (stars.radial_velocity_km_s, "km / s"),
    }
    for name, (v, unit) in values.items():
        if name == "rv" and not np.any(v):
            continue
        col = np.full(rank.size, np.nan)
        col[star] = v[rank[star]]
        put(name, col, unit)


def _written_version(obs: ObservationSet) -> str:
    """The lowest format version that carries the set (``model``'s DECISION on versions)."""
    if obs.landmark_sight != "geometric":
        return FORMAT_VERSION
    if obs.sigma_xy_m is not None:
        return FORMAT_VERSION_ROW_SIGMA
    return FORMAT_VERSION_STARS if obs.stars is not None else FORMAT_VERSION_LANDMARKS


def _metadata(obs: ObservationSet, n_rows: int) -> dict:
    meta = {
        "format": FORMAT_NAME,
        "format_version": _written_version(obs),
        "n_rows": n_rows,
        "epoch_utc": obs.epoch_utc,
        "focal_length_m": float(obs.focal_length_m),
        "fov_deg": None if obs.fov_deg is None else float(obs.fov_deg),
        "pixel_pitch_m": None if obs.pixel_pitch_m is None else float(obs.pixel_pitch_m),
        "C_SK_nominal": obs.C_SK_nominal.tolist(),
        "frames": dict(obs.frames),
        "quaternion_order": "scalar-last [q1, q2, q3, q4]; A(q) maps reference to body components",
        "theta_convention": "C_SK,true = exp(-Phi(theta)) C_SK,nominal (Kiev 2012 eq 24)",
        "landmark_order": obs.landmark_ids.astype(str)[np.bincount(obs.target_index, minlength=obs.n_targets) > 0].tolist(),
    }
    if obs.landmark_sight != "geometric":  # format 1.4; without the key a file's landmark rows are geometric
        meta["landmark_sight"] = obs.landmark_sight
    if obs.stars is not None:
        meta["star_epoch_jd_tt"] = float(obs.stars.epoch_jd_tt)
        meta["star_catalogue"] = obs.stars.source
    if obs.noise is not None:
        meta["noise"] = obs.noise
    if obs.camera is not None:
        meta["camera"] = obs.camera.to_mapping()
    if obs.truth is not None and "theta_rad" in obs.truth:
        meta["truth_theta_rad"] = np.asarray(obs.truth["theta_rad"]).tolist()
    if obs.truth is not None and obs.truth.get("effects"):
        # hidden catalogue effects (orbits.effects), in each effect's units: {name: values}
        meta["truth_effects"] = {k: np.asarray(v, float).tolist() for k, v in obs.truth["effects"].items()}
    return meta


# ---------------------------------------------------------------------------- reading


class _File:
    """One observation file being read: the table, its metadata and column access with checks."""

    def __init__(self, path: Path, tab, meta: dict):
        self.path, self.tab, self.meta = path, tab, meta
        self.n = len(tab)
        self.factor: dict[str, float] = {}  # column -> unit conversion factor to the format's unit

    def err(self, msg) -> ObservationFileError:
        return ObservationFileError(f"{self.path}: {msg}")

    def has(self, name) -> bool:
        return name in self.tab.colnames

    def col(self, name, dtype=float, rows=None) -> np.ndarray:
        """Column ``name`` as an array: no missing or non-finite value, converted to the format's unit.
        ``rows`` (a boolean mask): only those rows are checked (the others are returned as NaN):
        a landmark's position on landmark rows, a star's astrometry on star rows."""
        if rows is not None:
            out = np.full(self.n, np.nan)
            idx = np.flatnonzero(rows)
            if idx.size:
                sub = _File(self.path, self.tab[idx], self.meta)
                sub.factor = self.factor
                try:
                    out[idx] = sub.col(name, dtype)
                except ObservationFileError as exc:  # name the row of the whole file
                    import re

                    msg = re.sub(r"row (\d+)", lambda m: f"row {int(idx[int(m.group(1))])}", str(exc), count=1)
                    raise ObservationFileError(msg) from None
            return out
        c = self.tab[name]
        if hasattr(c, "mask") and np.any(c.mask):
            row = int(np.argmax(np.asarray(c.mask)))
            raise self.err(f"column {name!r} row {row}: missing value")
        try:
            a = np.asarray(c, dtype=float)
        except (TypeError, ValueError):
            what = "numbers" if dtype is float else "integers"
            raise self.err(f"column {name!r}: values are not {what} (e.g. row 0: {str(np.asarray(c)[0])!r})") from None
        if not np.all(np.isfinite(a)):
            row = int(np.argmax(~np.isfinite(a)))
            raise self.err(f"column {name!r} row {row}: non-finite value {float(a[row])!r}")
        if dtype is int:
            frac = a != np.round(a)
            if np.any(frac):
                row = int(np.argmax(frac))
                raise self.err(f"column {name!r} row {row}: index {float(a[row])!r} is not a whole number")
            if np.any(a < 0):
                row = int(np.argmax(a < 0))
                raise self.err(f"column {name!r} row {row}: negative index {int(a[row])}")
            if np.any(a >= self.n):
                row = int(np.argmax(a >= self.n))
                raise self.err(
                    f"column {name!r} row {row}: index {a[row]:.0f} but the file has {self.n} rows "
                    f"({name}s are numbered 0..{'R' if name == 'run' else 'N'}−1 and each has at least one row)"
                )
            return a.astype(np.int64)
        a = a * self.factor.get(name, 1.0)
        if name in _COLUMN_LIMITS:
            limit, unit, what = _COLUMN_LIMITS[name]
            big = np.abs(a) > limit
            if np.any(big):
                row = int(np.argmax(big))
                u = f" {unit}" if unit else ""
                raise self.err(f"column {name!r} row {row}: value {float(a[row]):.6g}{u} is beyond ±{limit:g}{u} ({what})")
        return a


def _header(path: Path, text: str):
    """The ECSV header's YAML text, the column-name line's names, and where that line starts.

    Only the header and the column-name line are split into lines (a 100 000-row file's lines
    as Python strings were 3× the file); the body is left to ``_parse_body``."""
    import csv

    head, pos, n = [], 0, len(text)
    while pos < n:
        end = text.find("\n", pos)
        end = n if end < 0 else end
        line = text[pos:end].rstrip("\r")
        if line.strip() and not line.startswith("#"):
            break
        if line.startswith("#"):
            head.append(line)
        pos = end + 1
    yaml_text = "\n".join(ln[2:] if ln.startswith("# ") else ln[1:] for ln in head[1:])
    first = text[pos : (text.find("\n", pos) if text.find("\n", pos) >= 0 else n)].rstrip("\r")
    names = next(csv.reader([first], delimiter=" ", skipinitialspace=True)) if pos < n else []
    return yaml_text, names, pos


def _body_lines(text: str) -> list:
    """The data lines (with the column-name line): the truncated-file message only."""
    return [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]


#: DECISION: astropy's ECSV parser is pure Python and holds ~8× its text in Python
#: strings while it runs; a file of more rows than this is parsed this many rows at a time (the
#: first piece with the header and its metadata, the others with the column header only), the
#: columns joined: the reader's peak is then the text, one piece's parse and the columns. Measured
#: on a 39 300-row, 17 MB file (tracemalloc, ObservationSet.read): 143 MB in one piece, 55 MB in
#: pieces of 5 000 rows, CPU 2.9 → 3.3 s. A smaller file takes the one-piece path, and any parse
#: error is reported from the whole text, as before.
ECSV_CHUNK_ROWS = 5_000


def _slim_header(tab) -> str:
    """The ECSV header (with the column-name line) of ``tab``'s columns and units, without metadata:
    what the later pieces of a long file are parsed with (the metadata's YAML — ``landmark_order``
    lists every landmark — is parsed once)."""
    import io

    empty = tab[:0].copy()
    empty.meta.clear()
    buf = io.StringIO()
    empty.write(buf, format="ascii.ecsv")
    return buf.getvalue()


def _parse_body(text: str, body_start: int, head: str | None = None):
    """The ECSV text as an astropy Table, parsed ``ECSV_CHUNK_ROWS`` data rows at a time; with ``head``,
    that header instead of ``text[:body_start]`` (``_without_landmark_order``)."""
    import gc

    from astropy.table import Table

    n = len(text)
    names_end = text.find("\n", body_start)
    names_end = n if names_end < 0 else names_end + 1
    bounds, pos = [], names_end
    while pos < n:
        end = pos
        for _ in range(ECSV_CHUNK_ROWS):
            end = text.find("\n", end)
            if end < 0:
                end = n
                break
            end += 1
        bounds.append((pos, end))
        pos = end
    if len(bounds) <= 1:
        return Table.read(text if head is None else head + text[body_start:], format="ascii.ecsv")
    # DECISION: the objects alive before the parse (the interpreter's, the imports') are frozen out of the
    # cycle collector while the pieces are parsed (``gc.freeze``; only when nothing else has frozen any),
    # so each piece's collection below traverses the parse's own objects, not every import's once per
    # piece (a cost of pieces × imports): a fresh process's read of 131 000 rows 4.9 → 3.8 s CPU, of
    # 13 100 rows 0.44 → 0.37 s (/tmp timing, 2 runs each). Nothing frozen is garbage of this parse.
    freeze = gc.get_freeze_count() == 0
    if freeze:
        gc.freeze()
    try:
        return _parse_pieces(text, body_start, head, bounds)
    finally:
        if freeze:
            gc.unfreeze()


def _parse_pieces(text: str, body_start: int, head: str | None, bounds: list):
    """``_parse_body`` of a text of several pieces ``bounds`` ((start, end) of each piece's rows), the
    first with the header ``head``."""
    import gc

    from astropy.table import Table

    try:
        first = Table.read(  # the header, its metadata and piece 0
            text[: bounds[0][1]] if head is None else head + text[body_start : bounds[0][1]], format="ascii.ecsv"
        )
        head = _slim_header(first)  # the other pieces: columns and units only (no metadata to parse again)
        columns = {name: [_plain(first[name])] for name in first.colnames}
        for a, b in bounds[1:]:
            piece = Table.read(head + text[a:b], format="ascii.ecsv")
            for name in first.colnames:
                columns[name].append(_plain(piece[name]))
            del piece
            # astropy's reader objects form reference cycles that keep each piece's parsed strings
            # (~8× its text) alive until the cycle collector runs: collect them piece by piece
            gc.collect()
    except Exception:  # the whole text's own error (line numbers of the file, not of a piece)
        return Table.read(text, format="ascii.ecsv")
    tab = Table(meta=dict(first.meta))
    for name in first.colnames:
        parts = columns.pop(name)
        masked = any(isinstance(c, np.ma.MaskedArray) for c in parts)
        tab[name] = np.ma.concatenate(parts) if masked else np.concatenate(parts)
        tab[name].unit = first[name].unit
    return tab


def _plain(col):
    """A parsed column as a plain (or masked) numpy array, holding nothing else."""
    if getattr(col, "mask", None) is not None and np.any(col.mask):
        return np.ma.MaskedArray(np.array(col.data), mask=np.array(col.mask))
    return np.array(col)


def _fast_loader():
    """PyYAML's loader with libyaml's C scanner and parser (``CSafeLoader``: the safe constructors, the
    same scalar resolution as astropy's ``AstropyLoader``, a subclass of ``SafeLoader``), or None
    without libyaml."""
    import yaml

    return getattr(yaml, "CSafeLoader", None)


def _duplicate_key(yaml_text):
    """(key, line) of the first key repeated inside one YAML mapping (or !!omap), or None.

    DECISION: composed (nodes only, no tags constructed) by libyaml's C parser where PyYAML has it:
    the header lists every target (``landmark_order``), whose pure-Python parse was 31 ms of a 103 ms
    read of 1 310 single-use targets (2 ms in C); the same nodes and line marks."""
    import yaml
    from astropy.io.misc.yaml import AstropyLoader

    try:
        root = yaml.compose(yaml_text, Loader=_fast_loader() or AstropyLoader)
    except yaml.YAMLError:
        return None  # astropy's own reader reports the syntax error
    stack = [root] if root is not None else []
    while stack:
        node = stack.pop()
        if isinstance(node, yaml.MappingNode):
            pairs = [(k, v) for k, v in node.value]
        elif isinstance(node, yaml.SequenceNode) and node.tag.endswith(":omap"):
            pairs = [p for item in node.value if isinstance(item, yaml.MappingNode) for p in item.value]
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
            continue
        else:
            continue
        seen = set()
        for k, v in pairs:
            key = getattr(k, "value", None)
            if key in seen:
                return key, k.start_mark.line
            seen.add(key)
            stack.append(v)
    return None


def _plain_string_list(item: str, loader) -> list | None:
    """The ids of ``item``, the YAML ``- landmark_order: [id, id, …]`` (or its block form), from libyaml's
    parse events when every id is a string scalar (quoted, or plain and resolved as a string by YAML's
    implicit resolvers, as every loader here resolves it), else None. No node or object per id is built:
    at 131 000 ids 0.11 s against 0.45 s for ``yaml.load`` (/tmp timing)."""
    import yaml

    resolver = yaml.resolver.Resolver()
    typed = resolver.yaml_implicit_resolvers
    str_tag = "tag:yaml.org,2002:str"
    events = yaml.parse(item, Loader=loader)
    kinds = [yaml.StreamStartEvent, yaml.DocumentStartEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent]
    try:
        for kind in kinds:
            if not isinstance(next(events), kind):
                return None
        key = next(events)
        if not (isinstance(key, yaml.ScalarEvent) and key.value == "landmark_order" and not key.style):
            return None
        first = next(events)
        if not isinstance(first, yaml.SequenceStartEvent) or first.tag is not None or first.anchor is not None:
            return None
        out = []
        for e in events:
            if isinstance(e, yaml.SequenceEndEvent):
                break
            if not isinstance(e, yaml.ScalarEvent) or e.tag is not None or e.anchor is not None:
                return None
            v = e.value
            if not e.style and (v[:1] in typed or None in typed or not v):  # plain (libyaml: style '')
                if resolver.resolve(yaml.ScalarNode, v, (True, False)) != str_tag:
                    return None  # a number, boolean or null: yaml.load's constructors decide
            out.append(v)
        rest = [type(e) for e in events]
    except (StopIteration, yaml.YAMLError):
        return None
    if rest != [yaml.MappingEndEvent, yaml.SequenceEndEvent, yaml.DocumentEndEvent, yaml.StreamEndEvent]:
        return None
    return out


def _without_landmark_order(text: str, body_start: int) -> tuple[str, list | None]:
    """(header, landmark_order): the file's header (``text[:body_start]``) with the metadata item
    ``landmark_order`` emptied and that item's list parsed with libyaml's C parser; or (the header, None)
    unchanged where the item is not in the writer's layout (an ``!!omap`` entry ``# - landmark_order: …``
    and its continuation lines), is not one list of scalars, or PyYAML has no libyaml. The emptied item
    keeps its lines (as ``#`` lines, which ECSV skips), so a header line number is the file's. Only the
    header is copied (a copy of the whole text was 3× a 54 MB file's text at once).

    DECISION: astropy's ECSV reader parses the header's YAML in pure Python, and ``landmark_order``
    lists every target: on the single-use campaign (1 310 targets) it made astropy's read 63 ms against
    41 ms for the same rows with 253 shared landmarks. The list is parsed here (libyaml's events, the
    same safe scalar resolution: ``_plain_string_list``, else ``yaml.load`` with libyaml) and astropy
    parses the rest; any error is still reported from the whole text."""
    import yaml

    loader = _fast_loader()
    head = text[:body_start]
    start = head.find("\n# - landmark_order:") + 1
    if loader is None or start <= 0:
        return head, None
    end = head.find("\n", start) + 1
    while 0 < end < len(head) and head.startswith("#   ", end):  # the item's continuation lines
        end = head.find("\n", end) + 1
    if end <= 0:
        return head, None
    lines = head[start:end].splitlines()
    item = "\n".join(ln[2:] for ln in lines)
    order = _plain_string_list(item, loader)
    if order is None:
        try:
            parsed = yaml.load(item, Loader=loader)
        except yaml.YAMLError:
            return head, None
        if not (
            isinstance(parsed, list)
            and len(parsed) == 1
            and isinstance(parsed[0], dict)
            and list(parsed[0]) == ["landmark_order"]
            and isinstance(parsed[0]["landmark_order"], list)
        ):
            return head, None
        order = parsed[0]["landmark_order"]
        if any(isinstance(k, (list, dict)) for k in order):  # a key inside is the duplicate check's: astropy's route
            return head, None
    return head[:start] + "# - landmark_order: []\n" + "#\n" * (len(lines) - 1) + head[end:], order


def _unreadable_where(text: str, yaml_text: str, names: list) -> str | None:
    """Where astropy's ECSV parser failed, as a line of the file (astropy names the symptom, not
    the line): the signature line, a NUL byte, a YAML error's line, a datatype entry without a
    name, or the first column where the header's datatype and the column-name line disagree."""
    import yaml
    from astropy.io.misc.yaml import AstropyLoader

    lines = text.split("\n")
    if not lines[0].startswith("# %ECSV"):
        return "line 1: the first line must be the ECSV signature '# %ECSV 1.0'"
    if len(lines) < 2 or lines[1].strip() != "# ---":
        return "line 2: the second line must be '# ---' (the start of the ECSV header)"
    if "\x00" in text:
        return f"line {text.count(chr(10), 0, text.index(chr(0))) + 1}: a NUL byte"
    try:
        header = yaml.load(yaml_text, Loader=AstropyLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        return None if mark is None else f"header line {mark.line + 3}: not valid YAML ({getattr(exc, 'problem', '') or exc})"
    entries = header.get("datatype") if isinstance(header, dict) else None
    if not isinstance(entries, list):
        return None
    for k, entry in enumerate(entries):
        if not isinstance(entry, dict) or "name" not in entry:
            return f"header line {k + 4}: datatype entry {k} has no column name ({entry!r})"
    declared = [str(e["name"]) for e in entries]
    if names and declared != list(names):
        k = next((i for i, (a, b) in enumerate(zip(declared, names)) if a != b), min(len(declared), len(names)))
        line = next(i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")) + 1
        got = repr(names[k]) if k < len(names) else "nothing"
        want = repr(declared[k]) if k < len(declared) else "no column"
        return (
            f"line {line}: column {k + 1} of the column-name line is {got} where the header declares {want} "
            "(the header and the column names disagree: a deleted or duplicated line?)"
        )
    return None


#: DECISION: the reader's working set, estimated before the file is read (``read_bytes``): an ECSV
#: file's text is held while its body is parsed in pieces and the tables are built — measured traced
#: peaks 8.5× the file at 0.5 MB (campaign-6pass, a fixed ~4 MB of parser state dominating), 2.8× at
#: 54 MB (docs/benchmarks.md, the ×100 single-use campaign): 3 × the size + 4 MiB covers both.
READ_BYTES_PER_FILE_BYTE = 3.0
READ_FIXED_BYTES = 4.0 * 2**20


def read_bytes(path) -> float:
    """Estimated memory (bytes) of reading the observation file ``path``: ``READ_BYTES_PER_FILE_BYTE``
    × its size + ``READ_FIXED_BYTES`` for ECSV; for Parquet (compressed on disk) its decoded columns,
    rows × columns float64, three times (pyarrow's table, the numpy columns, the tables built)."""
    path = Path(path)
    if _is_parquet(path):
        try:
            meta = _pyarrow(path).ParquetFile(path).metadata
            return 3 * 8.0 * float(meta.num_rows) * float(meta.num_columns) + READ_FIXED_BYTES
        except Exception:  # a damaged file: the reader names what is wrong with it
            return READ_BYTES_PER_FILE_BYTE * 8 * path.stat().st_size + READ_FIXED_BYTES
    return READ_BYTES_PER_FILE_BYTE * path.stat().st_size + READ_FIXED_BYTES


def _load(path) -> _File:
    """Read the file: the memory budget (``read_bytes``), header checks, astropy's ECSV parser, then
    the file's integrity."""

    if not isinstance(path, (str, os.PathLike)):
        raise InputTypeError.expected("ObservationSet.read", "path", "an observation file's path (str or pathlib.Path)", path)
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"observation file not found: {path}")
    if path.is_dir():
        raise IsADirectoryError(f"{path}: is a folder, not an observation file")
    if path.is_file():
        check_memory(
            f"reading {path} ({path.stat().st_size / 2**20:.3g} MiB on disk)",
            read_bytes(path),
            hint="split the campaign into several files (by pass), or write it as Parquet",
        )
    if _is_parquet(path):
        f = _load_parquet(path)
        _check_row_count(f)
        return f
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        from orbits.files import utf8_error_location

        raise ObservationFileError(f"{path}: not a text (UTF-8) file: {utf8_error_location(exc)}") from None
    if not text.strip():  # astropy would read "" as a file name (IsADirectoryError: '.')
        raise ObservationFileError(
            f"{path}: the file is empty ({len(text)} bytes); an observation file starts with '# %ECSV 1.0'"
        )
    yaml_text, names, body_start = _header(path, text)
    head, order = _without_landmark_order(text, body_start)  # the same lines, the per-target list emptied
    dup = _duplicate_key(yaml_text if order is None else _header(path, head)[0])
    if dup is not None:
        raise ObservationFileError(f"{path}: header line {dup[1] + 3}: key {dup[0]!r} appears twice (a YAML key must be unique)")
    seen = set()
    for name in names:
        if name in seen:
            raise ObservationFileError(f"{path}: column {name!r} appears twice in the header line {' '.join(names)!r}")
        seen.add(name)
    if text and not text.endswith("\n"):
        body = _body_lines(text)
        raise ObservationFileError(
            f"{path}: row {max(len(body) - 2, 0)}: the file does not end with a newline, so its last row {body[-1] if body else ''!r} "
            "may be cut short (a truncated file); end the file with a newline if the row is complete"
        )
    try:
        tab = _parse_body(text, body_start, None if order is None else head)
        if order is not None:
            tab.meta["landmark_order"] = order
    except Exception as exc:  # astropy raises several types for malformed ECSV
        from orbits.files import wrong_kind_hint

        hint = wrong_kind_hint(path, "ecsv", "an observation file (ECSV)")
        if hint:
            raise ObservationFileError(f"{path}: {hint}") from None
        where = _unreadable_where(text, yaml_text, names)
        raise ObservationFileError(
            f"{path}: {where + '; ' if where else ''}not a readable ECSV file ({type(exc).__name__}: {exc})"
        ) from None
    f = _File(path, tab, dict(tab.meta))
    _check_row_count(f)
    return f


def _check_row_count(f: _File):
    """A truncated file is an error: fewer rows than the writer's ``n_rows`` (a cut inside the last
    row is caught before parsing: the file then does not end with a newline)."""
    declared = f.meta.get("n_rows")
    if declared is not None:
        if isinstance(declared, bool) or not isinstance(declared, int) or declared < 0:
            raise f.err(f"metadata 'n_rows' must be a whole number ≥ 0, got {declared!r}")
        if f.n < declared:
            raise f.err(
                f"metadata 'n_rows' = {declared} but the file has {f.n} data rows: the file is truncated "
                "(if you removed rows on purpose, update or delete 'n_rows')"
            )


def _check_meta(f: _File) -> float:
    """Format, version and focal length; returns F (m)."""
    meta = f.meta
    if meta.get("format") != FORMAT_NAME:
        raise f.err(f"metadata 'format' must be {FORMAT_NAME!r}, got {meta.get('format')!r}")
    version = str(meta.get("format_version"))
    if version.split(".")[0] != FORMAT_VERSION.split(".")[0]:
        raise f.err(
            f"metadata 'format_version': unsupported format_version {version!r} (this reader reads {', '.join(READ_VERSIONS)})"
        )
    focal = meta.get("focal_length_m")
    if (
        isinstance(focal, bool)
        or not isinstance(focal, (int, float))
        or not np.isfinite(focal)
        or not 0 < focal <= LIMITS["focal_length_m"][0]
    ):
        raise f.err(f"metadata 'focal_length_m' must be a number > 0 m and ≤ {LIMITS['focal_length_m'][0]:g} m, got {focal!r}")
    fov = meta.get("fov_deg")
    if fov is not None and (isinstance(fov, bool) or not isinstance(fov, (int, float)) or not 0 < fov < 180):
        raise f.err(f"metadata 'fov_deg' must be a number in (0, 180), got {fov!r}")
    if meta.get("landmark_sight", "geometric") not in LANDMARK_SIGHTS:
        raise f.err(
            f"metadata 'landmark_sight' must be one of {', '.join(repr(k) for k in LANDMARK_SIGHTS)}, "
            f"got {meta.get('landmark_sight')!r}"
        )
    return float(focal)


def _check_columns(f: _File):
    """Required columns present; units converted to the format's (right dimension) or refused."""
    from astropy import units as u

    f.factor = {}
    for name, (unit, required, _) in COLUMNS.items():
        if required and not f.has(name):
            raise f.err(f"missing required column {name!r}")
        if not f.has(name):
            continue
        got = f.tab[name].unit
        if isinstance(got, u.UnrecognizedUnit):
            raise f.err(
                f"column {name!r} has unit {got.to_string()!r}, which astropy does not recognise (expected {unit or 'no unit'!r})"
            )
        if not unit:
            if got is not None and u.Unit(got) != u.dimensionless_unscaled:
                raise f.err(f"column {name!r} is unitless, got unit {got.to_string()!r}")
            continue
        if got is None:
            raise f.err(f"column {name!r} needs a unit ({unit!r} or one convertible to it), got none")
        try:
            f.factor[name] = float(u.Unit(got).to(unit))
        except u.UnitConversionError:
            raise f.err(
                f"column {name!r} has unit {got.to_string()!r}, which is not convertible to {unit!r} (wrong dimension)"
            ) from None
    for group in (("x", "y"), ("u", "v"), ("v_x", "v_y", "v_z"), ("sigma_x", "sigma_y")):
        absent = [c for c in group if not f.has(c)]
        if 0 < len(absent) < len(group):
            raise f.err(f"missing required column {absent[0]!r} (columns {' '.join(group)} go together)")
    if f.has("x") == f.has("u"):
        raise f.err(
            "needs the image points as 'x y' (focal plane, m) or as 'u v' (pixels, with the camera metadata), not both or neither"
        )
    if not f.has("t") and not f.has("time_utc"):
        raise f.err("needs a time column: 't' (s from epoch_utc) or 'time_utc' (ISO UTC)")
    if f.n == 0:
        raise f.err("no observation rows")


def _landmark_ids(f: _File, lm) -> list:
    """The landmark axis: ``landmark_order`` (ids never observed dropped) or first appearance."""
    order = f.meta.get("landmark_order")
    seen_ids = list(dict.fromkeys(lm.tolist()))
    if order is None:
        return seen_ids
    if not isinstance(order, list):
        raise f.err(f"metadata 'landmark_order' must be a list of ids, got {order!r}")
    order = [str(k) for k in order]
    if len(set(order)) != len(order):
        dup = next(k for k in order if order.count(k) > 1)
        raise f.err(f"metadata 'landmark_order' lists id {dup!r} twice")
    listed = set(order)
    missing = [k for k in seen_ids if k not in listed]
    if missing:
        raise f.err(f"column 'landmark': id {missing[0]!r} not in metadata landmark_order")
    # DECISION: an id listed but never observed is accepted and dropped: nothing in the file
    # gives its position, and a catalogue longer than what was seen is normal.
    present = set(seen_ids)
    return [k for k in order if k in present]


class _Index:
    """Row → (run, image, landmark) indices, the sizes R, N, M and K (rows per run), and the
    canonical order: ``order`` (R·K,) lists the file rows sorted by (run, image, landmark), so
    ``values[order].reshape(R, K, ...)`` is a column in the row model's layout. Nothing here
    has an images × landmarks axis pair: memory is O(file rows)."""

    def __init__(self, f: _File):
        self.run = f.col("run", int) if f.has("run") else np.zeros(f.n, np.int64)
        self.image = f.col("image", int)
        self.pas = f.col("pass", int) if f.has("pass") else np.zeros(f.n, np.int64)
        runs = np.unique(self.run)
        if not np.array_equal(runs, np.arange(runs.size)):
            raise f.err(f"column 'run' must number runs 0..R-1, got {runs.tolist()[:10]}")
        try:
            self.lm = np.asarray(f.tab["landmark"]).astype(str)
        except (TypeError, ValueError):
            raise f.err(f"column 'landmark': ids must be strings, got values of type {f.tab['landmark'].dtype}") from None
        ids = _landmark_ids(f, self.lm)
        self.ids = np.asarray(ids, dtype=str)
        pos = {k: i for i, k in enumerate(ids)}
        self.m = np.array([pos[k] for k in self.lm.tolist()], np.int64)
        self.R, self.N, self.M = runs.size, int(self.image.max()) + 1, self.ids.size
        self._kinds(f)
        self.order = np.lexsort((self.m, self.image, self.run))  # stable: duplicates keep file order
        srun, simg, slm = self.run[self.order], self.image[self.order], self.m[self.order]
        same = (srun[1:] == srun[:-1]) & (simg[1:] == simg[:-1]) & (slm[1:] == slm[:-1])
        if np.any(same):
            k = int(np.argmax(same))
            rows = sorted((int(self.order[k]), int(self.order[k + 1])))
            raise f.err(
                f"duplicate observation of landmark {str(self.lm[rows[0]])!r} in image {self.image[rows[0]]} "
                f"run {self.run[rows[0]]} (rows {rows[0]} and {rows[1]})"
            )
        # every run has every image 0..N-1: R·N distinct (run, image) keys (R·N ≤ rows, never a grid)
        seen = np.unique(self.run * self.N + self.image)
        if seen.size != self.R * self.N:
            gap = np.nonzero(seen != np.arange(seen.size))[0]
            missing = int(gap[0]) if gap.size else int(seen.size)
            rr, nn = divmod(missing, self.N)
            raise f.err(f"column 'image': run {rr} has no rows for image {nn} (images must be numbered 0..N-1 in every run)")
        counts = np.bincount(srun, minlength=self.R)
        if np.any(counts != counts[0]):
            raise f.err("every run must observe the same (image, landmark) pairs")
        self.K = int(counts[0])
        self.image_index = simg[: self.K]
        self.target_index = slm[: self.K]
        if self.R > 1 and not (
            np.all(simg.reshape(self.R, self.K) == self.image_index) and np.all(slm.reshape(self.R, self.K) == self.target_index)
        ):
            raise f.err("every run must observe the same (image, landmark) pairs")

    def _kinds(self, f: _File) -> None:
        """``kind_rows`` (file rows) and ``kinds`` (M,): each target's kind, the same on all its rows (format 1.2)."""
        if not f.has("kind"):
            self.kind_rows = np.full(f.n, "landmark")
            self.kinds = np.full(self.M, "landmark")
            return
        c = f.tab["kind"]
        if hasattr(c, "mask") and np.any(c.mask):
            raise f.err(f"column 'kind' row {int(np.argmax(np.asarray(c.mask)))}: missing value")
        self.kind_rows = np.asarray(c).astype(str)
        bad = ~np.isin(self.kind_rows, TARGET_KINDS)
        if np.any(bad):
            row = int(np.argmax(bad))
            raise f.err(
                f"column 'kind' row {row}: {str(self.kind_rows[row])!r} is not a target kind (expected one of {TARGET_KINDS})"
            )
        self.kinds = np.full(self.M, "landmark")
        self.kinds[self.m] = self.kind_rows
        differ = self.kinds[self.m] != self.kind_rows
        if np.any(differ):
            row = int(np.argmax(differ))
            raise f.err(f"column 'kind' row {row}: target {str(self.lm[row])!r} has differing kinds on its rows")

    def rows(self, values) -> np.ndarray:
        """Row values (file order, (n, ...)) in the row model's layout (R, K, ...)."""
        return values[self.order].reshape((self.R, self.K) + values.shape[1:])

    def row_of(self, r, n, m=None) -> int:
        sel = (self.run == r) & (self.image == n)
        if m is not None:
            sel &= self.m == m
        return int(np.nonzero(sel)[0][0])

    def file_row(self, r, k) -> int:
        """The file row of run ``r``'s canonical row ``k``."""
        return int(self.order[r * self.K + k])

    def per_image(self, f: _File, values, name) -> np.ndarray:
        """Scatter row values to (R, N, ...); every row of an image must carry the same value."""
        out = np.full((self.R, self.N) + values.shape[1:], np.nan)
        out[self.run, self.image] = values
        diff = np.any(out[self.run, self.image] != values, axis=tuple(range(1, values.ndim)))
        if np.any(diff):
            row = int(np.argmax(diff))
            raise f.err(f"column {name!r} row {row}: image {self.image[row]} has differing values on its rows")
        return out


def _utc(f: _File, values, what: str):
    from astropy.time import Time

    try:
        return Time(values, scale="utc")
    except Exception:  # astropy raises ValueError, TypeError and its own kinds for bad times
        shown = values if np.ndim(values) == 0 else np.asarray(values).ravel()[0]
        raise f.err(f"{what} is not an ISO UTC time, got {shown!r} (e.g. '2026-03-01T10:00:00.000')") from None


def _times(f: _File, ix: _Index):
    """Image times (N,) in s from the epoch, and the epoch."""
    epoch = f.meta.get("epoch_utc")
    if epoch is not None and not isinstance(epoch, str):
        raise f.err(f"metadata 'epoch_utc' must be an ISO UTC time string, got {epoch!r}")
    if epoch is not None:
        _utc(f, epoch, "metadata 'epoch_utc'")
    if f.has("t"):
        if epoch is None:
            raise f.err("column 't' needs the metadata 'epoch_utc'")
        t_row = f.col("t")
    else:
        times = _utc(f, np.asarray(f.tab["time_utc"], dtype=str), "column 'time_utc'")
        epoch = epoch or times[0].isot
        t_row = (times - _utc(f, epoch, "metadata 'epoch_utc'")).sec
    t_img = ix.per_image(f, t_row[:, None], "t" if f.has("t") else "time_utc")[..., 0]
    if not np.all(t_img == t_img[:1]):
        rr, nn = np.argwhere(t_img != t_img[:1])[0]
        raise f.err(
            f"column 't' row {ix.row_of(rr, nn)}: image {nn} of run {rr} has another time than in run 0 (image times are the same in every run)"
        )
    return t_img[0], str(epoch)


def _attitude_position(f: _File, ix: _Index):
    """Quaternions (R, N, 4) of unit norm, positions (R, N, 3), velocities (R, N, 3) or None."""
    q = ix.per_image(f, np.stack([f.col(f"q{k}") for k in (1, 2, 3, 4)], -1), "q1..q4")
    norms = np.linalg.norm(q, axis=-1)
    if np.any(np.abs(norms - 1) > 1e-6):
        rr, nn = np.argwhere(np.abs(norms - 1) > 1e-6)[0]
        raise f.err(f"columns 'q1..q4' row {ix.row_of(rr, nn)}: quaternion norm {norms[rr, nn]:.9g}, expected 1")
    r = ix.per_image(f, np.stack([f.col(f"r_{a}") for a in "xyz"], -1), "r_x..r_z")
    v = None
    if f.has("v_x"):
        v = ix.per_image(f, np.stack([f.col(f"v_{a}") for a in "xyz"], -1), "v_x..v_z")
    return q, r, v


def _earth_rotation(f: _File, ix: _Index, t_s, epoch):
    """C_GI (N, 3, 3) from the cgi columns (a proper rotation) or from astropy."""
    present = [c for c in _CGI_COLS if f.has(c)]
    if present and len(present) != 9:
        raise f.err(f"columns cgi11..cgi33 must be all present or all absent, found only {present}")
    if not present:
        frames = f.meta.get("frames") or {"inertial": "GCRS", "earth_fixed": "ITRS"}
        if not isinstance(frames, dict) or frames.get("inertial") != "GCRS" or frames.get("earth_fixed") != "ITRS":
            raise f.err(
                f"columns cgi11..cgi33 are required: metadata 'frames' = {frames!r} is not {{inertial: GCRS, earth_fixed: ITRS}}, "
                "so C_GI cannot be computed with astropy (a spherical-Earth simulation carries its own Earth rotation)"
            )
        from astropy import units as u
        from astropy.time import Time

        from orbits.earth import itrs_to_gcrs_dcm

        return itrs_to_gcrs_dcm(Time(epoch, scale="utc") + t_s * u.s)
    per_run = ix.per_image(f, np.stack([f.col(c) for c in _CGI_COLS], -1), "cgi11..cgi33")
    differ = np.any(per_run != per_run[:1], axis=-1)
    if np.any(differ):  # C_GI is one Earth rotation per image time, the same in every run
        rr, nn = np.argwhere(differ)[0]
        raise f.err(
            f"columns 'cgi11..cgi33' row {ix.row_of(rr, nn)}: image {nn} of run {rr} has another Earth rotation than in run 0 "
            "(C_GI depends only on the image time)"
        )
    C_GI = per_run[0].reshape(-1, 3, 3)
    bad = rotation_problem(C_GI)
    if bad is not None:
        k, what = bad
        raise f.err(f"columns 'cgi11..cgi33' row {ix.row_of(0, k)}: image {k}: {what}")
    return C_GI


def _landmarks(f: _File, ix: _Index):
    """Catalogue positions (R, M, 3) (NaN for a star); every row of a landmark (per run) must agree."""
    on = ix.kind_rows == "landmark"
    lmk = np.stack([f.col(a, rows=on) for a in "XYZ"], -1)
    L = np.full((ix.R, ix.M, 3), np.nan)
    L[ix.run[on], ix.m[on]] = lmk[on]
    diff = np.any(L[ix.run, ix.m] != lmk, axis=-1) & on
    if np.any(diff):
        row = int(np.argmax(diff))
        raise f.err(f"columns 'X, Y, Z' row {row}: landmark {str(ix.lm[row])!r} has differing catalogue positions")
    return L


def _stars(f: _File, ix: _Index):
    """The star targets' astrometry (format 1.2) as a ``StarCatalogue`` in target order, or None;
    every row of a star must carry the same values."""
    star_rows = ix.kind_rows == "star"
    if not star_rows.any():
        return None
    for name in list(_STAR_COLS) + ["rv"]:
        if name != "rv" and not f.has(name):
            raise f.err(
                f"missing column {name!r}: star rows (kind 'star') need hip, ra, dec, parallax, pm_ra_cosdec, pm_dec, mag"
            )
    values = {name: f.col(name, rows=star_rows) for name in list(_STAR_COLS) + (["rv"] if f.has("rv") else [])}
    hip = values["hip"]
    frac = star_rows & (hip != np.round(hip))
    if np.any(frac):
        row = int(np.argmax(frac))
        raise f.err(f"column 'hip' row {row}: {hip[row]!r} is not a whole number")
    star_targets = np.flatnonzero(ix.kinds == "star")
    first_row = np.full(ix.M, -1)
    first_row[ix.m[star_rows][::-1]] = np.flatnonzero(star_rows)[::-1]
    rows0 = first_row[star_targets]
    for name, v in values.items():
        differ = star_rows & (v != v[first_row[ix.m]])
        if np.any(differ):
            row = int(np.argmax(differ))
            raise f.err(f"column {name!r} row {row}: star {str(ix.lm[row])!r} has differing values on its rows")
    epoch = f.meta.get("star_epoch_jd_tt")
    from orbits.star_catalogue import HIPPARCOS_EPOCH_JD_TT, StarCatalogue, StarCatalogueError

    if epoch is not None and (isinstance(epoch, bool) or not isinstance(epoch, (int, float)) or not np.isfinite(epoch)):
        raise f.err(f"metadata 'star_epoch_jd_tt' must be a Julian date (TT), got {epoch!r}")
    try:
        return StarCatalogue.from_arrays(
            **{arg: values[col][rows0] for col, arg in _STAR_COLS.items() if col != "hip"},
            hip=values["hip"][rows0].astype(np.int64),
            radial_velocity_km_s=values["rv"][rows0] if "rv" in values else 0.0,
            epoch_jd_tt=HIPPARCOS_EPOCH_JD_TT if epoch is None else float(epoch),
            source=str(f.meta.get("star_catalogue", f"{f.path.name}")),
        )
    except StarCatalogueError as exc:
        raise f.err(f"star columns: {exc}") from None


def _camera(f: _File, focal):
    """The ``camera`` metadata block as an ``orbits.camera.CameraCalibration`` (or None)."""
    block = f.meta.get("camera")
    if block is None:
        return None
    from orbits.camera import CameraCalibration

    if not isinstance(block, dict):
        raise f.err(f"metadata 'camera' must be a mapping of calibration keys, got {block!r}")
    try:
        cam = CameraCalibration.from_mapping(block, where="metadata 'camera'", focal_length_m=focal)
    except ValueError as exc:
        raise f.err(str(exc)) from None
    return cam


def _image_points(f: _File, ix: _Index, cam):
    """Measured points (R, K, 2) on the ideal focal plane (m): x y as given, or u v undistorted."""
    if f.has("x"):
        return ix.rows(np.stack([f.col("x"), f.col("y")], -1))
    if cam is None:
        raise f.err("columns 'u v' (pixels) need the metadata 'camera' (the calibration that maps pixels to the focal plane)")
    uv = np.stack([f.col("u"), f.col("v")], -1)
    try:
        return ix.rows(cam.pixels_to_focal_plane(uv))
    except ValueError as exc:
        raise f.err(f"columns 'u v': {exc}") from None


def _row_sigma(f: _File, ix: _Index):
    """Format 1.3: each row's own σ (K, 2) in m from ``sigma_x sigma_y``, NaN (or an empty cell) where the
    noise model's pixel σ applies; None without the columns. Checked naming the column and row: both
    NaN or both given on a row, a given σ in ``SIGMA_XY_LIMITS_M``, the same σ in every run of a row."""
    if not f.has("sigma_x"):
        return None
    lo, hi = SIGMA_XY_LIMITS_M
    cols = []
    for name in ("sigma_x", "sigma_y"):
        c = f.tab[name]
        try:
            raw = np.asarray(c.filled(np.nan) if hasattr(c, "mask") else c, dtype=float)
        except (TypeError, ValueError):
            raise f.err(f"column {name!r}: values are not numbers (e.g. row 0: {str(np.asarray(c)[0])!r})") from None
        a = f.col(name, rows=~np.isnan(raw))  # unit converted; ±inf refused with its row
        bad = ~np.isnan(a) & ~((a >= lo) & (a <= hi))
        if np.any(bad):
            row = int(np.argmax(bad))
            raise f.err(
                f"column {name!r} row {row}: σ {float(a[row]):.6g} m is outside [{lo:g}, {hi:g}] m "
                "(a row's own pixel σ; NaN for the noise model's)"
            )
        cols.append(a)
    s = np.stack(cols, -1)
    half = np.isnan(s[:, 0]) != np.isnan(s[:, 1])
    if np.any(half):
        row = int(np.argmax(half))
        raise f.err(f"columns 'sigma_x sigma_y' row {row}: one is NaN and the other not (both NaN: the noise model's σ)")
    per_run = ix.rows(s)  # (R, K, 2)
    same = (per_run == per_run[:1]) | (np.isnan(per_run) & np.isnan(per_run[:1]))
    if not np.all(same):
        run, k, axis = (int(i) for i in np.argwhere(~same)[0])
        raise f.err(
            f"column {('sigma_x', 'sigma_y')[axis]!r} row {ix.file_row(run, k)}: differs from run 0's "
            f"(row {ix.file_row(0, k)}); a row's σ is the same in every run"
        )
    out: np.ndarray = per_run[0]
    return out


def _check_geometry(f: _File, ix: _Index, q, r, C_GI, L, C_SK, xy, focal, stars=None):
    """The shared plausibility check (``observations.geometry_problem``), located to a row."""
    from boresight.observations.model import geometry_problem

    bad = geometry_problem(
        q,
        r,
        C_GI,
        L,
        C_SK,
        ix.image_index,
        ix.target_index,
        xy,
        focal,
        f.meta.get("fov_deg"),
        star_directions_i=catalogue_directions(ix.kinds, stars),
    )
    if bad is None:
        return
    row = ix.file_row(bad.run, bad.row)
    if bad.kind == "behind":
        raise f.err(f"row {row}: {bad.describe(ix.ids)}")
    col = ("x", "y") if f.has("x") else ("u", "v")
    raise f.err(f"column {col[bad.axis]!r} row {row}: {bad.describe(ix.ids)}")


def _nominal_mount(f: _File):
    raw = f.meta.get("C_SK_nominal", np.eye(3).tolist())
    try:
        C_SK = np.asarray(raw, float)
    except (TypeError, ValueError):
        C_SK = np.full(1, np.nan)
    if C_SK.shape != (3, 3) or not np.all(np.isfinite(C_SK)):
        raise f.err(f"metadata 'C_SK_nominal' must be a 3×3 rotation matrix, got {raw!r}")
    bad = rotation_problem(C_SK[None])
    if bad is not None:
        raise f.err(f"metadata 'C_SK_nominal' is {bad[1]}: {raw!r}")
    return C_SK


def read_ecsv(path, geometry_checks: bool = True) -> ObservationSet:
    """Read and validate an observation file (format 1.0 to 1.4; ECSV, or Parquet for a ``.parquet``
    path). Errors name the file, the column or key, the row (0-based data row) and the value.

    ``geometry_checks=False`` skips the behind-the-camera and field-of-view tests (the convention
    doctor, ``boresight.observations.doctor``, reads a file that fails them to say which convention is wrong)."""
    f = _load(path)
    focal = _check_meta(f)
    _check_columns(f)
    ix = _Index(f)
    t_s, epoch = _times(f, ix)
    q, r, v = _attitude_position(f, ix)
    C_GI = _earth_rotation(f, ix, t_s, epoch)
    L = _landmarks(f, ix)
    stars = _stars(f, ix)
    cam = _camera(f, focal)
    xy = _image_points(f, ix, cam)
    sigma_xy = _row_sigma(f, ix)
    C_SK = _nominal_mount(f)
    if geometry_checks:
        _check_geometry(f, ix, q, r, C_GI, L, C_SK, xy, focal, stars)
    noise = f.meta.get("noise")
    if noise is not None:
        noise = normalize_noise(noise, f"{f.path}: metadata 'noise'", ObservationFileError)
    p_img = ix.per_image(f, ix.pas[:, None].astype(float), "pass")[0, :, 0]
    truth: dict[str, Any] | None = None
    if "truth_theta_rad" in f.meta:
        try:
            truth = {"theta_rad": np.asarray(f.meta["truth_theta_rad"], float).reshape(ix.R, 3)}
        except (TypeError, ValueError):
            raise f.err(
                f"metadata 'truth_theta_rad' must be {ix.R} × 3 numbers (rad), got {f.meta['truth_theta_rad']!r}"
            ) from None
    if truth is not None and isinstance(f.meta.get("truth_effects"), dict):
        try:
            truth["effects"] = {str(k): np.asarray(v, float) for k, v in f.meta["truth_effects"].items()}
        except (TypeError, ValueError):
            raise f.err(f"metadata 'truth_effects' must map effect names to numbers, got {f.meta['truth_effects']!r}") from None
    frames = f.meta.get("frames") or {"inertial": "GCRS", "earth_fixed": "ITRS"}
    if not isinstance(frames, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in frames.items()):
        raise f.err(
            f"metadata 'frames' must map frame roles to names, e.g. {{inertial: GCRS, earth_fixed: ITRS}}, got {frames!r}"
        )
    pitch = f.meta.get("pixel_pitch_m")
    if pitch is not None and (
        isinstance(pitch, bool) or not isinstance(pitch, (int, float)) or not (np.isfinite(pitch) and pitch > 0)
    ):
        raise f.err(f"metadata 'pixel_pitch_m' must be a positive number, got {pitch!r}")
    try:
        return ObservationSet(
            t_s=t_s,
            pass_index=p_img.astype(int),
            q_is=q,
            r_sc_i_m=r,
            C_GI=C_GI,
            landmark_ids=ix.ids,
            landmark_g_m=L,
            image_index=ix.image_index,
            target_index=ix.target_index,
            xy_m=xy,
            focal_length_m=focal,
            C_SK_nominal=C_SK,
            fov_deg=f.meta.get("fov_deg"),
            pixel_pitch_m=pitch,
            epoch_utc=epoch,
            frames=dict(frames),
            truth=truth,
            v_sc_i_m_s=v,
            noise=noise,
            camera=cam,
            target_kind=ix.kinds,
            stars=stars,
            check_geometry=geometry_checks,
            sigma_xy_m=sigma_xy,
            landmark_sight=f.meta.get("landmark_sight", "geometric"),
        )
    except ObservationFileError:
        raise
    except ObservationError as exc:  # what the shared in-memory checks found, located to this file
        raise f.err(str(exc).removeprefix("ObservationSet").lstrip(".: ")) from None


# ObservationSet.write / .read use this format (the model does not import it: see model.FILE_FORMAT)
_model.FILE_FORMAT.update(write=write_ecsv, read=read_ecsv)
