"""The simulator's inputs at scale, and their simulation: what the simulator's scaling tests
(``tests/orbits/test_simulate_rows.py``) and benchmark (``benchmarks/bench_scale.py --simulate``) share.

* ``tile_arrays(a, copies, single_use)``: ``copies`` copies of a campaign's simulator inputs
  (``orbits.campaign_arrays``), new images and new targets (issue 27: campaigns at real sizes);
* ``simulate_arrays(a, runs, rows)``: ``orbits.draw_errors`` + ``orbits.observe`` of those inputs under one
  fixed error model (seed 0; 4″ star-tracker, 3 µm pixel and 0.1 m catalogue errors), the rows given or found.
"""

from __future__ import annotations

import numpy as np

from orbits.measurements import draw_errors, observe
from orbits.sensors import PixelNoise, StarTrackerErrors


def tile_arrays(a: dict, copies: int, single_use: bool = False) -> dict:
    """``copies`` copies of a campaign's simulator inputs (``orbits.campaign_arrays``): new images
    (times shifted by 10⁷ s a copy, passes renumbered) and new targets, the rows with them; with
    ``single_use`` every row first gets a target of its own (a ground-control point seen once).
    What ``orbits.observe`` and ``draw_errors`` take: the simulator's scaling tests and benchmark."""
    a = dict(a)
    img, tgt = a["rows"]
    if single_use:
        a["landmarks_g_m"] = a["landmarks_g_m"][tgt]
        a["landmark_pass"] = a["pass_index"][img]
        a["landmark_ids"] = np.array([f"G{k}" for k in range(img.size)])
        tgt = np.arange(img.size)
    n, t, p = a["t_s"].size, a["landmarks_g_m"].shape[0], int(a["pass_index"].max()) + 1
    c = np.arange(copies)
    out = dict(a)
    for key in ("r_sc_i_m", "v_sc_i_m_s", "C_GI", "C_IE", "landmarks_g_m"):
        out[key] = np.concatenate([a[key]] * copies)
    out["t_s"] = (a["t_s"][None] + 1e7 * c[:, None]).ravel()
    out["pass_index"] = (a["pass_index"][None] + p * c[:, None]).ravel()
    out["landmark_pass"] = (a["landmark_pass"][None] + p * c[:, None]).ravel()
    out["landmark_ids"] = np.array([f"{i}@{k}" for k in c for i in a["landmark_ids"]])
    out["rows"] = ((img[None] + n * c[:, None]).ravel(), (tgt[None] + t * c[:, None]).ravel())
    return out


def simulate_arrays(a: dict, runs: int, rows: bool = True):
    """``draw_errors`` + ``observe`` of the simulator inputs ``a`` (seed 0; star tracker 4″ per axis, pixel 3 µm,
    catalogue 0.1 m): with ``rows`` the rows ``a`` gives, else the rows ``observe`` finds by ``visible_rows``
    (the errors are drawn on ``a``'s rows either way)."""
    e = draw_errors(
        np.random.default_rng(0),
        runs,
        a["pass_index"],
        a["landmarks_g_m"].shape[0],
        rows=a["rows"],
        star_tracker=StarTrackerErrors((4.0, 4.0, 4.0)),
        pixel=PixelNoise(3e-6),
        catalogue_sigma_m=0.1,
    )
    return observe(e, **(a if rows else {k: v for k, v in a.items() if k != "rows"}))
