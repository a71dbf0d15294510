"""The pushbroom observation file: one strip's detections and everything its lines are dated, placed and pointed with.

A frame camera's observation file (``observations/ecsv.py``) carries each image's attitude and position; a pushbroom
line has neither of its own — it interpolates the star tracker's samples and the orbit's (``docs/pushbroom.md``, "The
estimator on rows") — so the file carries the samples instead, and the reader rebuilds the ``ObservationSet`` of
lines exactly as the simulator and the flight readers build it (``orbits.strip.line_records``). One ECSV table
(astropy, every float written with all its digits), ``docs/data-format.md`` "The pushbroom observation file":

* **columns**, one row per detection: ``gcp`` (the ground-control point's id), ``chip``, ``line`` (fractional
  line), ``pixel`` (fractional column on the whole detector line), ``x_g_m``, ``y_g_m``, ``z_g_m`` (the point,
  ITRS, m);
* **meta** ``boresight_pushbroom`` (the format version) and ``pushbroom``: ``epoch_utc`` (τ = 0, UTC ISO);
  ``sensor`` (``focal_length_m``, ``pixel_pitch_m``, ``chips``: each ``n_pixels`` and its look-angle polynomials
  ``tan_psi_x``, ``tan_psi_y`` or a ``table_tan_psi`` (n, 2)); ``datation`` (``linear``: ``reference_line``,
  ``reference_time_s``, ``line_period_s``; or ``table``: ``lines``, ``times_s``); ``C_ES`` (the tracker mount, body →
  tracker: C_SK,nom = C_ESᵀ); ``orbit`` (``t_s``, ``r_i_m``, ``v_i_m_s`` GCRS, Lagrange ``degree``); ``tracker``
  (``t_s``, ``quat`` GCRS → star tracker, scalar last: the *measured* samples); ``earth`` (``t_s``, ``C_GI`` ITRS →
  GCRS samples, SLERPed between); ``light_time``, ``aberration``; optionally ``noise`` (``sigma_pixel_px`` on line
  and column, ``sigma_star_tracker_arcsec`` white per sample, and the tracker's Gauss–Markov error
  ``star_tracker_correlated_arcsec`` with its ``correlation_time_s``, default 30 s) and ``estimate`` (the unknowns floated besides θ, as a
  pushbroom scenario's ``[estimate]``). A simulated strip adds its truth (``scenario``, ``seed``,
  ``theta_arcsec``, ``effects``).

DECISION: the Earth-orientation samples are written, not recomputed by the reader: astropy's ITRS → GCRS takes ~2 s
a strip, and a file read back gives the lines the very matrices they were assembled with (the round trip is exact).
DECISION: one strip per file; a campaign is several files (``diagnose`` takes several).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from boresight.errors import ObservationError
from boresight.observations.model import ObservationSet
from boresight.observations.validation import first_outside

__all__ = [
    "FORMAT_VERSION",
    "is_strip_file",
    "write_strip_file",
    "read_strip_file",
    "strip_file_model",
    "noise_mapping",
    "StripFile",
]

FORMAT_VERSION = "1.0"
_MARK = "boresight_pushbroom"
_COLUMNS = ("gcp", "chip", "line", "pixel", "x_g_m", "y_g_m", "z_g_m")
_ARCSEC = np.pi / 180.0 / 3600.0


def is_strip_file(path: Any) -> bool:
    """True when ``path`` is an ECSV file whose header declares a pushbroom observation file (the header alone is read)."""
    p = Path(str(path))
    if p.suffix.lower() != ".ecsv" or not p.is_file():
        return False
    try:
        with open(p, encoding="utf-8") as f:
            for ln in f:
                if not ln.startswith("#"):
                    return False
                if f"{_MARK}:" in ln:
                    return True
    except (OSError, UnicodeDecodeError):
        return False
    return False


def _sensor_meta(sensor: Any) -> dict[str, Any]:
    chips = []
    for c in sensor.chips:
        if c.table_tan_psi is None:
            chips.append(
                dict(
                    n_pixels=int(c.n_pixels), tan_psi_x=[float(a) for a in c.tan_psi_x], tan_psi_y=[float(a) for a in c.tan_psi_y]
                )
            )
        else:
            chips.append(dict(n_pixels=int(c.n_pixels), table_tan_psi=np.asarray(c.table_tan_psi, float).tolist()))
    return dict(
        focal_length_m=float(sensor.focal_length_m),
        pixel_pitch_m=None if sensor.pixel_pitch_m is None else float(sensor.pixel_pitch_m),
        chips=chips,
    )


def _datation_meta(datation: Any) -> dict[str, Any]:
    from orbits.camera import LinearLineDatation

    if isinstance(datation, LinearLineDatation):
        return dict(
            kind="linear",
            reference_line=float(datation.reference_line),
            reference_time_s=float(datation.reference_time_s),
            line_period_s=float(datation.line_period_s),
        )
    return dict(
        kind="table", lines=np.asarray(datation.lines, float).tolist(), times_s=np.asarray(datation.times_s, float).tolist()
    )


def write_strip_file(
    obs: ObservationSet,
    path: Any,
    noise: dict[str, float] | None = None,
    estimate: dict[str, Any] | None = None,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Write a strip's ``ObservationSet`` of lines (one run; ``boresight.observations.strip`` or the flight readers) as a
    pushbroom observation file (module docstring), atomically. ``noise``: ``sigma_pixel_px``,
    ``sigma_star_tracker_arcsec``; ``estimate``: the scenario-style ``[estimate]`` table; ``extra``: more metadata
    (a simulation's truth)."""
    from astropy.table import Table

    from boresight.files import write_table

    ls = obs.line_scan
    if ls is None:
        raise ObservationError("write_strip_file: the set's images are not pushbroom lines (ObservationSet.line_scan is None)")
    if obs.runs != 1:
        raise ObservationError(f"write_strip_file: one run per file, got {obs.runs} runs")
    img = np.asarray(obs.image_index)
    g = obs.landmark_g_m[0, obs.target_index]
    table = Table(
        dict(
            gcp=np.asarray(obs.landmark_ids)[obs.target_index],
            chip=np.asarray(ls.chip, np.int64)[img],
            line=np.asarray(ls.line, float)[img],
            pixel=np.asarray(ls.pixel, float)[img],
            x_g_m=g[:, 0],
            y_g_m=g[:, 1],
            z_g_m=g[:, 2],
        )
    )
    tr = ls.trajectory
    meta: dict[str, Any] = dict(
        epoch_utc=str(obs.epoch_utc),
        sensor=_sensor_meta(ls.sensor),
        datation=_datation_meta(ls.datation),
        C_ES=np.asarray(tr.C_ES, float).tolist(),
        orbit=dict(
            t_s=np.asarray(tr.orbit_t_s).tolist(),
            r_i_m=np.asarray(tr.orbit_r_i_m).tolist(),
            v_i_m_s=np.asarray(tr.orbit_v_i_m_s).tolist(),
            degree=int(tr.orbit_degree),
        ),
        tracker=dict(t_s=np.asarray(tr.tracker_t_s).tolist(), quat=np.asarray(tr.tracker_quat).tolist()),
        earth=dict(t_s=np.asarray(tr.earth_t_s).tolist(), C_GI=np.asarray(tr.earth_C_GI).tolist()),
        light_time=bool(ls.light_time),
        aberration=bool(ls.aberration),
    )
    if noise:
        meta["noise"] = {k: float(v) for k, v in noise.items()}
    if estimate:
        meta["estimate"] = dict(estimate)
    table.meta[_MARK] = FORMAT_VERSION
    table.meta["pushbroom"] = meta
    for k, v in (extra or {}).items():
        table.meta[k] = v
    return write_table(table, path)


class StripFile:
    """A pushbroom observation file read back: ``obs`` (the ``ObservationSet`` of lines), ``noise`` and ``estimate``
    (dicts, possibly empty) and ``meta`` (the file's whole metadata)."""

    def __init__(self, path: Path, obs: ObservationSet, noise: dict[str, float], estimate: dict[str, Any], meta: dict[str, Any]):
        self.path, self.obs, self.noise, self.estimate, self.meta = path, obs, noise, estimate, meta


def _need(d: Any, key: str, where: str) -> Any:
    if not isinstance(d, dict) or key not in d:
        raise ObservationError(
            f"{where}: metadata key {key!r} is missing (docs/data-format.md, 'The pushbroom observation file')"
        )
    return d[key]


def _sensor(m: Any, where: str) -> Any:
    from orbits.camera import LineChip, LineSensor

    chips = []
    raw = _need(m, "chips", where)
    if not isinstance(raw, list) or not raw:
        raise ObservationError(f"{where}: sensor 'chips' must be a non-empty list of chips, got {raw!r}")
    for c, ch in enumerate(raw):
        w = f"{where}: sensor chip {c}"
        n = _need(ch, "n_pixels", w)
        try:
            if "table_tan_psi" in ch:
                chips.append(LineChip(int(n), table_tan_psi=np.asarray(ch["table_tan_psi"], float)))
            else:
                chips.append(LineChip(int(n), tuple(ch.get("tan_psi_x", (0.0,))), tuple(ch.get("tan_psi_y", (0.0,)))))
        except (TypeError, ValueError) as exc:
            raise ObservationError(f"{w}: {exc}") from exc
    F = _need(m, "focal_length_m", where)
    try:
        return LineSensor(float(F), tuple(chips), m.get("pixel_pitch_m"))
    except (TypeError, ValueError) as exc:
        raise ObservationError(f"{where}: sensor: {exc}") from exc


def _datation(m: Any, where: str) -> Any:
    from orbits.camera import LinearLineDatation, TabulatedLineDatation

    kind = _need(m, "kind", where)
    try:
        if kind == "linear":
            return LinearLineDatation(
                float(_need(m, "reference_line", where)),
                float(_need(m, "reference_time_s", where)),
                float(_need(m, "line_period_s", where)),
            )
        if kind == "table":
            return TabulatedLineDatation(
                np.asarray(_need(m, "lines", where), float), np.asarray(_need(m, "times_s", where), float)
            )
    except (TypeError, ValueError) as exc:
        raise ObservationError(f"{where}: datation: {exc}") from exc
    raise ObservationError(f"{where}: datation kind {kind!r}: 'linear' or 'table'")


def _trajectory(m: dict[str, Any], where: str) -> Any:
    from orbits.pushbroom import StripTrajectory

    orbit, tracker, earth = (_need(m, k, where) for k in ("orbit", "tracker", "earth"))
    try:
        return StripTrajectory(
            np.asarray(_need(orbit, "t_s", where + ": orbit"), float),
            np.asarray(_need(orbit, "r_i_m", where + ": orbit"), float),
            np.asarray(_need(orbit, "v_i_m_s", where + ": orbit"), float),
            np.asarray(_need(tracker, "t_s", where + ": tracker"), float),
            np.asarray(_need(tracker, "quat", where + ": tracker"), float),
            np.asarray(_need(m, "C_ES", where), float),
            np.asarray(_need(earth, "t_s", where + ": earth"), float),
            np.asarray(_need(earth, "C_GI", where + ": earth"), float),
            int(orbit.get("degree", 7)),
        )
    except (TypeError, ValueError) as exc:
        raise ObservationError(f"{where}: trajectory samples: {exc}") from exc


def _numbers(path: Any, table: Any) -> dict[str, np.ndarray]:
    """The numeric columns as finite float arrays; a value that is not a number, or not finite, is refused naming the
    file, the column, the row (1-based, as in the file) and the value."""
    if len(table) == 0:
        raise ObservationError(f"{path}: no detections (the table has no rows)")
    out = {}
    for name in _COLUMNS[1:]:
        col = np.asarray(table[name])
        try:
            v = col.astype(float)
        except (TypeError, ValueError):
            k = next(i for i, x in enumerate(col) if not _is_number(x))
            raise ObservationError(f"{path}: column {name!r} row {k + 1}: {str(col[k])!r} is not a number") from None
        bad = ~np.isfinite(v)
        if np.any(bad):
            k = int(np.argmax(bad))
            raise ObservationError(f"{path}: column {name!r} row {k + 1}: non-finite value {float(v[k])!r}")
        out[name] = v
    return out


def _is_number(x: Any) -> bool:
    try:
        float(x)
    except (TypeError, ValueError):
        return False
    return True


def _check_rows(path: Any, cols: dict[str, np.ndarray], sensor: Any, datation: Any, traj: Any) -> None:
    """Each row's chip a chip of the sensor, its pixel a column of that chip, its line's time inside the samples:
    a refusal names the file, the column, the row (1-based, as in the file) and the value."""
    from orbits.pushbroom import LineScanParameters, line_time_s

    chip = cols["chip"]
    bad = (chip < 0) | (chip >= sensor.n_chips) | (chip != np.round(chip))
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ObservationError(
            f"{path}: column 'chip' row {k + 1}: {int(chip[k]) if chip[k] == round(chip[k]) else float(chip[k])!r} is not a chip of the sensor (0 … {sensor.n_chips - 1})"
        )
    pixel = cols["pixel"]
    first = sensor.chip_start
    lo, hi = first[chip.astype(int)] - 0.5, first[chip.astype(int) + 1] - 0.5
    row = first_outside(pixel, lo, hi)
    if row is not None:
        raise ObservationError(
            f"{path}: column 'pixel' row {row + 1}: {float(pixel[row])!r} is not a column of chip {int(chip[row])} ({lo[row] + 0.5:g} … {hi[row] - 0.5:g})"
        )
    line = cols["line"]
    t = line_time_s(datation, line, LineScanParameters())
    t0, t1 = traj.span_s
    row = first_outside(t, t0, t1)
    if row is not None:
        raise ObservationError(
            f"{path}: column 'line' row {row + 1}: line {float(line[row])!r} is dated {t[row]:.6f} s, outside the orbit, tracker and Earth "
            f"samples ({t0:.6f} … {t1:.6f} s from the epoch)"
        )


def read_strip_file(path: Any, geometry_checks: bool = True) -> StripFile:
    """Read a pushbroom observation file (module docstring) into the ``ObservationSet`` of its lines; a missing column
    or key, a chip the sensor does not have, a pixel off its chip or a line dated outside the samples is an
    ``ObservationError`` naming the file, the column and the row. ``geometry_checks=False`` skips the set's
    behind-the-camera test (``boresight check``: the convention doctor names the slip instead)."""
    from astropy.table import Table

    from orbits.strip import line_records

    p = Path(str(path))
    if not p.exists():
        raise FileNotFoundError(f"no such observation file: {p}")
    if p.is_file():  # the memory budget before reading, with the observation file's estimate (ecsv.read_bytes)
        from boresight.observations.ecsv import read_bytes
        from orbits.limits import check_memory

        check_memory(
            f"reading {p} ({p.stat().st_size / 2**20:.3g} MiB on disk)", read_bytes(p), hint="split the strip into several files"
        )
    try:
        table = Table.read(p, format="ascii.ecsv")
    except Exception as exc:  # noqa: BLE001 - astropy raises many kinds for a malformed ECSV; one typed error names the file
        raise ObservationError(f"{p}: not a readable ECSV table: {exc}") from exc
    if table.meta.get(_MARK) != FORMAT_VERSION:
        raise ObservationError(
            f"{p}: not a pushbroom observation file of format {FORMAT_VERSION} (meta {_MARK!r} = {table.meta.get(_MARK)!r})"
        )
    missing = [c for c in _COLUMNS if c not in table.colnames]
    if missing:
        raise ObservationError(
            f"{p}: missing column(s) {', '.join(map(repr, missing))}; the file has {', '.join(table.colnames)}"
        )
    m = table.meta.get("pushbroom")
    where = f"{p}: meta 'pushbroom'"
    sensor = _sensor(_need(m, "sensor", where), where)
    datation = _datation(_need(m, "datation", where), where)
    traj = _trajectory(m, where)
    cols = _numbers(p, table)
    _check_rows(p, cols, sensor, datation, traj)
    ids_all = np.asarray(table["gcp"], dtype=str)
    g_all = np.stack([cols[c] for c in ("x_g_m", "y_g_m", "z_g_m")], axis=-1)
    ids, first, target_index = np.unique(ids_all, return_index=True, return_inverse=True)
    same = np.all(np.isclose(g_all, g_all[first][target_index], rtol=0, atol=1e-6), axis=-1)
    if not np.all(same):
        k = int(np.argmax(~same))
        raise ObservationError(
            f"{p}: columns 'x_g_m', 'y_g_m', 'z_g_m' row {k + 1}: GCP {str(ids_all[k])!r} is at {g_all[k].tolist()} here and at "
            f"{g_all[first[target_index[k]]].tolist()} on row {first[target_index[k]] + 1}"
        )
    chip = cols["chip"].astype(np.int64)
    rec = line_records(
        sensor,
        datation,
        traj,
        cols["line"],
        chip,
        cols["pixel"],
        target_index,
        ids,
        g_all[first],
        str(_need(m, "epoch_utc", where)),
        light_time=bool(m.get("light_time", True)),
        aberration=bool(m.get("aberration", True)),
    )
    noise = dict(m.get("noise") or {})
    obs = ObservationSet(**rec, noise=noise_mapping(noise, sensor), check_geometry=geometry_checks)
    return StripFile(p, obs, noise, dict(m.get("estimate") or {}), dict(table.meta))


def noise_mapping(noise: dict[str, float], sensor: Any) -> dict[str, Any] | None:
    """The ``ObservationSet.noise`` mapping of a file's ``noise`` (as ``boresight.observations.strip`` writes it)."""
    if not noise:
        return None
    return {
        "pixel": {"sigma_m": float(noise.get("sigma_pixel_px", 0.0)) * (sensor.pixel_pitch_m or 0.0)},
        "star_tracker": {"sigma_arcsec": [float(noise.get("sigma_star_tracker_arcsec", 0.0))] * 3, "error_mode": "per_image"},
        "gnss": {"sigma_m": 0.0, "error_mode": "per_pass"},
        "catalogue": {"sigma_m": 0.0},
    }


def strip_file_model(sf: StripFile, sigma_pixel_px: float | None = None, sigma_star_tracker_arcsec: float | None = None) -> Any:
    """The noise model of a pushbroom file (``boresight.observations.strip.line_noise_model``): the file's ``noise``,
    each σ replaced by the one given here; a pixel σ is needed (it weights the rows)."""
    from boresight.observations.strip import line_noise_model

    px = sf.noise.get("sigma_pixel_px") if sigma_pixel_px is None else sigma_pixel_px
    st = sf.noise.get("sigma_star_tracker_arcsec", 0.0) if sigma_star_tracker_arcsec is None else sigma_star_tracker_arcsec
    ls = sf.obs.line_scan
    if px is None:
        raise ObservationError(
            f"{sf.path}: no pixel σ in the file's noise model: give --sigma-pixel-px (σ on line and column, pixels)"
        )
    return line_noise_model(
        float(px),
        float(st),
        ls.sensor.pixel_pitch_m,
        str(sf.path),
        sigma_star_tracker_correlated_arcsec=float(sf.noise.get("star_tracker_correlated_arcsec", 0.0)),
        correlation_time_s=float(sf.noise.get("correlation_time_s", 30.0)),
    )
