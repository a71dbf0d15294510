"""Static pointing error model of a two-axis gimbal (Tang 2014 eqs 1-10, Table 1).

Conventions of Tang 2014 (Fig. 1-2): at zero the azimuth axis is OZ, the elevation axis OY and
the LOS OX. The LOS is turned by R about OZ (azimuth) and P about OY (elevation), counter-
clockwise positive, so the ideal direction is OE' = (cos R cos P, sin R cos P, -sin P) (eq 3) --
note that positive P points the LOS *down*. The pointing error is (dR, dP): azimuth and
elevation of the actual LOS minus the commanded ones. (The paper's notation table swaps the
words "azimuth"/"elevation" for P and R; eqs 1-10 and Table 1 are unambiguous and are followed.)

The 14-coefficient parametric model (Tang 2014 eq 10):

    dR = C1 + C2 R + C3 sin R + C4 cos R + C5 sec P + C6 tan P + C7 cos R tan P + C8 sin R tan P
    dP = C9 + C10 P + C11 sin P + C12 cos P + C13 sin R + C14 cos R

R and P enter the regressors in radians; dR, dP and C are in whatever angle unit the caller
uses for the errors (degrees in the tests, as in the paper's tables).

Example
-------
>>> import numpy as np
>>> az, el = np.radians([[0.0, 10.0], [5.0, -20.0]])
>>> design_matrix(az, el).shape
(2, 14)
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy.spatial.transform import Rotation

from boresight.errors import InputValueError

__all__ = [
    "N_COEFFS",
    "N_AZIMUTH_COEFFS",
    "design_matrix",
    "design_matrix_azimuth",
    "design_matrix_elevation",
    "pointing_error",
    "GimbalErrors",
    "table1_contributions",
    "ParametricFit",
    "fit_parametric",
    "exact_base_tilt_error_rad",
]

N_COEFFS = 14
N_AZIMUTH_COEFFS = 8  # C1..C8 model dR, C9..C14 model dP


def _angles(az_rad, el_rad):
    R = np.asarray(az_rad, dtype=float)
    P = np.asarray(el_rad, dtype=float)
    R, P = np.broadcast_arrays(R, P)
    for name, a in (("az_rad", R), ("el_rad", P)):
        bad = ~np.isfinite(a)
        if np.any(bad):
            raise InputValueError(f"{name}: non-finite value {a[bad].ravel()[0]}")
    if np.any(np.abs(P) >= np.pi / 2 - 1e-6):
        raise InputValueError(
            f"el_rad: expected |P| < pi/2 (sec P, tan P in eq 10), got {P[np.abs(P) >= np.pi / 2 - 1e-6].ravel()[0]}"
        )
    return R, P


def design_matrix_azimuth(az_rad, el_rad) -> np.ndarray:
    """Regressors of dR in Tang 2014 eq 10 (C1..C8); shape ``broadcast(az, el).shape + (8,)``."""
    R, P = _angles(az_rad, el_rad)
    tp = np.tan(P)
    return np.stack([np.ones_like(R), R, np.sin(R), np.cos(R), 1.0 / np.cos(P), tp, np.cos(R) * tp, np.sin(R) * tp], axis=-1)


def design_matrix_elevation(az_rad, el_rad) -> np.ndarray:
    """Regressors of dP in Tang 2014 eq 10 (C9..C14); shape ``broadcast(az, el).shape + (6,)``."""
    R, P = _angles(az_rad, el_rad)
    return np.stack([np.ones_like(P), P, np.sin(P), np.cos(P), np.sin(R), np.cos(R)], axis=-1)


def design_matrix(az_rad, el_rad) -> np.ndarray:
    """Both blocks side by side, shape ``(..., 14)``: columns 0-7 for dR, 8-13 for dP."""
    return np.concatenate([design_matrix_azimuth(az_rad, el_rad), design_matrix_elevation(az_rad, el_rad)], axis=-1)


def pointing_error(coeffs, az_rad, el_rad):
    """(dR, dP) of Tang 2014 eq 10 for coefficients C1..C14 (shape ``(14,)`` or ``(..., 14)``)."""
    C = np.asarray(coeffs, dtype=float)
    if C.shape[-1:] != (N_COEFFS,):
        raise InputValueError(f"coeffs: expected shape (..., 14), got {C.shape}")
    dR = np.einsum("...k,...k->...", design_matrix_azimuth(az_rad, el_rad), C[..., :N_AZIMUTH_COEFFS])
    dP = np.einsum("...k,...k->...", design_matrix_elevation(az_rad, el_rad), C[..., N_AZIMUTH_COEFFS:])
    return dR, dP


@dataclass(frozen=True)
class GimbalErrors:
    """The integrant error sources of Tang 2014 Table 1 (all default 0), in the caller's angle unit.

    Table 1 names the optical-axis misalignment about OZ ``delta_vzx``, the same symbol as the
    azimuth-axis tilt about OX; it is ``delta_vxz`` here. ``q1``, ``q2`` are the encoder scale
    coefficients (elevation, azimuth; Table 1, eq 8 swaps them); ``q3_rho_ryx`` ... ``q6_rho_rzy``
    are the products Q_k rho of the rotating-shaft rows (eq 9).
    """

    delta_vzx: float = 0.0  # azimuth axis nonperpendicularity about OX
    delta_vzy: float = 0.0  # azimuth axis nonperpendicularity about OY
    delta_vyx: float = 0.0  # elevation axis nonperpendicularity about OX
    delta_vyz: float = 0.0  # elevation axis nonperpendicularity about OZ
    delta_vxy: float = 0.0  # optical axis misalignment about OY
    delta_vxz: float = 0.0  # optical axis misalignment about OZ
    eta_y: float = 0.0  # initialisation error, elevation
    eta_z: float = 0.0  # initialisation error, azimuth
    q1: float = 0.0  # encoder scale, elevation: dP = q1 P / 2 pi
    q2: float = 0.0  # encoder scale, azimuth: dR = q2 R / 2 pi
    q3_rho_ryx: float = 0.0  # shaft, elevation about OX: dP = -Q3 rho cos P
    q4_rho_ryz: float = 0.0  # shaft, elevation about OZ: dP = -Q4 rho sin P
    q5_rho_rzx: float = 0.0  # shaft, azimuth about OX: dR = -Q5 rho cos R
    q6_rho_rzy: float = 0.0  # shaft, azimuth about OY: dR = -Q6 rho sin R

    def coefficients(self) -> np.ndarray:
        """C1..C14 of eq 10 implied by these sources, shape ``(14,)``.

        Eq 10 ties C13 = -C7 and C14 = C8 (both come from the azimuth-axis tilt); the
        14-coefficient model leaves them free.
        """
        return np.array(
            [
                self.delta_vyz + self.eta_z,  # C1
                self.q2 / (2 * np.pi),  # C2
                -self.q6_rho_rzy,  # C3
                -self.q5_rho_rzx,  # C4
                self.delta_vxz,  # C5
                self.delta_vyx,  # C6
                self.delta_vzx,  # C7
                self.delta_vzy,  # C8
                self.delta_vxy + self.eta_y,  # C9
                self.q1 / (2 * np.pi),  # C10
                -self.q4_rho_ryz,  # C11
                -self.q3_rho_ryx,  # C12
                -self.delta_vzx,  # C13
                self.delta_vzy,  # C14
            ]
        )

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


def table1_contributions(errors: GimbalErrors, az_rad, el_rad):
    """(dR, dP) summed row by row from Tang 2014 Table 1 (independent of the C mapping)."""
    R, P = _angles(az_rad, el_rad)
    e = errors
    sR, cR, sP, cP, tP = np.sin(R), np.cos(R), np.sin(P), np.cos(P), np.tan(P)
    dR = (
        e.delta_vzx * cR * tP
        + e.delta_vzy * sR * tP
        + e.delta_vyx * tP
        + e.delta_vyz
        + e.delta_vxz / cP
        + e.eta_z
        + e.q2 * R / (2 * np.pi)
        - e.q5_rho_rzx * cR
        - e.q6_rho_rzy * sR
    )
    dP = (
        -e.delta_vzx * sR
        + e.delta_vzy * cR
        + e.delta_vxy
        + e.eta_y
        + e.q1 * P / (2 * np.pi)
        - e.q3_rho_ryx * cP
        - e.q4_rho_ryz * sP
    )
    return dR, dP


@dataclass(frozen=True)
class ParametricFit:
    """Least-squares C1..C14 (shape ``(14,)``) with residuals (data - model) and conditioning."""

    coeffs: np.ndarray
    residual_az: np.ndarray
    residual_el: np.ndarray
    cond_az: float
    cond_el: float

    def predict(self, az_rad, el_rad):
        return pointing_error(self.coeffs, az_rad, el_rad)


def _lstsq_scaled(G, y):
    # DECISION: scale columns to unit norm before the SVD solve; the eq-10 regressors
    # (1, R, sin R, cos R over +-20 deg) are nearly collinear and differ in size.
    s = np.linalg.norm(G, axis=0)
    s[s == 0] = 1.0
    x, *_ = np.linalg.lstsq(G / s, y, rcond=None)
    return x / s, float(np.linalg.cond(G / s))


def fit_parametric(az_rad, el_rad, d_az, d_el) -> ParametricFit:
    """Fit Tang 2014 eq 10 by least squares; all inputs shape ``(n,)``, n >= 8.

    ``d_az``/``d_el`` are the measured pointing errors dR, dP (any angle unit; C comes out in it).
    """
    R, P = _angles(az_rad, el_rad)
    dR, dP = np.asarray(d_az, dtype=float), np.asarray(d_el, dtype=float)
    if R.ndim != 1 or dR.shape != R.shape or dP.shape != R.shape:
        raise InputValueError(f"az_rad, el_rad, d_az, d_el: expected equal shapes (n,), got {R.shape}, {dR.shape}, {dP.shape}")
    if R.size < N_AZIMUTH_COEFFS:
        raise InputValueError(f"az_rad: need at least {N_AZIMUTH_COEFFS} points for eq 10, got {R.size}")
    for name, a in (("d_az", dR), ("d_el", dP)):
        if not np.all(np.isfinite(a)):
            raise InputValueError(f"{name}: non-finite value {a[~np.isfinite(a)][0]}")
    Ga, Ge = design_matrix_azimuth(R, P), design_matrix_elevation(R, P)
    ca, ka = _lstsq_scaled(Ga, dR)
    ce, ke = _lstsq_scaled(Ge, dP)
    return ParametricFit(np.concatenate([ca, ce]), dR - Ga @ ca, dP - Ge @ ce, ka, ke)


def exact_base_tilt_error_rad(az_rad, el_rad, tilt_x_rad=0.0, tilt_y_rad=0.0):
    """Exact (dR, dP) of an azimuth axis tilted about OX then OY, from scipy ``Rotation``.

    OE'' = Q_tilt Q_z(R) Q_y(P) i (Tang 2014 eqs 4-5), with Q_tilt the rotation by tilt_y about
    OY followed by tilt_x about OX; the returned errors are the azimuth atan2(y, x) and the
    elevation asin(-z) (eq 3 sign) of OE'' minus (R, P). First order in the tilts they equal
    Table 1's rows for delta_vzx and delta_vzy. Inputs broadcast; outputs of the broadcast shape.
    """
    R, P = _angles(az_rad, el_rad)
    tx, ty = np.broadcast_to(tilt_x_rad, R.shape).ravel(), np.broadcast_to(tilt_y_rad, R.shape).ravel()
    Rf, Pf = R.ravel(), P.ravel()
    z = np.zeros_like(Rf)
    rot = (
        Rotation.from_rotvec(np.column_stack([tx, z, z]))
        * Rotation.from_rotvec(np.column_stack([z, ty, z]))
        * Rotation.from_rotvec(np.column_stack([z, z, Rf]))
        * Rotation.from_rotvec(np.column_stack([z, Pf, z]))
    )
    v = rot.apply([1.0, 0.0, 0.0])
    dR = np.angle(np.exp(1j * (np.arctan2(v[:, 1], v[:, 0]) - Rf)))
    dP = np.arcsin(np.clip(-v[:, 2], -1, 1)) - Pf
    return dR.reshape(R.shape), dP.reshape(R.shape)
