"""Interpolation of orbit and attitude samples to image times, with an error bound.

Position (CCSDS OEM, 502.0-B-3 §5.2.1 ``INTERPOLATION`` / ``INTERPOLATION_DEGREE``):

* **Lagrange** of degree n: the n+1 samples nearest the image time (a contiguous window, centred
  where the data allow), p(t) = Σ_j y_j ℓ_j(t), ℓ_j(t) = Π_{i≠j} (t − t_i)/(t_j − t_i).
* **Hermite** of degree n: k = (n+1)/2 samples, each with position and velocity (2k conditions,
  degree 2k − 1), by confluent divided differences (Newton form with doubled nodes).
* Error bound: SAFETY × |p_{n+2}(t) − p_n(t)| + Λ(t) (√3 δ + 4 ε |p|), where p_{n+2} uses the
  answer's window grown by one sample on each side (two on one side at an end of the data). The
  first term estimates the truncation error of p_n itself (the next terms of the Newton series,
  ≈ f^{(n+1)}(ξ) ω_n(t)/(n+1)! with ξ centred on the window); it vanishes at the samples as the
  error does. The second is the samples' rounding carried through the interpolation: Λ the
  Lebesgue function Σ|ℓ_j(t)|, δ half a unit in the last digit written in the file
  (``resolution``), ε the float64 epsilon. ``OrbitTrack.at`` adds speed × 1e-11 s (the time
  resolution of astropy Time differences).

  DECISION: SAFETY = 2 and the centred growth: the centred estimate measured 1.00–1.02 × the true
  error against a J2 propagation, so the bound is ≈ 2× the true error (the measurements, and why
  not the one-sided growth or the dropped-sample estimate: ``docs/data-format.md``, "Interpolation
  error bound"; ``tests/observations/test_interpolation_bound.py`` pins the ratio).

Attitude (CCSDS AEM; quaternions): **SLERP** between the two samples bracketing t (the geodesic on
the rotation group, what the AEM's LINEAR interpolation means for quaternions). Error estimate:
the angle between SLERP and a cubic (4-sample) Lagrange interpolation of the rotation vectors
relative to the bracketing sample (the tangent space at that sample); with fewer than 4 samples
the estimate uses what there is, with 2 it is unknown (reported as inf unless t is a sample).

Functions take times in seconds (float arrays) and vectorise over the query times.

The one implementation for the flight readers (``boresight.observations.flight.interpolate`` re-exports it)
and the pushbroom sensor model (``orbits.pushbroom``): it lives in the world's layer because ``orbits``
never imports ``boresight``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["window", "lagrange", "lagrange_values", "hermite", "slerp", "SAFETY"]

#: factor on the next-term estimate (see the module docstring: calibrated against J2 propagations)
SAFETY = 2.0


def window(t_nodes: Any, t_query: Any, k: int) -> np.ndarray:
    """Indices (Q, k) of the k samples nearest each query (contiguous, clipped at the ends)."""
    t_nodes = np.asarray(t_nodes, float)
    n = t_nodes.size
    k = min(k, n)
    j = np.searchsorted(t_nodes, t_query)  # first node ≥ t
    start = np.clip(j - k // 2, 0, n - k)
    result: np.ndarray = start[:, None] + np.arange(k)[None, :]
    return result


def _lagrange_eval(tn: Any, yn: Any, t: Any) -> np.ndarray:
    """tn (Q,k), yn (Q,k,D), t (Q,) -> (Q,D) by the Lagrange basis (k ≤ ~12, well conditioned on a window)."""
    k = tn.shape[1]
    d = t[:, None] - tn  # (Q,k)
    diff = tn[:, :, None] - tn[:, None, :]  # (Q,k,k)
    eye = np.eye(k, dtype=bool)
    num = np.where(eye[None], 1.0, d[:, None, :])  # (t - t_i) for i != j
    den = np.where(eye[None], 1.0, diff)
    basis = np.prod(num / den, axis=-1)  # (Q,k)
    result: np.ndarray = np.einsum("qk,qkd->qd", basis, yn)
    return result


def _drop_farthest(idx: Any, tn: Any, t: Any) -> np.ndarray:
    far = np.argmax(np.abs(tn - t[:, None]), axis=1)
    keep = np.ones(idx.shape, bool)
    keep[np.arange(idx.shape[0]), far] = False
    result: np.ndarray = idx[keep].reshape(idx.shape[0], idx.shape[1] - 1)
    return result


def _bound(p: Any, p_next: Any, lebesgue: Any, resolution: float) -> np.ndarray:
    """SAFETY × |next-term estimate| + the samples' rounding carried through the interpolation."""
    floor = np.max(np.abs(p), axis=-1) * np.finfo(float).eps * 4  # float64 rounding of the sums themselves
    result: np.ndarray = SAFETY * np.linalg.norm(p - p_next, axis=-1) + lebesgue * (np.sqrt(3.0) * resolution + floor)
    return result


def _lebesgue(tn: Any, t: Any) -> np.ndarray:
    """Σ_j |ℓ_j(t)| for the Lagrange basis on the window ``tn`` (Q, k)."""
    k = tn.shape[1]
    d = t[:, None] - tn
    diff = tn[:, :, None] - tn[:, None, :]
    eye = np.eye(k, dtype=bool)
    num = np.where(eye[None], 1.0, d[:, None, :])
    den = np.where(eye[None], 1.0, diff)
    result: np.ndarray = np.abs(np.prod(num / den, axis=-1)).sum(axis=1)
    return result


def lagrange_values(t_nodes: Any, y_nodes: Any, t_query: Any, degree: int) -> np.ndarray:
    """``lagrange``'s values alone (Q, D), without the error bound (a third of the work): for callers that evaluate
    the same samples many times and state their interpolation error elsewhere (``orbits.pushbroom``)."""
    t_nodes = np.asarray(t_nodes, float)
    y = np.asarray(y_nodes, float).reshape(t_nodes.size, -1)
    t = np.atleast_1d(np.asarray(t_query, float))
    idx = window(t_nodes, t, degree + 1)
    t0 = t_nodes[idx[:, 0]]
    return _lagrange_eval(t_nodes[idx] - t0[:, None], y[idx], t - t0)


def lagrange(t_nodes: Any, y_nodes: Any, t_query: Any, degree: int, resolution: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Lagrange interpolation of ``y_nodes`` (K, D) to ``t_query`` (Q,): (values (Q, D), error bound (Q,)).

    ``resolution``: half a unit in the last written digit of the samples (their rounding)."""
    t_nodes = np.asarray(t_nodes, float)
    y = np.asarray(y_nodes, float).reshape(t_nodes.size, -1)
    t = np.atleast_1d(np.asarray(t_query, float))
    idx = window(t_nodes, t, degree + 1)
    t0 = t_nodes[idx[:, 0]]  # local origin: conditioning
    p = _lagrange_eval(t_nodes[idx] - t0[:, None], y[idx], t - t0)
    if idx.shape[1] < 2:
        return p, np.full(t.size, np.inf)
    leb = _lebesgue(t_nodes[idx] - t0[:, None], t - t0)
    if t_nodes.size >= idx.shape[1] + 2:  # the next terms: the window grown by one sample on each side (two at an end)
        idx2 = window(t_nodes, t, idx.shape[1] + 2)
        p2 = _lagrange_eval(t_nodes[idx2] - t0[:, None], y[idx2], t - t0)
    else:  # no sample to spare: the previous term (drop the farthest), larger than the next in practice
        idx2 = _drop_farthest(idx, t_nodes[idx], t)
        p2 = _lagrange_eval(t_nodes[idx2] - t0[:, None], y[idx2], t - t0)
    return p, _bound(p, p2, leb, resolution)


def _hermite_eval(tn: Any, yn: Any, dyn: Any, t: Any) -> np.ndarray:
    """Confluent divided differences: nodes doubled, f[z_i, z_i] = f'(t_i). tn (Q,k), yn/dyn (Q,k,D)."""
    z = np.repeat(tn, 2, axis=1)  # (Q, 2k)
    m = z.shape[1]
    c = np.repeat(yn, 2, axis=1).copy()  # (Q, 2k, D) — column 0 of the table
    coef = [c[:, 0].copy()]
    # first divided differences
    prev = c
    for order in range(1, m):
        nxt = np.empty((c.shape[0], m - order, c.shape[2]))
        for i in range(m - order):
            dz = z[:, i + order] - z[:, i]
            if order == 1 and i % 2 == 0:
                nxt[:, i] = dyn[:, i // 2]
            else:
                nxt[:, i] = (prev[:, i + 1] - prev[:, i]) / dz[:, None]
        coef.append(nxt[:, 0].copy())
        prev = nxt
    # Newton form evaluation
    out = coef[-1].copy()
    for order in range(m - 2, -1, -1):
        out = out * (t - z[:, order])[:, None] + coef[order]
    return out


def hermite(
    t_nodes: Any, y_nodes: Any, dy_nodes: Any, t_query: Any, degree: int, resolution: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Hermite interpolation (values and derivatives at the samples): (values (Q, D), error bound (Q,))."""
    t_nodes = np.asarray(t_nodes, float)
    y = np.asarray(y_nodes, float).reshape(t_nodes.size, -1)
    dy = np.asarray(dy_nodes, float).reshape(t_nodes.size, -1)
    t = np.atleast_1d(np.asarray(t_query, float))
    k = max(1, (int(degree) + 1) // 2)
    idx = window(t_nodes, t, k)
    t0 = t_nodes[idx[:, 0]]
    p = _hermite_eval(t_nodes[idx] - t0[:, None], y[idx], dy[idx], t - t0)
    if idx.shape[1] < 2 and t_nodes.size < 2:
        return p, np.full(t.size, np.inf)
    # rounding: the value part of the Hermite basis is bounded by the Lagrange one on the doubled nodes; use the
    # Lagrange constant of the k nodes times 2 (DECISION: a simple upper estimate, only the floor of dense data)
    leb = 2.0 * _lebesgue(t_nodes[idx] - t0[:, None], t - t0) if idx.shape[1] > 1 else np.ones(t.size)
    if t_nodes.size >= idx.shape[1] + 2:
        idx2 = window(t_nodes, t, idx.shape[1] + 2)
    else:
        idx2 = _drop_farthest(idx, t_nodes[idx], t)
    p2 = _hermite_eval(t_nodes[idx2] - t0[:, None], y[idx2], dy[idx2], t - t0)
    return p, _bound(p, p2, leb, resolution)


def slerp(t_nodes: Any, q_nodes: Any, t_query: Any) -> tuple[np.ndarray, np.ndarray]:
    """SLERP of scalar-last quaternions: (q (Q, 4) with q4 ≥ 0, error estimate (Q,) rad)."""
    t_nodes = np.asarray(t_nodes, float)
    t = np.atleast_1d(np.asarray(t_query, float))
    rots = Rotation.from_quat(np.asarray(q_nodes, float))
    n = t_nodes.size
    if n == 1:
        q = np.repeat(rots.as_quat()[:1], t.size, axis=0)
        return q, np.where(t == t_nodes[0], 0.0, np.inf)
    i = np.clip(np.searchsorted(t_nodes, t, side="right") - 1, 0, n - 2)
    f = (t - t_nodes[i]) / (t_nodes[i + 1] - t_nodes[i])
    r0, r1 = rots[i], rots[i + 1]
    step = (r0.inv() * r1).as_rotvec()  # relative rotation in the sample's frame (scipy: active)
    r = r0 * Rotation.from_rotvec(step * f[:, None])
    q = r.as_quat()
    q = np.where(q[:, 3:4] < 0, -q, q)
    # error estimate: cubic Lagrange of rotation vectors relative to sample i
    k = min(4, n)
    if k < 3:
        err = np.where((f == 0) | (f == 1), 0.0, np.inf)
        return q, err
    idx = window(t_nodes, t, k)
    rel = np.stack([(r0.inv() * rots[idx[:, j]]).as_rotvec() for j in range(k)], axis=1)  # (Q,k,3)
    t0 = t_nodes[i]
    v = _lagrange_eval(t_nodes[idx] - t0[:, None], rel, t - t0)
    r_hi = r0 * Rotation.from_rotvec(v)
    err = (r.inv() * r_hi).magnitude()
    return q, err
