"""Spacecraft velocity derived from GNSS positions when a file does not carry it.

The velocity-dependent effects (star-tracker aberration b × v/c, a GNSS bias in the
radial/along-track/cross-track frame, the argument of latitude) need v only to a small
fraction of its size: 1 m/s of error (1.3e-4 of a LEO speed) moves the aberration by
0.0007″. So when ``v_x v_y v_z`` are absent, v is the time derivative of a least-squares
polynomial through each pass's positions.

Model, per pass, run and inertial axis: r(t) ≈ Σ_k c_k P_k(τ), τ = (t − t_mid)/h ∈ [−1, 1]
(h the half-span, P_k Legendre polynomials for conditioning); v(t_i) = Σ_k c_k P_k'(τ_i)/h. The
whole fit is one linear map v = D r (D = P'(τ) V⁺ / h, (n, n)), applied to every run and axis at
once.

Truncation, known before fitting: the orbit is near-circular, so the error of D on *this* pass's
sampling is measured exactly on a circular orbit of the pass's mean radius |r| and mean motion
ω = √(μ/|r|³): e_d = max_i |D_d r_circ(t_i) − v_circ(t_i)| over both in-plane phases. The degree d
is the smallest in 2..min(n − 2, ``MAX_DEGREE`` = 10) with e_d ≤ ``MAX_TRUNCATION_M_S``
(0.05 m/s, 7e-6 of a LEO speed: 0.00003″ of aberration); the smallest degree keeps the noise
gain lowest, and n − 2 keeps one degree of freedom.

Criterion ("dense enough"), per pass: at least ``MIN_IMAGES`` = 4 images at distinct times and a
degree meeting the truncation bound. Every pass must qualify, else no velocity is derived and
the status says which pass failed and why. Checked against the simulator's exact velocity on
simulated passes in ``tests/observations/test_format_1_1.py``.

Noise: GNSS noise σ_R per image propagates as σ_v,i = σ_R ‖D_i‖ (a constant per-pass bias
cancels exactly: D·1 = 0), reported in the status when the noise model gives σ_R.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre

__all__ = [
    "DerivedVelocity",
    "derive_velocity",
    "derivative_matrix",
    "truncation_m_s",
    "MIN_IMAGES",
    "MAX_DEGREE",
    "MAX_TRUNCATION_M_S",
]

MIN_IMAGES = 4
MAX_DEGREE = 10
MAX_TRUNCATION_M_S = 0.05
MU_EARTH_M3_S2 = 3.986004418e14


@dataclass(frozen=True)
class DerivedVelocity:
    """``v_i_m_s`` (R, N, 3) or None; ``status`` (str); ``sigma_m_s`` (N,) the GNSS-noise 1-σ per
    image and axis (None when σ_R is unknown or no velocity was derived)."""

    v_i_m_s: np.ndarray | None
    status: str
    sigma_m_s: np.ndarray | None = None


def derivative_matrix(t_s, degree: int) -> np.ndarray:
    """D (n, n) with v = D r: the derivative at each time of the degree-``degree`` least-squares
    Legendre fit through samples at ``t_s`` (distinct, n > degree)."""
    t = np.asarray(t_s, float)
    d = int(degree)
    h = (t.max() - t.min()) / 2
    tau = (t - (t.max() + t.min()) / 2) / h
    V = legendre.legvander(tau, d)
    dV = np.stack([legendre.legval(tau, legendre.legder(np.eye(d + 1)[k])) for k in range(d + 1)], axis=-1)
    return dV @ np.linalg.pinv(V) / h


def truncation_m_s(t_s, D, radius_m: float) -> float:
    """Largest velocity error of ``D`` on a circular orbit of ``radius_m`` sampled at ``t_s``."""
    t = np.asarray(t_s, float)
    w = np.sqrt(MU_EARTH_M3_S2 / radius_m**3)
    ph = w * (t - t.mean())
    r = radius_m * np.stack([np.cos(ph), np.sin(ph)], -1)
    v = radius_m * w * np.stack([-np.sin(ph), np.cos(ph)], -1)
    return float(np.abs(D @ r - v).max())


def _pass_fit(t, radius_m):
    """(D, degree, truncation) for one pass, or (None, reason, None)."""
    n = t.size
    if n < MIN_IMAGES:
        return None, f"{n} image(s), need ≥ {MIN_IMAGES}", None
    if np.any(np.diff(np.sort(t)) <= 0):
        return None, "two images at the same time", None
    e = np.inf
    for d in range(2, min(n - 2, MAX_DEGREE) + 1):
        D = derivative_matrix(t, d)
        e = truncation_m_s(t, D, radius_m)
        if e <= MAX_TRUNCATION_M_S:
            return D, d, e
    span = float(t.max() - t.min())
    return (
        None,
        (
            f"{n} images over {span:g} s: a polynomial of degree ≤ {min(n - 2, MAX_DEGREE)} follows the orbit only to "
            f"{e:.3g} m/s (limit {MAX_TRUNCATION_M_S} m/s); more images per pass are needed"
        ),
        None,
    )


def derive_velocity(t_s, pass_index, r_sc_i_m, gnss_sigma_m: float | None = None) -> DerivedVelocity:
    """Velocity (R, N, 3) m/s from positions ``r_sc_i_m`` (R, N, 3) at times ``t_s`` (N,), pass by pass."""
    t = np.asarray(t_s, float)
    p = np.asarray(pass_index)
    r = np.asarray(r_sc_i_m, float)
    v = np.empty_like(r)
    gain = np.empty(t.size)
    degrees, trunc = [], 0.0
    for k in np.unique(p):
        sel = np.nonzero(p == k)[0]
        radius = float(np.linalg.norm(r[:, sel], axis=-1).mean())
        D, d, e = _pass_fit(t[sel], radius)
        if D is None:
            return DerivedVelocity(
                None,
                f"unavailable: pass {int(k)} has {d} (velocity is derived from GNSS positions only where every pass has ≥ "
                f"{MIN_IMAGES} images dense enough for a polynomial to follow the orbit); give v_x v_y v_z in the file",
            )
        v[:, sel] = np.einsum("ij,rjk->rik", D, r[:, sel])
        gain[sel] = np.sqrt(np.sum(D**2, axis=1))
        degrees.append(d)
        trunc = max(trunc, e)
    what = f"derived from GNSS positions ({len(degrees)} pass(es), Legendre degree {min(degrees)}..{max(degrees)}, truncation ≤ {trunc:.2g} m/s"
    if gnss_sigma_m is None:
        return DerivedVelocity(v, what + "; GNSS noise σ unknown)")
    sigma = gnss_sigma_m * gain
    return DerivedVelocity(v, what + f"; GNSS noise gives σ_v ≤ {sigma.max():.3g} m/s per axis)", sigma)
