"""The camera TOML of ``boresight ingest``: the calibration (``orbits.camera.CameraCalibration``,
OpenCV's pinhole + Brown–Conrady model with the detector axes — the same keys as the observation
file's ``camera`` block, ``docs/data-format.md``) and the nominal star-tracker mount.

```toml
[camera]
focal_length_m = 2.2
pixel_pitch_m = 13e-6                 # or focal_length_px = [fu, fv] (or camera_matrix = [[...]])
principal_point_px = [5119.5, 5119.5]
u_axis = "+x"                         # camera-frame axis along which u (the column) increases
v_axis = "-y"                         # ... and v (the row): OpenCV's image with boresight −z_K
k1 = -0.08                            # k1 k2 k3 p1 p2 as OpenCV names them (or dist_coeffs = [...])
fov_deg = 3.4                         # optional: the full square field

[mount]
C_SK_nominal = [[...], [...], [...]]  # optional: nominal star tracker → camera DCM (rows)
```
"""

from __future__ import annotations

import tomllib

import numpy as np

from boresight.observations.flight.common import IngestError

__all__ = ["read_camera_toml", "read_mount_toml", "write_camera_toml"]


def _load(path) -> dict:
    try:
        return tomllib.loads(open(path, encoding="utf-8").read())
    except FileNotFoundError:
        raise
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise IngestError(f"{path}: not a readable TOML camera file: {exc}") from exc


def read_camera_toml(path):
    """(``CameraCalibration``, fov_deg or None) from a camera TOML's ``[camera]`` table."""
    from orbits.camera import CameraCalibration

    data = _load(path)
    unknown = sorted(set(data) - {"camera", "mount"})
    if unknown:
        raise IngestError(
            f"{path}: unknown table(s)/key(s) {', '.join(repr(k) for k in unknown)}; a camera file has [camera] and optionally [mount]"
        )
    if "camera" not in data:
        raise IngestError(f"{path}: no [camera] table")
    m = dict(data["camera"])
    fov = m.pop("fov_deg", None)
    if fov is not None and (isinstance(fov, bool) or not isinstance(fov, (int, float)) or not 0 < fov < 180):
        raise IngestError(f"{path}: [camera] fov_deg must be a number in (0, 180), got {fov!r}")
    try:
        cal = CameraCalibration.from_mapping(m, where=f"{path}: [camera]")
    except ValueError as exc:
        raise IngestError(str(exc)) from None
    return cal, (None if fov is None else float(fov))


def read_mount_toml(path):
    """The nominal star-tracker → camera DCM ``C_SK_nominal`` from the ``[mount]`` table (3 rows of
    3 numbers), or None (identity) if absent; it must be a proper rotation (to 1e-9)."""
    mount = _load(path).get("mount")
    if mount is None:
        return None
    unknown = sorted(set(mount) - {"C_SK_nominal"})
    if unknown:
        raise IngestError(f"{path}: unknown [mount] key(s) {', '.join(repr(k) for k in unknown)}; allowed: 'C_SK_nominal'")
    try:
        C = np.asarray(mount["C_SK_nominal"], float)
    except (KeyError, ValueError, TypeError) as exc:
        raise IngestError(f"{path}: [mount] C_SK_nominal must be 3 rows of 3 numbers: {exc}") from exc
    if C.shape != (3, 3) or not np.allclose(C @ C.T, np.eye(3), atol=1e-9) or np.linalg.det(C) < 0:
        raise IngestError(
            f"{path}: [mount] C_SK_nominal must be a 3×3 rotation matrix (star tracker → camera), got {mount['C_SK_nominal']!r}"
        )
    return C


def toml_value(v) -> str:
    """A TOML value of a string, a number (every digit) or a (nested) list of them."""
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(float(v))


def write_camera_toml(path, camera, C_SK_nominal=None, fov_deg=None):
    """The calibration (``camera.to_mapping()``), ``fov_deg`` and the mount, as ``read_camera_toml`` reads them."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(
            "# camera calibration: OpenCV pinhole + Brown-Conrady, detector axes (orbits.camera.CameraCalibration)\n[camera]\n"
        )
        for k, v in camera.to_mapping().items():
            f.write(f"{k} = {toml_value(v)}\n")
        if fov_deg is not None:
            f.write(f"fov_deg = {float(fov_deg)!r}\n")
        if C_SK_nominal is not None:
            f.write(
                f"\n# nominal star tracker -> camera DCM (rows)\n[mount]\nC_SK_nominal = {toml_value(np.asarray(C_SK_nominal, float).tolist())}\n"
            )
    return path
