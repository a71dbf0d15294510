"""Star centroids → star rows: a CSV of centroids without identities, an orbit, an attitude, a camera.

The centroid CSV has one row per detection: ``time_utc`` (the frame time, ISO UTC; rows with the
same string are one frame), the position as ``u v`` (pixels, through the camera calibration, as
the landmark detections) or ``x_m y_m`` (the ideal focal plane, m), an optional ``magnitude``
(Hipparcos Hp or close to it; it narrows the identification's candidates) and an optional centroid σ
of each detection as the centroider reports it: ``sigma_px`` (pixels, isotropic, with ``u v``) or
``sigma_m`` (m on the focal plane, with ``x_m y_m``). A pixel σ becomes each row's focal-plane σ of
x and y through the calibration's local Jacobian J at that pixel, σ_x = σ_px √(J Jᵀ)_xx,
σ_y = σ_px √(J Jᵀ)_yy (σ_px × pitch without distortion; the x–y correlation a distorted field adds is
dropped: the row model carries a σ per axis). The identified rows carry it (``sigma_xy_m``, the
file's ``sigma_x sigma_y``, format 1.3) and the GLS weights each star by it; the identification's
gates keep the one ``sigma_centroid_m`` (DECISION: a gate sized by the command's σ, not by each
detection's, so a centroider that under-reports a false detection's σ cannot narrow its gate).

A CSV with a ``magnitude`` column but no σ column can have each centroid's σ derived from its
magnitude (``centroid_sigma_by_magnitude``) by the simulator's law (``orbits.star_frames.CentroidNoise``,
``docs/stars.md`` "Centroid noise by magnitude"): σ_px(m) = √(σ_floor² + (σ_ref 10^(0.2 (m − m_ref)))²), a
photon-limited centroid's σ ∝ 1/√flux ∝ 10^(0.2 m) above a floor, given in pixels and converted to
the focal plane as a ``sigma_px`` column is.

``assemble_star_centroids`` interpolates the orbit (GCRS position and velocity) and the star
tracker's attitude at each frame time, as ``assemble`` does for landmark detections, identifies
the centroids under the prior camera attitude C_SK,nom A with ``boresight.observations.star_id``
(σ_prior covers θ's prior and the tracker's error; false detections, hot pixels and ambiguous
matches stay unmatched and are reported, never accepted), and builds the star rows of the
identified ones (``boresight.observations.stars.star_observations``): the observation file of
format 1.2 (1.3 with the centroids' own σ) that ``estimate`` reads.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.observations.flight.attitude import MAX_ATTITUDE_ERROR_ARCSEC
from boresight.observations.flight.common import IngestError, distinct_times
from boresight.observations.flight.orbit import MAX_POSITION_ERROR_M
from boresight.observations.flight.tables import read_csv_columns

__all__ = [
    "read_star_centroids_csv",
    "centroid_sigma_by_magnitude",
    "centroid_sigma_span_px",
    "assemble_star_centroids",
    "DEFAULT_PRIOR_SIGMA_ARCSEC",
]

#: DECISION: the prior σ per axis of the camera attitude C_SK,nom A when the user gives none: 150″
#: covers a mounting misalignment of a few arcminutes at 5σ (the identification's gate) and the
#: star tracker's arcseconds; ``docs/stars.md`` measured identification with it
DEFAULT_PRIOR_SIGMA_ARCSEC = 150.0


def read_star_centroids_csv(path: Any) -> dict[str, Any]:
    """{'time_utc': (K,) str, 'uv_px' (K, 2) or 'xy_m' (K, 2), 'magnitude': (K,) or None, 'source'}, and
    'sigma_px' or 'sigma_m' (K,) when the CSV has that column (module docstring)."""
    with open(path, encoding="utf-8") as f:
        head = next((ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")), "")
    names = {h.strip() for h in head.split(",")}
    optional = tuple(c for c in ("magnitude", "sigma_px", "sigma_m") if c in names)
    if ({"u", "v"} <= names and "sigma_m" in names) or ({"x_m", "y_m"} <= names and "sigma_px" in names):
        raise IngestError(
            f"{path}: a centroid σ goes with its coordinates: 'sigma_px' (pixels) with 'u, v', 'sigma_m' (m) with 'x_m, y_m'"
        )
    if {"u", "v"} <= names:
        c = read_csv_columns(path, required=("time_utc", "u", "v"), optional=optional)
        out: dict[str, Any] = {"uv_px": np.stack([c["u"], c["v"]], -1)}
    elif {"x_m", "y_m"} <= names:
        c = read_csv_columns(path, required=("time_utc", "x_m", "y_m"), optional=optional)
        out = {"xy_m": np.stack([c["x_m"], c["y_m"]], -1)}
    else:
        raise IngestError(
            f"{path}: a star-centroid CSV needs columns 'time_utc' and 'u, v' (pixels) or 'x_m, y_m' (focal plane), "
            f"optionally 'magnitude' and 'sigma_px' (or 'sigma_m'); the header has {sorted(names)}"
        )
    out.update(time_utc=np.asarray(c["time_utc"], str), magnitude=c.get("magnitude"), source=str(path))
    for key in ("sigma_px", "sigma_m"):
        if key in c:
            sig = np.asarray(c[key], float)
            bad = ~(sig > 0)
            if np.any(bad):
                row = int(np.argmax(bad))
                raise IngestError(f"{path}: row {row + 1}: column {key!r} must be > 0 (a centroid's σ), got {sig[row]!r}")
            out[key] = sig
    return out


def centroid_sigma_by_magnitude(
    centroids: dict[str, Any], camera: Any, sigma_reference_px: float, reference_mag: float = 6.0, sigma_floor_px: float = 0.0
) -> dict[str, Any]:
    """``centroids`` (``read_star_centroids_csv``) with ``sigma_px`` (K,) from each row's ``magnitude`` by the
    centroid noise law (module docstring; ``orbits.star_frames.CentroidNoise``), and ``uv_px`` (through the
    calibration) when the CSV gave ``x_m y_m``, so each σ converts to the focal plane at its own pixel.

    DECISION: the law is evaluated by ``CentroidNoise`` itself (one implementation) with its σ_ref and
    floor in pixels: it is homogeneous of degree 1 in them, so its result is then in pixels. Refused
    (``IngestError``, naming the file and row): no ``magnitude`` column, a σ column already there (the
    centroider's own σ wins; give one or the other), a non-finite magnitude, σ_ref ≤ 0 or a floor < 0."""
    from orbits.star_frames import CentroidNoise

    source = centroids.get("source", "centroids")
    if centroids.get("magnitude") is None:
        raise IngestError(f"{source}: a centroid σ by magnitude needs a 'magnitude' column; the CSV has none")
    for key in ("sigma_px", "sigma_m"):
        if centroids.get(key) is not None:
            raise IngestError(
                f"{source}: the CSV has its own centroid σ (column {key!r}); a σ by magnitude would replace it: give one or the other"
            )
    if not (np.isfinite(sigma_reference_px) and sigma_reference_px > 0) or not (
        np.isfinite(sigma_floor_px) and sigma_floor_px >= 0
    ):
        raise IngestError(
            f"{source}: the centroid σ by magnitude needs σ_ref > 0 and a floor ≥ 0 pixels, got {sigma_reference_px!r}, {sigma_floor_px!r}"
        )
    mag = np.asarray(centroids["magnitude"], float)
    bad = ~np.isfinite(mag)
    if np.any(bad):
        row = int(np.argmax(bad))
        raise IngestError(
            f"{source}: row {row + 1}: column 'magnitude' must be a finite number (it sets the σ), got {mag[row]!r}"
        )
    law = CentroidNoise(sigma_reference_m=sigma_reference_px, reference_mag=reference_mag, sigma_floor_m=sigma_floor_px)  # pixels
    out = dict(centroids, sigma_px=law.sigma_m(mag))
    if "uv_px" not in out:
        out["uv_px"] = camera.focal_plane_to_pixels(np.asarray(out["xy_m"], float))
    return out


def centroid_sigma_span_px(centroids: dict[str, Any]) -> tuple[float, float] | None:
    """(smallest, largest) per-centroid σ of ``centroids`` (their ``sigma_px``: the CSV's own or
    ``centroid_sigma_by_magnitude``'s), px; None when they carry none. ``boresight ingest`` prints it.

    >>> centroid_sigma_span_px({"sigma_px": np.array([0.3, 0.1, 0.2])}), centroid_sigma_span_px({"sigma_px": None})
    ((0.1, 0.3), None)
    """
    s = centroids.get("sigma_px")
    if s is None or np.size(s) == 0:
        return None
    return float(np.min(s)), float(np.max(s))


def assemble_star_centroids(
    orbit: Any,
    attitude: Any,
    centroids: dict[str, Any],
    camera: Any,
    catalogue: Any,
    *,
    fov_deg: float,
    sigma_centroid_m: float,
    C_SK_nominal: Any = None,
    sigma_prior_arcsec: float = DEFAULT_PRIOR_SIGMA_ARCSEC,
    noise: dict | None = None,
    max_position_error_m: float = MAX_POSITION_ERROR_M,
    max_attitude_error_arcsec: float = MAX_ATTITUDE_ERROR_ARCSEC,
) -> tuple[Any, dict[str, Any]]:
    """(ObservationSet of the identified star rows, report) — module docstring. ``camera`` an
    ``orbits.camera.CameraCalibration`` (pixels ↔ focal plane); ``catalogue`` the star catalogue
    to identify against (e.g. ``load_hipparcos(limit + 0.5)``); ``max_position_error_m`` and
    ``max_attitude_error_arcsec`` the interpolation limits, as in ``assemble`` (typed keywords: a misspelt
    one is refused by Python, not silently ignored)."""

    from boresight.observations.star_id import IDENTIFIED, identify_stars
    from boresight.observations.stars import star_observations
    from orbits.camera import Camera
    from orbits.rotations import ARCSEC, dcm_from_quat

    source = centroids.get("source", "centroids")
    t_str = np.asarray(centroids["time_utc"], str)
    uniq, tt = distinct_times(t_str, source)
    frame = np.searchsorted(uniq, t_str, sorter=np.argsort(uniq))
    frame = np.argsort(uniq)[frame]  # each row's frame in time order
    xy = np.asarray(centroids["xy_m"], float) if "xy_m" in centroids else camera.pixels_to_focal_plane(centroids["uv_px"])
    F = uniq.size
    counts = np.bincount(frame, minlength=F)
    D = int(counts.max())
    slot = np.zeros(frame.size, np.int64)
    by_frame = np.argsort(frame, kind="stable")
    slot[by_frame] = np.arange(frame.size) - np.repeat(np.cumsum(counts) - counts, counts)
    xy_pad = np.zeros((F, D, 2))
    mask = np.zeros((F, D), bool)
    xy_pad[frame, slot], mask[frame, slot] = xy, True
    sig_pad = None
    own = _centroid_sigma_m(centroids, camera)  # (K, 2) each detection's own σ, or None
    if own is not None:
        sig_pad = np.full((F, D, 2), np.nan)
        sig_pad[frame, slot] = own
    mag = None
    if centroids.get("magnitude") is not None:
        mag = np.full((F, D), np.nan)
        mag[frame, slot] = centroids["magnitude"]
    r, v, _ = orbit.at(tt, max_error_m=max_position_error_m)
    q, _ = attitude.at(tt, max_error_arcsec=max_attitude_error_arcsec)
    if v is None:
        raise IngestError(f"{source}: star rows need the spacecraft velocity (orbital aberration): the orbit gives none")
    C_SK = np.eye(3) if C_SK_nominal is None else np.asarray(C_SK_nominal, float)
    pitch = getattr(camera, "pixel_pitch_m", None)
    pitch = float(np.atleast_1d(pitch)[0]) if pitch is not None else float(camera.focal_length_m / camera.focal_length_px[0])
    cam = Camera(float(camera.focal_length_m), float(fov_deg), pitch)
    ident = identify_stars(
        catalogue,
        cam,
        tt,
        r,
        v,
        xy_pad,
        mask,
        C_SK @ dcm_from_quat(q),
        sigma_prior_arcsec * ARCSEC,
        sigma_centroid_m,
        magnitude=mag,
    )
    ok = mask & (ident.status == IDENTIFIED)
    f, d = np.nonzero(ok)
    keep = np.unique(f)  # frames with an identified star
    new = np.full(F, -1)
    new[keep] = np.arange(keep.size)
    epoch = tt[keep[0]] if keep.size else tt[0]
    if not keep.size:
        raise IngestError(
            f"{source}: no centroid identified ({ident.counts(mask)}); check the attitude, the mount and --sigma-prior-arcsec"
        )
    obs = star_observations(
        catalogue,
        new[f],
        ident.hip[f, d],
        xy_pad[f, d][None],
        t_s=(tt[keep] - epoch).to_value("s"),
        q_is=q[keep][None],
        r_sc_i_m=r[keep][None],
        v_sc_i_m_s=v[keep][None],
        focal_length_m=float(camera.focal_length_m),
        epoch_utc=epoch.isot,
        C_SK_nominal=C_SK,
        fov_deg=fov_deg,
        pixel_pitch_m=pitch,
        noise=noise,
        camera=camera,
        sigma_xy_m=None if sig_pad is None else sig_pad[f, d],
    )
    report = {
        "frames": F,
        "frames_with_stars": int(keep.size),
        "detections": int(mask.sum()),
        "counts": ident.counts(mask),
        "offset_arcsec": (np.asarray(ident.offset_rad) / ARCSEC).tolist(),
        "orbit": orbit.describe() if hasattr(orbit, "describe") else getattr(orbit, "source", ""),
        "attitude": attitude.describe() if hasattr(attitude, "describe") else getattr(attitude, "source", ""),
    }
    return obs, report


def _centroid_sigma_m(centroids: dict[str, Any], camera: Any) -> np.ndarray | None:
    """(K, 2) each detection's own focal-plane σ of x and y (m) from ``sigma_px`` (through the calibration's
    Jacobian at its pixel) or ``sigma_m``; None without either (module docstring)."""
    if centroids.get("sigma_m") is not None:
        s = np.asarray(centroids["sigma_m"], float)
        return np.stack([s, s], -1)
    if centroids.get("sigma_px") is None:
        return None
    J = camera.pixels_to_focal_plane_jacobian(np.asarray(centroids["uv_px"], float))  # (K, 2, 2) m per pixel
    per_axis = np.sqrt(np.sum(J * J, axis=-1))  # √(J Jᵀ)_aa, a = x, y
    out: np.ndarray = np.asarray(centroids["sigma_px"], float)[:, None] * per_axis
    return out
