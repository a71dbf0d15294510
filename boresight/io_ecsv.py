"""Read and write ``ObservationSet`` as astropy ECSV (format in ``docs/data-format.md``).

One row per landmark observation (long format, easy to write by hand from flight data);
image-level columns (time, star-tracker quaternion, GNSS position, Earth rotation) repeat on
every row of the image and must agree. Floats are written with Python's shortest round-trip
repr, so write → read is bit-for-bit lossless.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .observations import FORMAT_NAME, FORMAT_VERSION, ObservationFileError, ObservationSet

__all__ = ["write_ecsv", "read_ecsv", "COLUMNS"]

#: column -> (unit, required, meaning)
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
    "cgi11": ("", False, "C_GI (Earth-fixed → inertial DCM) element 11; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi12": ("", False, "C_GI (Earth-fixed → inertial DCM) element 12; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi13": ("", False, "C_GI (Earth-fixed → inertial DCM) element 13; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi21": ("", False, "C_GI (Earth-fixed → inertial DCM) element 21; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi22": ("", False, "C_GI (Earth-fixed → inertial DCM) element 22; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi23": ("", False, "C_GI (Earth-fixed → inertial DCM) element 23; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi31": ("", False, "C_GI (Earth-fixed → inertial DCM) element 31; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi32": ("", False, "C_GI (Earth-fixed → inertial DCM) element 32; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "cgi33": ("", False, "C_GI (Earth-fixed → inertial DCM) element 33; all nine or none: computed from astropy ITRS→GCRS if absent"),
    "landmark": ("", True, "landmark identifier"),
    "X": ("m", True, "catalogue landmark position, Earth-fixed x"),
    "Y": ("m", True, "… Earth-fixed y"),
    "Z": ("m", True, "… Earth-fixed z"),
    "x": ("m", True, "measured image coordinate x on the focal plane"),
    "y": ("m", True, "measured image coordinate y on the focal plane"),
}

_IMAGE_COLS = ("q1", "q2", "q3", "q4", "r_x", "r_y", "r_z")


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


def write_ecsv(obs: ObservationSet, path, overwrite: bool = False) -> Path:
    """Write every run of ``obs`` to ``path`` (ECSV). Returns the path."""
    from astropy.table import Table

    path = Path(path)
    r_idx, n_idx, m_idx = np.nonzero(np.broadcast_to(obs.mask, (obs.runs,) + obs.mask.shape))
    empty = ~obs.mask.any(axis=1)
    if np.any(empty):
        raise ValueError(f"ObservationSet image {int(np.argmax(empty))} has no landmark observations; drop it with obs.images(...) before writing")
    t = Table()
    t["run"] = r_idx.astype(np.int64)
    t["image"] = n_idx.astype(np.int64)
    t["pass"] = obs.pass_index[n_idx].astype(np.int64)
    t["t"] = obs.t_s[n_idx]
    t["t"].unit = "s"
    for k in range(4):
        t[f"q{k + 1}"] = obs.q_is[r_idx, n_idx, k]
    for k, ax in enumerate("xyz"):
        t[f"r_{ax}"] = obs.r_sc_i_m[r_idx, n_idx, k]
        t[f"r_{ax}"].unit = "m"
    for i in range(3):
        for j in range(3):
            t[f"cgi{i + 1}{j + 1}"] = obs.C_GI[n_idx, i, j]
    t["landmark"] = obs.landmark_ids.astype(str)[m_idx]
    for k, ax in enumerate("XYZ"):
        t[ax] = obs.landmark_g_m[r_idx, m_idx, k]
        t[ax].unit = "m"
    for k, ax in enumerate("xy"):
        t[ax] = obs.xy_m[r_idx, n_idx, m_idx, k]
        t[ax].unit = "m"
    meta = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "epoch_utc": obs.epoch_utc,
        "focal_length_m": float(obs.focal_length_m),
        "fov_deg": None if obs.fov_deg is None else float(obs.fov_deg),
        "pixel_pitch_m": None if obs.pixel_pitch_m is None else float(obs.pixel_pitch_m),
        "C_SK_nominal": obs.C_SK_nominal.tolist(),
        "frames": dict(obs.frames),
        "quaternion_order": "scalar-last [q1, q2, q3, q4]; A(q) maps reference to body components",
        "theta_convention": "C_SK,true = exp(-Phi(theta)) C_SK,nominal (Kiev 2012 eq 24)",
        "landmark_order": obs.landmark_ids.astype(str).tolist(),
    }
    if obs.truth is not None and "theta_rad" in obs.truth:
        meta["truth_theta_rad"] = np.asarray(obs.truth["theta_rad"]).tolist()
    t.meta.update({k: _jsonable(v) for k, v in meta.items()})
    path.parent.mkdir(parents=True, exist_ok=True)
    t.write(path, format="ascii.ecsv", overwrite=overwrite)
    return path


def _err(msg):
    return ObservationFileError(msg)


def read_ecsv(path, geometry_checks: bool = True) -> ObservationSet:
    """Read and validate an observation file. Errors name the column and the row (0-based data row).

    ``geometry_checks=False`` skips the behind-the-camera and field-of-view tests (the convention
    doctor, ``boresight.doctor``, reads a file that fails them to say which convention is wrong)."""
    from astropy import units as u
    from astropy.table import Table
    from astropy.time import Time

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"observation file not found: {path}")
    try:
        tab = Table.read(path, format="ascii.ecsv")
    except Exception as exc:  # astropy raises several types for malformed ECSV
        raise _err(f"{path}: not a readable ECSV file ({type(exc).__name__}: {exc})") from None
    meta = dict(tab.meta)
    if meta.get("format") != FORMAT_NAME:
        raise _err(f"{path}: metadata 'format' must be {FORMAT_NAME!r}, got {meta.get('format')!r}")
    version = str(meta.get("format_version"))
    if version.split(".")[0] != FORMAT_VERSION.split(".")[0]:
        raise _err(f"{path}: unsupported format_version {version!r} (this reader reads {FORMAT_VERSION})")
    focal = meta.get("focal_length_m")
    if not isinstance(focal, (int, float)) or not np.isfinite(focal) or focal <= 0:
        raise _err(f"{path}: metadata 'focal_length_m' must be a positive number, got {focal!r}")

    for name, (unit, required, _) in COLUMNS.items():
        if required and name not in tab.colnames:
            raise _err(f"{path}: missing required column {name!r}")
        if name in tab.colnames and unit:
            got = tab[name].unit
            if got is None or u.Unit(got) != u.Unit(unit):
                raise _err(f"{path}: column {name!r} must have unit {unit!r}, got {got!r}")
    if "t" not in tab.colnames and "time_utc" not in tab.colnames:
        raise _err(f"{path}: needs a time column: 't' (s from epoch_utc) or 'time_utc' (ISO UTC)")
    if len(tab) == 0:
        raise _err(f"{path}: no observation rows")

    def col(name, dtype=float):
        c = tab[name]
        if hasattr(c, "mask") and np.any(c.mask):
            row = int(np.argmax(np.asarray(c.mask)))
            raise _err(f"{path}: column {name!r} row {row}: missing value")
        try:
            a = np.asarray(c, dtype=dtype)
        except (TypeError, ValueError):
            raise _err(f"{path}: column {name!r}: values are not {dtype.__name__}") from None
        if dtype is float and not np.all(np.isfinite(a)):
            row = int(np.argmax(~np.isfinite(a)))
            raise _err(f"{path}: column {name!r} row {row}: non-finite value {float(a[row])!r}")
        return a

    run = col("run", int) if "run" in tab.colnames else np.zeros(len(tab), int)
    image = col("image", int)
    pas = col("pass", int) if "pass" in tab.colnames else np.zeros(len(tab), int)
    if np.any(image < 0) or np.any(run < 0):
        bad = "image" if np.any(image < 0) else "run"
        row = int(np.argmax((image if bad == "image" else run) < 0))
        raise _err(f"{path}: column {bad!r} row {row}: negative index")

    epoch = meta.get("epoch_utc")
    if "t" in tab.colnames:
        t_row = col("t")
        if epoch is None:
            raise _err(f"{path}: column 't' needs the metadata 'epoch_utc'")
    else:
        try:
            times = Time(np.asarray(tab["time_utc"], dtype=str), scale="utc")
        except ValueError as exc:
            raise _err(f"{path}: column 'time_utc': not ISO UTC times ({exc})") from None
        epoch = epoch or times[0].isot
        t_row = (times - Time(epoch, scale="utc")).sec

    lm = np.asarray(tab["landmark"]).astype(str)
    runs = np.unique(run)
    if not np.array_equal(runs, np.arange(runs.size)):
        raise _err(f"{path}: column 'run' must number runs 0..R-1, got {runs.tolist()[:10]}")
    images = np.unique(image)
    n_img = int(images.max()) + 1
    ids = meta.get("landmark_order") or list(dict.fromkeys(lm.tolist()))
    ids = np.asarray(ids, dtype=str)
    if len(set(ids.tolist())) != ids.size:
        raise _err(f"{path}: metadata 'landmark_order' has duplicate ids")
    pos = {k: i for i, k in enumerate(ids.tolist())}
    missing = [k for k in dict.fromkeys(lm.tolist()) if k not in pos]
    if missing:
        raise _err(f"{path}: column 'landmark': id {missing[0]!r} not in metadata landmark_order")
    m_idx = np.array([pos[k] for k in lm.tolist()], int)
    R, N, M = runs.size, n_img, ids.size

    key = (run * N + image) * M + m_idx
    uniq, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = int(uniq[counts > 1][0])
        rows = np.nonzero(key == dup)[0]
        raise _err(f"{path}: duplicate observation of landmark {str(lm[rows[0]])!r} in image {image[rows[0]]} run {run[rows[0]]} (rows {rows[0]} and {rows[1]})")

    def per_image(values, name):
        out = np.full((R, N) + values.shape[1:], np.nan)
        out[run, image] = values
        check = out[run, image]
        diff = np.any(np.abs(check - values) > 0, axis=tuple(range(1, values.ndim)))
        if np.any(diff):
            row = int(np.argmax(diff))
            raise _err(f"{path}: column {name!r} row {row}: image {image[row]} has differing values on its rows")
        return out

    q = per_image(np.stack([col(f"q{k}") for k in (1, 2, 3, 4)], -1), "q1..q4")
    r = per_image(np.stack([col(f"r_{a}") for a in "xyz"], -1), "r_x..r_z")
    t_img = per_image(t_row[:, None], "t")[..., 0]
    p_img = per_image(pas[:, None].astype(float), "pass")[..., 0]
    seen = np.zeros((R, N), bool)
    seen[run, image] = True
    if not np.all(seen):
        rr, nn = np.argwhere(~seen)[0]
        raise _err(f"{path}: column 'image': run {rr} has no rows for image {nn} (images must be numbered 0..N-1 in every run)")
    if not np.all(t_img == t_img[:1]):
        raise _err(f"{path}: column 't': image times differ between runs")
    norms = np.linalg.norm(q, axis=-1)
    if np.any(np.abs(norms - 1) > 1e-6):
        rr, nn = np.argwhere(np.abs(norms - 1) > 1e-6)[0]
        row = int(np.nonzero((run == rr) & (image == nn))[0][0])
        raise _err(f"{path}: columns 'q1..q4' row {row}: quaternion norm {norms[rr, nn]:.9g}, expected 1")

    cgi_cols = [f"cgi{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]
    present = [c for c in cgi_cols if c in tab.colnames]
    if present and len(present) != 9:
        raise _err(f"{path}: columns cgi11..cgi33 must be all present or all absent, found only {present}")
    if present:
        C_GI = per_image(np.stack([col(c) for c in cgi_cols], -1), "cgi11..cgi33")[0].reshape(N, 3, 3)
        if not np.allclose(C_GI @ np.swapaxes(C_GI, -1, -2), np.eye(3), atol=1e-9):
            bad = int(np.argmax(np.abs(C_GI @ np.swapaxes(C_GI, -1, -2) - np.eye(3)).max(axis=(1, 2))))
            raise _err(f"{path}: columns 'cgi11..cgi33': image {bad} is not a rotation matrix")
    else:
        from astropy import units as uu

        from orbits.earth import itrs_to_gcrs_dcm

        C_GI = itrs_to_gcrs_dcm(Time(epoch, scale="utc") + t_img[0] * uu.s)

    lmk = np.stack([col(a) for a in "XYZ"], -1)
    L = np.full((R, M, 3), np.nan)
    L[run, m_idx] = lmk
    diff = np.any(L[run, m_idx] != lmk, axis=-1)
    if np.any(diff):
        row = int(np.argmax(diff))
        raise _err(f"{path}: columns 'X, Y, Z' row {row}: landmark {str(lm[row])!r} has differing catalogue positions")
    if np.any(np.isnan(L)):
        rr, mm = np.argwhere(np.isnan(L[..., 0]))[0]
        raise _err(f"{path}: landmark {str(ids[mm])!r} is never observed in run {rr}")
    mask_r = np.zeros((R, N, M), bool)
    mask_r[run, image, m_idx] = True
    if not np.all(mask_r == mask_r[:1]):
        raise _err(f"{path}: every run must observe the same (image, landmark) pairs")
    xy = np.zeros((R, N, M, 2))
    xy[run, image, m_idx] = np.stack([col("x"), col("y")], -1)

    C_SK = np.asarray(meta.get("C_SK_nominal", np.eye(3).tolist()), float)
    if C_SK.shape != (3, 3) or not np.allclose(C_SK @ C_SK.T, np.eye(3), atol=1e-9):
        raise _err(f"{path}: metadata 'C_SK_nominal' must be a 3×3 rotation matrix, got {meta.get('C_SK_nominal')!r}")

    # landmark in front of the camera (θ small): the nominal camera z component must be < 0
    from orbits.rotations import dcm_from_quat as _dq

    C_IK = C_SK @ _dq(q)  # (R, N, 3, 3)
    d = np.einsum("nij,rmj->rnmi", C_GI, L) - r[:, :, None, :]
    sz = np.einsum("rnj,rnmj->rnm", C_IK[:, :, 2, :], d)
    behind = mask_r & (sz >= 0) & geometry_checks
    if np.any(behind):
        rr, nn, mm = np.argwhere(behind)[0]
        row = int(np.nonzero((run == rr) & (image == nn) & (m_idx == mm))[0][0])
        raise _err(f"{path}: row {row}: landmark {str(ids[mm])!r} in image {nn} is behind the camera (camera-frame z = {sz[rr, nn, mm]:.6g} m ≥ 0)")
    fov = meta.get("fov_deg")
    if fov is not None:
        if not isinstance(fov, (int, float)) or not 0 < fov < 180:
            raise _err(f"{path}: metadata 'fov_deg' must be a number in (0, 180), got {fov!r}")
        # DECISION: a measured point may sit a little outside the nominal field (noise, a real
        # misalignment); 1 % of the half-width is allowed, more is a bad row or a bad fov_deg.
        half = focal * np.tan(np.radians(fov) / 2)
        out = mask_r[..., None] & (np.abs(xy) > 1.01 * half) & geometry_checks
        if np.any(out):
            rr, nn, mm, kk = np.argwhere(out)[0]
            row = int(np.nonzero((run == rr) & (image == nn) & (m_idx == mm))[0][0])
            raise _err(
                f"{path}: column {'xy'[kk]!r} row {row}: landmark {str(ids[mm])!r} in image {nn} is outside the field of view "
                f"({xy[rr, nn, mm, kk]:.6g} m, half-width {half:.6g} m for fov_deg = {fov})"
            )

    truth = None
    if "truth_theta_rad" in meta:
        truth = {"theta_rad": np.asarray(meta["truth_theta_rad"], float).reshape(R, 3)}
    frames = meta.get("frames") or {"inertial": "GCRS", "earth_fixed": "ITRS"}
    return ObservationSet(
        t_s=t_img[0],
        pass_index=p_img[0].astype(int),
        q_is=q,
        r_sc_i_m=r,
        C_GI=C_GI,
        landmark_ids=ids,
        landmark_g_m=L,
        xy_m=xy,
        mask=mask_r[0],
        focal_length_m=float(focal),
        C_SK_nominal=C_SK,
        fov_deg=meta.get("fov_deg"),
        pixel_pitch_m=meta.get("pixel_pitch_m"),
        epoch_utc=str(epoch),
        frames=dict(frames),
        truth=truth,
    )
