"""M-estimator weights (IRLS) of the Huber, Cauchy and Tukey losses, as functions of the tuning
constant: the estimator chooses the constant (``boresight.core.losses.LOSSES``), this says what
the weight is.

>>> irls_weights([1.0, 4.0], "huber", 2.0).tolist()
[1.0, 0.5]
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.errors import InputValueError

__all__ = ["IRLS_LOSSES", "irls_weights", "irls_weight_slope"]

#: the losses :func:`irls_weights` knows
IRLS_LOSSES = ("huber", "cauchy", "tukey")


def _check(loss: str) -> None:
    if loss not in IRLS_LOSSES:
        raise InputValueError(f"loss: expected one of {list(IRLS_LOSSES)}, got {loss!r}")


def irls_weights(z: Any, loss: str, c: float) -> np.ndarray:
    """IRLS weight w(z) = ψ(z)/z of a normalised residual (length) ``z`` ≥ 0 under ``loss`` with
    tuning constant ``c``: Huber min(1, c/z), Cauchy 1/(1 + (z/c)²), Tukey (1 − (z/c)²)² inside c."""
    _check(loss)
    z = np.asarray(z, float)
    if loss == "huber":
        return np.where(z <= c, 1.0, c / np.maximum(z, 1e-300))
    if loss == "cauchy":
        w: np.ndarray = 1.0 / (1.0 + (z / c) ** 2)
        return w
    return np.where(z < c, (1.0 - (z / c) ** 2) ** 2, 0.0)


def irls_weight_slope(z: Any, loss: str, c: float) -> np.ndarray:
    """dw/dz of :func:`irls_weights`."""
    _check(loss)
    z = np.asarray(z, float)
    if loss == "huber":
        return np.where(z <= c, 0.0, -c / np.maximum(z, c) ** 2)
    if loss == "cauchy":
        slope: np.ndarray = -2.0 * z / c**2 * irls_weights(z, loss, c) ** 2
        return slope
    return np.where(z < c, -4.0 * z / c**2 * (1.0 - (z / c) ** 2), 0.0)
