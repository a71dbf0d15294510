"""Installation perpendicularity error of a ship-borne electro-optical device (USV sea-sky eqs 1-27).

Frames (USV sea-sky section 2): horizon g (x east, y north, z up), deck j (x starboard, y
heading, z up), device c. Azimuth q is measured from y (north / heading) towards x, elevation h
up from the x-y plane (eq 1). The device's azimuth axis is tilted from the deck normal by the
installation perpendicularity error: alpha about x_j and beta about y_j (eqs 8-10). Hull pitch P
is a rotation about x_j, roll R about y_j (eqs 2-3).

Forward model (eq 12): the stabilisation loop commands the device to the deck-frame direction
S_R S_P A of the wanted horizon direction A (eqs 4-6), but because of (alpha, beta) the LOS
actually lands at

    A_g' = S_P^-1 S_R^-1 S_alpha S_beta S_R S_P A,

and the elevation error against the sea-sky line is dh' = asin(A_g'[z]) - h (eq 14).

Everything here is a pure function of arrays that broadcast against each other; angles are in
radians in the ``*_rad`` core and in degrees in the ``*_deg`` wrappers used by the public API.

Example
-------
>>> import numpy as np
>>> dh = elevation_error_deg(np.array([0.0, 90.0]), alpha_deg=1.0, beta_deg=0.5)
>>> np.round(dh, 6).tolist()   # eq 16: dh'(0) = alpha, dh'(90) = -asin(cos a sin b)
[1.0, -0.499924]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from boresight.errors import InputValueError

__all__ = [
    "s_pitch",
    "s_roll",
    "s_alpha",
    "s_beta",
    "los_vector",
    "los_horizon_rad",
    "los_error_rad",
    "elevation_error_deg",
    "compensated_command_rad",
    "compensated_command_deg",
    "coarse_estimate_deg",
    "SpecialPoints",
    "special_points_deg",
]


def _rot(angle, axis: int, sign: float) -> np.ndarray:
    """Elementary rotation matrices of shape ``angle.shape + (3, 3)``, written as printed."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    if axis == 0:
        rows = [[o, z, z], [z, c, -sign * s], [z, sign * s, c]]
    else:
        rows = [[c, z, sign * s], [z, o, z], [-sign * s, z, c]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def s_pitch(pitch_rad) -> np.ndarray:
    """S_P of USV sea-sky eq 2, ``[[1,0,0],[0,cos P,sin P],[0,-sin P,cos P]]``; shape ``(..., 3, 3)``.

    It is scipy's active rotation by -P about x:
    ``Rotation.from_rotvec([-P, 0, 0]).as_matrix()``.
    """
    return _rot(pitch_rad, 0, -1.0)


def s_roll(roll_rad) -> np.ndarray:
    """S_R of USV sea-sky eq 3, ``[[cos R,0,-sin R],[0,1,0],[sin R,0,cos R]]``; shape ``(..., 3, 3)``.

    Active rotation by -R about y.
    """
    return _rot(roll_rad, 1, -1.0)


def s_alpha(alpha_rad) -> np.ndarray:
    """S_alpha of USV sea-sky eq 9, ``[[1,0,0],[0,cos a,-sin a],[0,sin a,cos a]]``: active +alpha about x."""
    return _rot(alpha_rad, 0, 1.0)


def s_beta(beta_rad) -> np.ndarray:
    """S_beta of USV sea-sky eq 10, ``[[cos b,0,sin b],[0,1,0],[-sin b,0,cos b]]``: active +beta about y."""
    return _rot(beta_rad, 1, 1.0)


def los_vector(azimuth_rad, elevation_rad=0.0) -> np.ndarray:
    """Unit LOS A = (cos h sin q, cos h cos q, sin h) of USV sea-sky eq 1; shape ``(..., 3)``."""
    q = np.asarray(azimuth_rad, dtype=float)
    h = np.asarray(elevation_rad, dtype=float)
    q, h = np.broadcast_arrays(q, h)
    return np.stack([np.cos(h) * np.sin(q), np.cos(h) * np.cos(q), np.sin(h)], axis=-1)


def _mv(m, v):
    return np.einsum("...ij,...j->...i", m, v)


def los_horizon_rad(azimuth_rad, alpha_rad, beta_rad, pitch_rad=0.0, roll_rad=0.0, elevation_rad=0.0):
    """Actual LOS A_g' in the horizon frame (USV sea-sky eq 12); shape ``(..., 3)``.

    All arguments broadcast. ``azimuth_rad``/``elevation_rad`` are the wanted direction (eq 1).
    """
    A = los_vector(azimuth_rad, elevation_rad)
    SP, SR = s_pitch(pitch_rad), s_roll(roll_rad)
    A_j = _mv(SR, _mv(SP, A))  # eq 4: the commanded direction in deck = device axes
    A_j_true = _mv(s_alpha(alpha_rad), _mv(s_beta(beta_rad), A_j))  # eq 8
    # eq 11: S_P^-1 S_R^-1 = S_P^T S_R^T (orthogonal)
    return _mv(np.swapaxes(SP, -1, -2), _mv(np.swapaxes(SR, -1, -2), A_j_true))


def los_error_rad(azimuth_rad, alpha_rad, beta_rad, pitch_rad=0.0, roll_rad=0.0, elevation_rad=0.0):
    """(dq', dh') of USV sea-sky eqs 13-14 in radians; each of the broadcast shape.

    dq' is wrapped to (-pi, pi].
    """
    Ag = los_horizon_rad(azimuth_rad, alpha_rad, beta_rad, pitch_rad, roll_rad, elevation_rad)
    q = np.asarray(azimuth_rad, dtype=float)
    dq = np.arctan2(Ag[..., 0], Ag[..., 1]) - q  # eq 13 (atan2 keeps the quadrant)
    dq = np.angle(np.exp(1j * dq))
    dh = np.arcsin(np.clip(Ag[..., 2], -1.0, 1.0)) - np.asarray(elevation_rad, dtype=float)  # eq 14
    return dq, dh


def elevation_error_deg(azimuth_deg, alpha_deg, beta_deg, pitch_deg=0.0, roll_deg=0.0):
    """Elevation error dh' (deg) of the LOS against the sea-sky line (USV sea-sky eqs 12, 14), h = 0.

    Parameters broadcast; e.g. ``azimuth_deg`` shape ``(n,)`` with ``alpha_deg`` shape
    ``(k, 1)`` gives shape ``(k, n)``.
    """
    r = np.radians
    _, dh = los_error_rad(r(azimuth_deg), r(alpha_deg), r(beta_deg), r(pitch_deg), r(roll_deg))
    return np.degrees(dh)


def compensated_command_rad(azimuth_rad, elevation_rad, alpha_rad, beta_rad, pitch_rad=0.0, roll_rad=0.0):
    """Device azimuth/elevation (q_c, h_c) that put the LOS on (q, h) (USV sea-sky eqs 25-27).

    A_c = (S_alpha S_beta)^-1 S_R S_P A; q_c = atan2(A_c[x], A_c[y]); h_c = asin(A_c[z]).
    Feeding A_c through the error chain of eq 12 returns A exactly.
    """
    A = los_vector(azimuth_rad, elevation_rad)
    A_j = _mv(s_roll(roll_rad), _mv(s_pitch(pitch_rad), A))  # eq 4
    Sab = np.einsum("...ij,...jk->...ik", s_alpha(alpha_rad), s_beta(beta_rad))
    A_c = _mv(np.swapaxes(Sab, -1, -2), A_j)  # eq 25 (inverse of a rotation = transpose)
    return np.arctan2(A_c[..., 0], A_c[..., 1]), np.arcsin(np.clip(A_c[..., 2], -1.0, 1.0))  # eqs 26-27


def compensated_command_deg(azimuth_deg, elevation_deg, alpha_deg, beta_deg, pitch_deg=0.0, roll_deg=0.0):
    """Degree wrapper of :func:`compensated_command_rad`; returns (q_c_deg, h_c_deg)."""
    r = np.radians
    qc, hc = compensated_command_rad(r(azimuth_deg), r(elevation_deg), r(alpha_deg), r(beta_deg), r(pitch_deg), r(roll_deg))
    return np.degrees(qc), np.degrees(hc)


def coarse_estimate_deg(q1_deg, h2_deg, *, alpha_positive: bool = True, peak_first: bool = False):
    """Closed-form (alpha, beta) in degrees from the special points (USV sea-sky eqs 21-23).

    Parameters
    ----------
    q1_deg : float or array
        Azimuth q1' of the zero crossing of dh' (eq 21: tan q1' = sin a / tan b).
    h2_deg : float or array
        Magnitude of the peak |h2'| (eq 22: sin^2 h2' = sin^2 a + cos^2 a sin^2 b).
    alpha_positive : bool
        Sign rule of section 4: alpha has the sign of h0' = dh'(q = 0).
    peak_first : bool
        Sign rule of section 4: beta is negative if, scanning 0 -> 359 deg, the peak comes
        before the valley, else positive.

    Returns
    -------
    (alpha_deg, beta_deg)

    >>> a, b = coarse_estimate_deg(60.0, 1.2)   # (the paper's own points: reproductions.usv_sea_sky)
    >>> round(float(a), 4), round(float(b), 4)
    (1.0393, 0.6)
    """
    q1 = np.radians(np.asarray(q1_deg, dtype=float))
    h2 = np.radians(np.asarray(h2_deg, dtype=float))
    if np.any(np.abs(h2) >= np.pi / 2):
        raise InputValueError(f"h2_deg: expected |h2| < 90 deg, got {h2_deg}")
    c2, t2 = np.cos(h2) ** 2, np.tan(q1) ** 2
    # eq 23 (the printed interval "(-pi/2, -pi/2)" is a typo for (-pi/2, pi/2))
    alpha = np.arccos(np.sqrt((c2 + c2 * t2) / (c2 + t2)))
    beta = np.arccos(np.sqrt(np.clip((c2 + t2) / (1.0 + t2), 0.0, 1.0)))
    alpha = alpha if alpha_positive else -alpha
    beta = -beta if peak_first else beta
    return np.degrees(alpha), np.degrees(beta)


@dataclass(frozen=True)
class SpecialPoints:
    """Special points of a measured dh'(q) curve (USV sea-sky section 4, points P0-P4), degrees."""

    zero_crossings_deg: np.ndarray  # azimuths where the smoothed curve changes sign, shape (m,)
    q1_deg: float  # zero crossing used in eq 21 (crossings averaged modulo 180 deg)
    peak_deg: tuple[float, float]  # (azimuth, value) of the maximum
    valley_deg: tuple[float, float]  # (azimuth, value) of the minimum
    h2_deg: float  # |peak| and |valley| averaged, used in eq 22
    h0_deg: float  # smoothed dh' nearest q = 0
    alpha_positive: bool  # sign rule for alpha (h0' > 0), decided robustly, see below
    peak_first: bool  # sign rule for beta (peak before valley from 0 to 359 deg), ditto

    def coarse_estimate_deg(self):
        """(alpha, beta) from these points through :func:`coarse_estimate_deg`."""
        return coarse_estimate_deg(self.q1_deg, self.h2_deg, alpha_positive=self.alpha_positive, peak_first=self.peak_first)


def special_points_deg(azimuth_deg, h_deg, *, window: int = 5) -> SpecialPoints:
    """Find the zero crossings, peak and valley of a measured scan (USV sea-sky section 4).

    The paper read these points off the images (Fig. 8) and does not say how; here they are
    taken from the table's frames. # DECISION: a circular running median of ``window`` frames
    first, because single frames are hit by surge-blocked sea-sky lines (section 6); zero
    crossings by linear interpolation between sign changes; as the paper suggests, the two
    crossings (pi apart) are averaged modulo 180 deg into the one in [0, 180), and |peak| and
    |valley| are averaged. The two sign rules of section 4 ("alpha has the sign of h0'", "beta
    is negative if the peak comes first") flip on a single noisy frame, so they are decided from
    projections over the whole scan that are equivalent for a clean eq-16 curve
    sin h' = sin a cos q - cos a sin b sin q: h0' > 0 <=> sum h cos q > 0, and the peak lies
    in [0, 180) <=> sum h sin q > 0.

    Parameters
    ----------
    azimuth_deg, h_deg : arrays of shape (n,)
        One scan sorted by azimuth in [0, 360).
    """
    q = np.asarray(azimuth_deg, dtype=float)
    h = np.asarray(h_deg, dtype=float)
    if q.ndim != 1 or q.shape != h.shape:
        raise InputValueError(f"azimuth_deg, h_deg: expected equal shapes (n,), got {q.shape}, {h.shape}")
    if window < 1 or window % 2 == 0 or window > q.size:
        raise InputValueError(f"window: expected an odd number in [1, {q.size}], got {window}")
    if np.any(np.diff(q) <= 0):
        raise InputValueError("azimuth_deg: expected strictly increasing azimuths (one scan, sorted)")
    half = window // 2
    idx = (np.arange(q.size)[:, None] + np.arange(-half, half + 1)[None, :]) % q.size
    hs = np.median(h[idx], axis=1)
    s = np.sign(hs)
    crossings = []
    for i in range(q.size):
        j = (i + 1) % q.size
        if s[i] != 0 and s[j] != 0 and s[i] != s[j]:
            qj = q[j] + (360.0 if j == 0 else 0.0)
            crossings.append((q[i] + (qj - q[i]) * hs[i] / (hs[i] - hs[j])) % 360.0)
        elif s[i] == 0:
            crossings.append(q[i])
    p1 = np.asarray(sorted(crossings))
    if p1.size == 0:
        raise InputValueError("h_deg: the smoothed scan never crosses zero; no special point P1")
    # average modulo 180 (doubling the angle makes crossings pi apart coincide)
    ang = np.radians(2.0 * p1)
    q1 = (np.degrees(np.arctan2(np.sin(ang).mean(), np.cos(ang).mean())) / 2.0) % 180.0
    ip, iv = int(np.argmax(hs)), int(np.argmin(hs))
    h2 = 0.5 * (abs(hs[ip]) + abs(hs[iv]))
    i0 = int(np.argmin(np.abs(np.angle(np.exp(1j * np.radians(q))))))
    qr = np.radians(q)
    return SpecialPoints(
        p1,
        float(q1),
        (float(q[ip]), float(hs[ip])),
        (float(q[iv]), float(hs[iv])),
        float(h2),
        float(hs[i0]),
        bool(np.sum(h * np.cos(qr)) >= 0),
        bool(np.sum(h * np.sin(qr)) > 0),
    )
