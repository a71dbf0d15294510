"""Detections: a CSV of landmark image positions in pixels, one row per landmark seen in an image.

Columns ``time_utc`` (the image time, ISO UTC; rows with the same string are one image),
``landmark`` (an id of the landmark catalogue) and the pixel position as ``u v`` (OpenCV: u the
column, v the row, 0 at the centre of the first pixel) or ``row col``.
"""

from __future__ import annotations

import numpy as np

from boresight.observations.flight.common import IngestError
from boresight.observations.flight.tables import read_csv_columns

__all__ = ["read_detections_csv", "write_detections_csv"]


def read_detections_csv(path) -> dict:
    """{'time_utc': (K,) str, 'landmark': (K,) str, 'uv_px': (K, 2)}."""
    with open(path, encoding="utf-8") as f:
        head = next((ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")), "")
    names = {h.strip() for h in head.split(",")}
    if {"u", "v"} <= names:
        c = read_csv_columns(path, required=("time_utc", "landmark", "u", "v"))
        uv = np.stack([c["u"], c["v"]], -1)
    elif {"row", "col"} <= names:
        c = read_csv_columns(path, required=("time_utc", "landmark", "row", "col"))
        uv = np.stack([c["col"], c["row"]], -1)
    else:
        raise IngestError(
            f"{path}: a detection CSV needs columns 'time_utc', 'landmark' and 'u, v' or 'row, col' (pixels); the header has {sorted(names)}"
        )
    return {"time_utc": c["time_utc"], "landmark": c["landmark"], "uv_px": uv, "source": str(path)}


def write_detections_csv(path, time_utc, landmark, uv_px):
    uv = np.asarray(uv_px, float)
    with open(path, "w", encoding="utf-8") as f:
        f.write("time_utc,landmark,u,v\n")
        for t, m, p in zip(time_utc, landmark, uv):
            f.write(f"{t},{m},{p[0]:.9f},{p[1]:.9f}\n")
    return path
