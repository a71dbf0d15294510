"""Pushbroom flight data → a pushbroom observation file (``boresight ingest --line-detections``, ``docs/data-format.md``
"Pushbroom flight files").

Inputs: the orbit (CCSDS OEM, ``orbit.read_oem``), the star tracker's attitude at its own rate (CCSDS AEM,
``attitude.read_aem``: GCRS → star tracker, scalar last), the ground-control points (``landmarks.read_landmarks_csv``:
WGS84 or ITRS), the detections as (line, pixel) (``read_line_detections_csv``: ``landmark, chip, line, pixel``, the
pixel a column of the whole detector line) and the line sensor (``read_line_sensor_toml``: the focal length, the pixel
pitch, each chip's look-angle polynomials in its chip index, the datation law — a reference line, its UTC time and
the line period — or a table of (line, UTC time), the tracker mount ``[mount] C_SK_nominal``, light time and
aberration, and the unknowns to float besides θ, ``[estimate]``).

``assemble_strip`` dates every detection's line, checks it lies inside the samples of the AEM and of the OEM (and
inside a datation table), and builds the lines' ``ObservationSet`` the way the simulator does
(``orbits.strip.line_records``: one image per detection, its attitude the SLERP of the tracker's samples — the
attitude-sample table whose errors the GLS carries —, its position the OEM's Lagrange interpolation of the given
degree, the Earth's orientation astropy's ITRS → GCRS every second, SLERPed). ``export_strip_files`` writes a
simulated strip as these files (the round trip of the tests and the shipped example ``pushbroom-pass``).

DECISION: the OEM's samples are interpolated by Lagrange of its ``INTERPOLATION_DEGREE`` on positions and velocities
(``orbits.pushbroom.StripTrajectory``: the sensor model's own interpolation, as in the simulator); a HERMITE OEM is
read the same way and the report says so. DECISION: one OEM and one AEM segment: a strip lasts seconds; a file with
several segments is refused naming them (the lines would have to be split where the segments meet).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from boresight.observations.flight.common import IngestError
from boresight.observations.flight.tables import read_csv_columns
from boresight.observations.validation import first_outside

__all__ = [
    "LineSensorSpec",
    "read_line_sensor_toml",
    "read_line_detections_csv",
    "read_datation_csv",
    "assemble_strip",
    "export_strip_files",
]

_SENSOR_KEYS = {
    "": ("sensor", "chips", "datation", "mount", "model", "estimate"),
    "sensor": ("focal_length_m", "pixel_pitch_m"),
    "chips": ("n_pixels", "tan_psi_x", "tan_psi_y", "lines_of_sight"),
    "datation": ("reference_line", "reference_time_utc", "line_period_s", "table"),
    "model": ("light_time", "aberration"),
}


@dataclass(frozen=True)
class LineSensorSpec:
    """A line sensor TOML read: the ``sensor`` (``orbits.camera.LineSensor``), the datation — linear (``reference_line``,
    ``reference_time_utc``, ``line_period_s``) or a ``table`` path —, ``C_SK_nominal`` (3, 3) or None, ``light_time``,
    ``aberration``, ``estimate`` (a pushbroom scenario's ``[estimate]`` keys) and the file's ``source``."""

    sensor: Any
    reference_line: float | None
    reference_time_utc: str | None
    line_period_s: float | None
    table: Path | None
    C_SK_nominal: np.ndarray | None
    light_time: bool
    aberration: bool
    estimate: dict[str, Any]
    source: str


def _keys(d: Any, where: str, allowed: tuple[str, ...]) -> dict[str, Any]:
    from orbits.errors import checked_table

    return checked_table(d, where, allowed, IngestError)


def _number(d: dict[str, Any], key: str, where: str, positive: bool = False) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or (positive and not v > 0):
        raise IngestError(f"{where} {key} must be a {'positive ' if positive else ''}number, got {v!r}")
    return float(v)


def _chips(data: dict[str, Any], path: Any) -> tuple[Any, ...]:
    from orbits.camera import LineChip

    raw = data.get("chips")
    if not isinstance(raw, list) or not raw:
        raise IngestError(f"{path}: [[chips]]: at least one chip is needed (n_pixels, tan_psi_x, tan_psi_y)")
    chips = []
    for c, ch in enumerate(raw):
        where = f"{path}: [[chips]] {c}"
        ch = _keys(ch, where, _SENSOR_KEYS["chips"])
        if "lines_of_sight" in ch:
            chips.append(_table_chip(ch, Path(path), where))
            continue
        n = ch.get("n_pixels")
        if isinstance(n, bool) or not isinstance(n, int):
            raise IngestError(f"{where} n_pixels must be an integer ≥ 2, got {n!r}")
        try:
            chips.append(LineChip(n, tuple(ch.get("tan_psi_x", (0.0,))), tuple(ch.get("tan_psi_y", (0.0,)))))
        except (TypeError, ValueError) as exc:
            raise IngestError(f"{where}: {exc}") from exc
    return tuple(chips)


def _table_chip(ch: dict[str, Any], path: Path, where: str) -> Any:
    """A chip given as a table of lines of sight (Rugged's ``LineSensor``): ``lines_of_sight = "FILE.csv"`` (relative to
    the TOML) with columns ``x, y, z``, one K-frame direction per pixel in chip-index order (``LineChip.from_lines_of_sight``);
    ``n_pixels``, if given, must be its row count; no polynomial beside it."""
    from orbits.camera import LineChip

    if "tan_psi_x" in ch or "tan_psi_y" in ch:
        raise IngestError(f"{where}: give the look angles as tan_psi_x, tan_psi_y or as lines_of_sight, not both")
    los_path = path.parent / str(ch["lines_of_sight"])
    c = read_csv_columns(los_path, required=("x", "y", "z"))
    los = np.stack([c["x"], c["y"], c["z"]], axis=-1)
    n = ch.get("n_pixels", los.shape[0])
    if n != los.shape[0]:
        raise IngestError(f"{where} n_pixels = {n!r}, but {los_path} holds {los.shape[0]} lines of sight (one per pixel)")
    try:
        return LineChip.from_lines_of_sight(los)
    except ValueError as exc:
        raise IngestError(f"{los_path}: {exc}") from exc


def read_line_sensor_toml(path: Any) -> LineSensorSpec:
    """The line sensor of a pushbroom TOML (module docstring; ``docs/data-format.md``): every unknown table or key, a
    missing value or a law that is not monotonic across the chip is an ``IngestError`` naming the file and the key."""
    from boresight.observations.flight.pixels import read_mount_toml
    from orbits.camera import LineSensor

    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise IngestError(f"{path}: not a readable TOML line-sensor file: {exc}") from exc
    _keys(data, str(path), _SENSOR_KEYS[""])
    s = _keys(data.get("sensor"), f"{path}: [sensor]", _SENSOR_KEYS["sensor"])
    F = _number(s, "focal_length_m", f"{path}: [sensor]", positive=True)
    pitch = _number(s, "pixel_pitch_m", f"{path}: [sensor]", positive=True) if "pixel_pitch_m" in s else None
    chips = _chips(data, path)
    try:
        sensor = LineSensor(F, chips, pitch)
    except ValueError as exc:
        raise IngestError(f"{path}: [sensor]: {exc}") from exc
    d = _keys(data.get("datation"), f"{path}: [datation]", _SENSOR_KEYS["datation"])
    table = ref_line = ref_time = period = None
    if "table" in d:
        if len(d) != 1:
            raise IngestError(
                f"{path}: [datation]: give either table = FILE or reference_line, reference_time_utc and line_period_s"
            )
        table = Path(path).parent / str(d["table"])
    else:
        ref_line = _number(d, "reference_line", f"{path}: [datation]")
        period = _number(d, "line_period_s", f"{path}: [datation]", positive=True)
        ref_time = d.get("reference_time_utc")
        if not isinstance(ref_time, str):
            raise IngestError(f"{path}: [datation] reference_time_utc must be a UTC ISO time string, got {ref_time!r}")
    m = _keys(data.get("model", {}), f"{path}: [model]", _SENSOR_KEYS["model"])
    for k, v in m.items():
        if not isinstance(v, bool):
            raise IngestError(f"{path}: [model] {k} must be true or false, got {v!r}")
    est = data.get("estimate", {})
    if not isinstance(est, dict):
        raise IngestError(f"{path}: [estimate] must be a table, got {est!r}")
    return LineSensorSpec(
        sensor,
        ref_line,
        ref_time,
        period,
        table,
        read_mount_toml(path),
        m.get("light_time", True),
        m.get("aberration", True),
        dict(est),
        str(path),
    )


def read_line_detections_csv(path: Any) -> dict[str, Any]:
    """{'landmark': (D,) str, 'chip': (D,) int, 'line': (D,), 'pixel': (D,), 'source'} of a detection CSV with columns
    ``landmark, chip, line, pixel`` (fractional line and line column); a chip that is not an integer is refused
    naming the row."""
    c = read_csv_columns(path, required=("landmark", "chip", "line", "pixel"))
    chip = c["chip"]
    bad = chip != np.round(chip)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise IngestError(f"{path}: column 'chip' row {k + 1}: {float(chip[k])!r} is not a chip number (an integer)")
    return {"landmark": c["landmark"], "chip": chip.astype(np.int64), "line": c["line"], "pixel": c["pixel"], "source": str(path)}


def read_datation_csv(path: Any) -> tuple[np.ndarray, Any]:
    """(lines (L,), UTC ``Time`` (L,)) of a datation table with columns ``line, time_utc``, both strictly increasing."""
    from astropy.time import Time

    c = read_csv_columns(path, required=("line", "time_utc"))
    try:
        t = Time(list(c["time_utc"]), scale="utc")
    except ValueError as exc:
        raise IngestError(f"{path}: column 'time_utc': {exc}") from exc
    dt = (t[1:] - t[:-1]).to_value("s") if len(t) > 1 else np.zeros(0)
    for name, step in (("line", np.diff(c["line"])), ("time_utc", dt)):
        bad = step <= 0
        if len(c["line"]) < 2 or np.any(bad):
            k = int(np.argmax(bad)) + 1 if len(c["line"]) >= 2 else 0
            raise IngestError(
                f"{path}: column {name!r} row {k + 1}: a datation table needs ≥ 2 rows, lines and times strictly increasing"
            )
    return c["line"], t


def _check_detections(
    det: dict[str, Any], sensor: Any, ids: np.ndarray, datation_lines: tuple[float, float] | None
) -> np.ndarray:
    """Each detection's chip a chip of the sensor, its pixel a column of that chip, its landmark in the GCP file and its
    line inside the datation table: the target index (D,) of each, or an ``IngestError`` naming file, column, row, value."""
    src = det["source"]
    chip = det["chip"]
    bad = (chip < 0) | (chip >= sensor.n_chips)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise IngestError(
            f"{src}: column 'chip' row {k + 1}: chip {int(chip[k])} is not a chip of the sensor (0 … {sensor.n_chips - 1})"
        )
    first = sensor.chip_start
    lo, hi = first[chip] - 0.5, first[chip + 1] - 0.5
    pixel = det["pixel"]
    row = first_outside(pixel, lo, hi)
    if row is not None:
        raise IngestError(
            f"{src}: column 'pixel' row {row + 1}: {float(pixel[row])!r} is not a column of chip {int(chip[row])} "
            f"({lo[row] + 0.5:g} … {hi[row] - 0.5:g} on the whole line)"
        )
    if datation_lines is not None:
        line = det["line"]
        row = first_outside(line, datation_lines[0], datation_lines[1])
        if row is not None:
            raise IngestError(
                f"{src}: column 'line' row {row + 1}: line {float(line[row])!r} is outside the datation table "
                f"(lines {datation_lines[0]:g} … {datation_lines[1]:g})"
            )
    index = {str(n): i for i, n in enumerate(ids)}
    missing = [k for k, n in enumerate(det["landmark"]) if str(n) not in index]
    if missing:
        k = missing[0]
        raise IngestError(
            f"{src}: column 'landmark' row {k + 1}: {str(det['landmark'][k])!r} is not in the ground-control point file"
        )
    return np.array([index[str(n)] for n in det["landmark"]], np.int64)


def _one_segment(track: Any, what: str) -> Any:
    if track.segments:
        raise IngestError(
            f"{track.source}: {len(track.segments)} segments; a strip is read from one {what} segment (split the strip where "
            "the segments meet, or give the segment that covers it)"
        )
    return track


def _inside(
    t_s: np.ndarray, span: tuple[float, float], det: dict[str, Any], what: str, epoch: Any, time_system: tuple = ()
) -> None:
    """Refuse a detection whose line time falls outside ``span`` (s from ``epoch``), naming the row and the span, and a
    time-system slip of the samples' file (``time_system`` = its declared TIME_SYSTEM and line) that would put every
    line inside (``common.time_slip_hint``)."""
    from astropy import units as u

    from boresight.observations.flight.common import time_slip_hint

    k = first_outside(t_s, span[0], span[1])
    if k is not None:
        at = (epoch + t_s[k] * u.s).isot
        lo, hi = ((epoch + s * u.s).isot for s in span)
        hint = time_slip_hint(epoch + np.asarray(t_s, float) * u.s, epoch + span[0] * u.s, epoch + span[1] * u.s, time_system)
        raise IngestError(
            f"{det['source']}: column 'line' row {k + 1}: line {float(det['line'][k])!r} is dated {at}, outside {what} ({lo} … {hi})"
            + hint
        )


def assemble_strip(
    orbit: Any,
    attitude: Any,
    gcp_ids: Any,
    gcp_itrs_m: Any,
    det: dict[str, Any],
    spec: LineSensorSpec,
    noise: dict[str, Any] | None = None,
    check_geometry: bool = True,
    max_position_error_m: float | None = None,
) -> tuple[Any, dict[str, Any]]:
    """The ``ObservationSet`` of a strip's lines from the read inputs (module docstring), and a report (the inputs
    described, the counts) for the command to print. Strict: every detection is checked (chip, pixel, landmark,
    datation table) and its line's time must lie inside the AEM's samples and the OEM's. ``check_geometry=False``
    defers the set's behind-the-camera test (as ``assemble`` does), so that the convention doctor names a slip first.
    The orbit's interpolation error bound at every line's time is refused above ``max_position_error_m`` (default the
    frame camera's, ``orbit.MAX_POSITION_ERROR_M``: ``OrbitTrack.at``). DECISION: no SLERP error bound on the
    attitude: between the tracker's samples the lines' attitude *is* their interpolation (the attitude-sample table
    of the model; what the platform adds between samples is the jitter, an effect ``diagnose`` tests)."""
    from astropy.time import Time

    from boresight.observations.model import ObservationSet
    from orbits.camera import LinearLineDatation, TabulatedLineDatation
    from orbits.pushbroom import LineScanParameters, StripTrajectory, earth_orientation_samples, line_time_s
    from orbits.strip import line_records

    orbit, attitude = _one_segment(orbit, "orbit"), _one_segment(attitude, "attitude")
    if spec.table is not None:
        lines, t_tab = read_datation_csv(spec.table)
        epoch = t_tab[0]
        datation: Any = TabulatedLineDatation(lines, (t_tab - epoch).to_value("s"))
        table_lines: tuple[float, float] | None = (float(lines[0]), float(lines[-1]))
        how = f"table {spec.table} ({len(lines)} lines)"
    else:
        try:
            epoch = Time(spec.reference_time_utc, scale="utc")
        except ValueError as exc:
            raise IngestError(f"{spec.source}: [datation] reference_time_utc: {exc}") from exc
        datation = LinearLineDatation(float(spec.reference_line), 0.0, float(spec.line_period_s))  # type: ignore[arg-type]
        table_lines = None
        how = f"linear: line {spec.reference_line:g} at {epoch.isot}, {spec.line_period_s:g} s per line"
    target = _check_detections(det, spec.sensor, np.asarray(gcp_ids), table_lines)
    t_line = line_time_s(datation, det["line"], LineScanParameters())
    t_att = (attitude.times - epoch).to_value("s")
    t_orb = (orbit.times - epoch).to_value("s")
    att_span = (t_att[0], t_att[-1])
    if attitude.useable is not None:
        att_span = (
            max(att_span[0], (attitude.useable[0] - epoch).to_value("s")),
            min(att_span[1], (attitude.useable[1] - epoch).to_value("s")),
        )
    _inside(t_line, att_span, det, f"the attitude samples of {attitude.source}", epoch, getattr(attitude, "time_system", ()))
    # the orbit's Lagrange window: the middle of degree + 1 samples, so the first and last degree/2 spans are fine too
    _inside(t_line, (t_orb[0], t_orb[-1]), det, f"the orbit samples of {orbit.source}", epoch, getattr(orbit, "time_system", ()))
    from astropy import units as u

    from boresight.observations.flight.orbit import MAX_POSITION_ERROR_M

    _, _, bound = orbit.at(epoch + t_line * u.s, MAX_POSITION_ERROR_M if max_position_error_m is None else max_position_error_m)
    v = orbit.v_m_s
    if v is None:
        _, v, _ = orbit.at(orbit.times, max_error_m=np.inf)  # the derivative of the interpolating polynomial
    t_earth, C_GI = earth_orientation_samples(epoch, t_att[0] - 1.0, t_att[-1] + 1.0)
    mount = np.eye(3) if spec.C_SK_nominal is None else np.asarray(spec.C_SK_nominal, float)
    try:
        traj = StripTrajectory(t_orb, orbit.r_m, v, t_att, attitude.q_is, mount.T, t_earth, C_GI, int(orbit.degree))
    except ValueError as exc:
        raise IngestError(f"{orbit.source}, {attitude.source}: {exc}") from exc
    rec = line_records(
        spec.sensor,
        datation,
        traj,
        det["line"],
        det["chip"],
        det["pixel"],
        target,
        np.asarray(gcp_ids),
        np.asarray(gcp_itrs_m, float),
        epoch.isot,
        light_time=spec.light_time,
        aberration=spec.aberration,
    )
    obs = ObservationSet(**rec, noise=noise, check_geometry=check_geometry)
    rate = (t_att.size - 1) / (t_att[-1] - t_att[0])
    report = dict(
        orbit=f"{orbit.source} ({t_orb.size} samples, Lagrange degree {orbit.degree}"
        + ("; a HERMITE OEM read by Lagrange on positions and velocities" if orbit.method == "HERMITE" else "")
        + f"; {orbit.frame}; largest interpolation error bound {np.max(bound):.3g} m)",
        attitude=f"{attitude.source} ({t_att.size} tracker samples at {rate:.4g} Hz, SLERP; the attitude-sample table)",
        datation=how,
        detections=f"{det['source']}: {obs.n_observations} detections of {np.unique(target).size} GCPs on {spec.sensor.n_chips} chips, "
        f"lines {np.min(det['line']):.1f} … {np.max(det['line']):.1f}",
        notes=list(getattr(attitude, "notes", ())) + list(getattr(orbit, "notes", ())),
    )
    return obs, report


def _write_sensor_toml(path: Path, sensor: Any, datation: Any, epoch: Any, C_SK_nominal: Any, table: str | None) -> None:
    from astropy import units as u

    from boresight.observations.flight.pixels import toml_value

    out = ["[sensor]", f"focal_length_m = {sensor.focal_length_m!r}"]
    if sensor.pixel_pitch_m is not None:
        out.append(f"pixel_pitch_m = {sensor.pixel_pitch_m!r}")
    for c, ch in enumerate(sensor.chips):
        if ch.table_tan_psi is not None:  # its lines of sight [tan ψx, tan ψy, −1] in a CSV beside the TOML
            name = f"chip{c}-lines-of-sight.csv"
            with open(path.parent / name, "w", encoding="utf-8") as f:
                f.write("x,y,z\n")
                for tx, ty in np.asarray(ch.table_tan_psi, float):
                    f.write(f"{float(tx)!r},{float(ty)!r},-1.0\n")
            out += ["", "[[chips]]", f"n_pixels = {ch.n_pixels}", f'lines_of_sight = "{name}"']
            continue
        out += ["", "[[chips]]", f"n_pixels = {ch.n_pixels}"]
        out += [
            f"tan_psi_x = {toml_value([float(a) for a in ch.tan_psi_x])}",
            f"tan_psi_y = {toml_value([float(a) for a in ch.tan_psi_y])}",
        ]
    out += ["", "[datation]"]
    if table is not None:
        out.append(f'table = "{table}"')
    else:
        t_ref = (epoch + float(datation.reference_time_s) * u.s).utc
        t_ref.precision = 6
        out += [
            f"reference_line = {float(datation.reference_line)!r}",
            f'reference_time_utc = "{t_ref.isot}"',
            f"line_period_s = {float(datation.line_period_s)!r}",
        ]
    out += ["", "[mount]", f"C_SK_nominal = {toml_value(np.asarray(C_SK_nominal, float).tolist())}", ""]
    path.write_text("\n".join(out), encoding="utf-8")


def export_strip_files(obs: Any, folder: Any, datation_table_step: int | None = None) -> dict[str, Path]:
    """Write a strip's ``ObservationSet`` of lines (one run, ``boresight.observations.strip``) as pushbroom flight files
    in ``folder``: ``orbit.oem`` (its orbit samples, GCRF, Lagrange of the trajectory's degree), ``attitude.aem`` (the
    tracker's measured samples, ICRF → STAR_TRACKER), ``landmarks.csv`` (the GCPs seen, ITRS metres: every digit),
    ``line-detections.csv`` (landmark, chip, line, pixel, every digit) and ``line-sensor.toml``; with
    ``datation_table_step`` the datation as ``datation.csv``, one row every that many lines (needs the optional
    extra ``flight-export`` for the CCSDS writers)."""
    from astropy import units as u
    from astropy.time import Time

    from boresight.observations.flight.export import write_aem, write_oem
    from boresight.observations.flight.landmarks import write_landmarks_csv

    ls = obs.line_scan
    if ls is None or obs.runs != 1:
        raise IngestError("export_strip_files: one run of a set whose images are pushbroom lines")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tr = ls.trajectory
    epoch = Time(obs.epoch_utc, scale="utc")

    def times(t_s: np.ndarray) -> Any:  # to the microsecond (the CCSDS writers' and the tables' precision)
        t = epoch + np.asarray(t_s) * u.s
        t.precision = 6
        return Time(t.isot, scale="utc", precision=6)

    paths = {
        "oem": Path(
            write_oem(folder / "orbit.oem", times(tr.orbit_t_s), tr.orbit_r_i_m, tr.orbit_v_i_m_s, degree=int(tr.orbit_degree))
        ),
        "aem": Path(write_aem(folder / "attitude.aem", times(tr.tracker_t_s), tr.tracker_quat)),
    }
    seen = np.unique(obs.target_index)
    paths["landmarks"] = Path(
        write_landmarks_csv(
            folder / "landmarks.csv", np.asarray(obs.landmark_ids)[seen], obs.landmark_g_m[0, seen], geodetic=False
        )
    )
    img = np.asarray(obs.image_index)
    with open(folder / "line-detections.csv", "w", encoding="utf-8") as f:
        f.write("landmark,chip,line,pixel\n")
        for name, c, L, p in zip(
            np.asarray(obs.landmark_ids)[obs.target_index],
            np.asarray(ls.chip)[img],
            np.asarray(ls.line)[img],
            np.asarray(ls.pixel)[img],
        ):
            f.write(f"{name},{int(c)},{float(L)!r},{float(p)!r}\n")
    paths["line_detections"] = folder / "line-detections.csv"
    table = None
    if datation_table_step is not None:
        lo, hi = np.floor(np.min(ls.line)) - datation_table_step, np.ceil(np.max(ls.line)) + datation_table_step
        lines = np.arange(lo, hi + datation_table_step, datation_table_step)
        with open(folder / "datation.csv", "w", encoding="utf-8") as f:
            f.write("line,time_utc\n")
            for L, t in zip(lines, times(ls.datation.time_s(lines)).isot):
                f.write(f"{float(L)!r},{t}\n")
        paths["datation"] = folder / "datation.csv"
        table = "datation.csv"
    _write_sensor_toml(folder / "line-sensor.toml", ls.sensor, ls.datation, epoch, obs.C_SK_nominal, table)
    paths["line_sensor"] = folder / "line-sensor.toml"
    return paths
