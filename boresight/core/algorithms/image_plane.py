"""Algorithm 3 — image-plane residuals (Kiev 2012 eqs 19-22), derived for eq 24's sign of θ.

Algorithm 3 is Gauss-Newton on the exact measurement model of ``boresight.core.measurement`` (eqs 3,
20, 24): the residuals and Jacobian are ``measurement.linearize`` (derived there, with the SO(3)
right Jacobian ``orbits.rotations.right_jacobian``); this module adds the residual map and the
slide's literal eq 21 for comparison. ``predicted_camera_vectors``, ``projection_jacobian``,
``predict``, ``linearize`` and ``misalignment_jacobian`` (= ``right_jacobian``) are re-exported
from there under their historical names.

The slide's eq 21 printed literally ([[0, F, −x′], [−F, 0, y′]]) is kept as
``linearize_slide_eq21`` only so the tests can show what it loses.

Example
-------
>>> import numpy as np
>>> from boresight import simulate
>>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0))
>>> G, _ = linearize(obs, np.zeros(3))
>>> G21, _ = linearize_slide_eq21(obs, np.zeros(3))
>>> bool(np.abs(G - G21).max() > 1e-3)           # the slide's third column is not the rotation about z_K
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.core.measurement import (
    linearize,
    measured_rows,
    observation_rows,
    predict,
    predicted_camera_vectors,
    projection_jacobian,
)
from orbits.rotations import right_jacobian as misalignment_jacobian

__all__ = [
    "predicted_camera_vectors",
    "projection_jacobian",
    "predict",
    "linearize",
    "misalignment_jacobian",
    "residual_map",
    "linearize_slide_eq21",
]


def residual_map(obs: Any, theta_rad: Any) -> np.ndarray:
    """∂q/∂(image residual) per observation: the identity here, (R, K, 2, 2).

    Every algorithm exposes this map L so that the disturbance model (stated for image-plane
    residuals, ``boresight.core.disturbances``) can weight its residuals: cov(q) = L cov(q_image) Lᵀ.
    """
    L: np.ndarray = np.broadcast_to(np.eye(2), (obs.runs, observation_rows(obs)[0].size, 2, 2))
    return L


def linearize_slide_eq21(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray]:
    """Eq 21 exactly as printed: G_n = [[0, F, −x′_n], [−F, 0, y′_n]] (a known slip: loses θz).

    For demonstration and tests only; use ``linearize``. Shapes as ``linearize``.
    """
    _, q = linearize(obs, theta_rad)
    xy = measured_rows(obs)
    x, y = xy[..., 0], xy[..., 1]
    F = obs.focal_length_m
    G = np.zeros(xy.shape + (3,))
    G[..., 0, 1], G[..., 0, 2] = F, -x
    G[..., 1, 0], G[..., 1, 2] = -F, y
    return G, q
