"""Batched forms of the estimators for the Monte Carlo engine, beside the modules they mirror.

``image_plane_kernel`` (Algorithm 3, ``image_plane``), ``ground_plane_kernel`` (Algorithm 2,
``ground_plane``), ``unit_vector_kernel`` (``unit_vector``) and ``kalman_theta_kernel`` (the
study's θ-only filter, ``kalman``'s information form with R_n fixed at the nominal geometry): each
a chosen twin of its algorithm, tested equal to it (< 1e-8″, ``tests/studies/test_montecarlo.py``).
``gauss_newton`` runs any module's ``linearize`` over a batch; ``weighted_kernel`` drives the library
estimator ``boresight.estimate`` itself on a batch of runs. Which kernel runs a name is
``boresight.core.registry``'s ``montecarlo_kernel``.

Structure of arrays, fixed summation order, no BLAS products: see ``docs/montecarlo.md``, "Kernels".

On rows (``docs/architecture.md``, "The row model"): every kernel works on the observations of a
set — ``camera_vectors0`` (R, K, 3), the measured points (R, K, 2), in canonical (image, target)
order — so a chunk's memory is O(R K) whatever the campaign's targets. The first k images of a set
are its first ``row_start[k]`` rows; the Kalman kernel takes image n's rows
``row_start[n]:row_start[n + 1]`` and its weight block (2m_n × 2m_n). Only ``camera_vectors0``
uses the (R, N, T) view of a complete set (``obs.is_complete``: a reshape, no copy). The rows are
the valid cells of the old images × landmarks grid in the same order, so the kernels' sums run
over the same terms in the same order as before the row model.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from boresight.errors import InputValueError
from orbits.rotations import rotate, rotate_soa, sym3_inverse, sym3_inverse_soa

# DECISION: the rotation math (Rodrigues, right Jacobian, symmetric 3 × 3 inverses) is
# orbits.rotations'; these kernels only arrange it for batches. Bit-identical to the
# kernels' former private copies (tests/project/test_public_outputs.py compares the study outputs byte for byte).


def _rotate(theta: np.ndarray, s0: np.ndarray) -> Any:
    """exp(−Φ(θ)) s0, θ (R, 3), s0 (R, ..., 3) → (R, ..., 3) (``orbits.rotations.rotate``)."""
    return rotate(-theta, s0)


def _inv6(m: Any) -> Any:
    """Inverse of symmetric 3 × 3 matrices given as 6 component arrays (00, 01, 02, 11, 12, 22)."""
    return sym3_inverse_soa(*m)


def _image_plane_G(s: np.ndarray, F: float) -> Any:
    """P Φ(s) for s (..., 3): the image-plane Jacobian at θ = 0 rotation (``image_plane`` module docstring)."""
    sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
    f = -F / sz
    G = np.empty(s.shape[:-1] + (2, 3))
    G[..., 0, 0] = f * sx * sy / sz
    G[..., 0, 1] = f * (-sz - sx * sx / sz)
    G[..., 0, 2] = f * sy
    G[..., 1, 0] = f * (sz + sy * sy / sz)
    G[..., 1, 1] = -f * sx * sy / sz
    G[..., 1, 2] = -f * sx
    return G


def _solve3(B: np.ndarray, y: np.ndarray) -> Any:
    """Batched solve of B θ = y, B (R, 3, 3) symmetric, y (R, 3)."""
    return np.einsum("rij,rj->ri", sym3_inverse(B), y)


def camera_vectors0(obs: Any) -> Any:
    """s0 = C_SK,nom A (r_L − r) of every row, (R, K, 3): the θ-independent part of eq 20.

    A complete set is computed on its (R, N, T) view (one 3 × 3 product per image, batched, as
    before the row model); any other set row by row, component by component (the rows' attitude
    components gathered one at a time: no (R, K, 3, 3) array).
    """
    C = obs.nominal_camera_attitude()  # (R, N, 3, 3)
    d = obs.row_target_vectors_i(obs.image_index, obs.target_index)  # (R, K, 3)
    R, K = d.shape[:2]
    if obs.is_complete:
        grid = np.matmul(d.reshape(R, obs.n_images, obs.n_targets, 3), np.swapaxes(C, -1, -2))
        return grid.reshape(R, K, 3)
    img = obs.image_index
    out = np.empty_like(d)
    for i in range(3):
        out[..., i] = C[:, img, i, 0] * d[..., 0] + C[:, img, i, 1] * d[..., 1] + C[:, img, i, 2] * d[..., 2]
    return out


def image_plane_kernel(
    s0: np.ndarray,
    xy_m: np.ndarray,
    focal_length_m: float,
    iterations: int = 2,
    *,
    max_iterations: int | None = None,
) -> Any:
    """Gauss-Newton on Algorithm 3 (Kiev 2012 eqs 20-22, eq 24's sign) from θ0 = 0, batched.

    ``s0`` (R, K, 3) = C_SK,nom A (r_L − r) of each row (``camera_vectors0``); ``xy_m`` (R, K, 2).
    Unit weights (eq 22's B = Σ GᵀG). Returns θ̂ (R, 3), rad. Mirrors
    ``boresight.core.algorithms.image_plane.linearize`` (same G = P Φ(s) J_r(θ0), tested equal).
    Structure of arrays (run axis last, see ``kalman_theta_kernel``); the sums over observations
    run in a fixed order so a run's result does not depend on the chunk it is in.
    With ``max_iterations``: iterate each run until ``step_converged`` (at least
    ``iterations`` steps, at most ``max_iterations``) and return ``(θ̂, converged (R,) bool)``.

    >>> import numpy as np
    >>> s0 = np.array([[[1e3, 0, -7e5], [0, 1e3, -7e5], [-1e3, 0, -7e5], [0, -1e3, -7e5]]])
    >>> xy = -2.2 * s0[..., :2] / s0[..., 2:]
    >>> bool(np.abs(image_plane_kernel(s0, xy, 2.2)).max() < 1e-15)
    True
    """
    R = s0.shape[0]
    F = float(focal_length_m)
    S0, XY = _soa(s0), _soa(xy_m)  # (K, 3, R), (K, 2, R)
    sx0, sy0, sz0 = S0[:, 0], S0[:, 1], S0[:, 2]
    theta = np.zeros((3, R))
    conv = _Convergence(R, iterations, max_iterations)
    for it in range(conv.n_max):
        sx, sy, sz, b, c = _rotated_soa(theta, it, sx0, sy0, sz0)
        px, py, g = _image_plane_soa(sx, sy, sz, F)
        rx, ry = XY[:, 0] + F * px, XY[:, 1] + F * py
        if it > 0:
            g = tuple(_times_right_jacobian(gk, theta, b, c) for gk in g)
        (a0, a1, a2), (b0, b1, b2) = g
        B = [
            _sum0(a0 * a0 + b0 * b0),
            _sum0(a0 * a1 + b0 * b1),
            _sum0(a0 * a2 + b0 * b2),
            _sum0(a1 * a1 + b1 * b1),
            _sum0(a1 * a2 + b1 * b2),
            _sum0(a2 * a2 + b2 * b2),
        ]
        y0, y1, y2 = _sum0(a0 * rx + b0 * ry), _sum0(a1 * rx + b1 * ry), _sum0(a2 * rx + b2 * ry)
        P = _inv6(B)
        step = np.stack([P[0] * y0 + P[1] * y1 + P[2] * y2, P[1] * y0 + P[3] * y1 + P[4] * y2, P[2] * y0 + P[4] * y1 + P[5] * y2])
        theta = theta + conv.update(step.T, it).T
        if conv.done(it):
            break
    return conv.result(theta.T.copy())


#: Gauss-Newton convergence tolerance of the Monte Carlo kernels: 1e-4″ (a 10⁻⁵ part of any σθ
#: the seminar reports), in rad
CONVERGENCE_TOL_RAD = 1e-4 * np.pi / (180 * 3600)


def step_converged(step: np.ndarray, previous_step: np.ndarray, tol_rad: float = CONVERGENCE_TOL_RAD) -> Any:
    """Has a Gauss-Newton run converged after taking ``step`` (R, 3) rad? (R,) bool.

    Near the solution Gauss-Newton on these small-residual problems converges quadratically:
    the error left after a step is about |step|² (rad; the rotation's curvature is O(1)). A run
    is converged when that predicted error is below ``tol_rad`` *and* the step shrank at least
    100-fold (evidence of the quadratic regime), or when the step itself is below ``tol_rad``.
    A non-finite step is never converged.

    >>> step_converged(np.array([[1e-6, 0, 0], [1e-3, 0, 0], [1e-12, 0, 0]]), np.array([[1e-3, 0, 0], [2e-3, 0, 0], [1e-12, 0, 0]])).tolist()
    [True, False, True]
    """
    s = np.abs(step).max(axis=-1)
    p = np.abs(previous_step).max(axis=-1)
    return np.isfinite(s) & ((s <= tol_rad) | ((s * s <= tol_rad) & (s <= 0.01 * p)))


def _rotated_soa(theta: np.ndarray, it: Any, x0: np.ndarray, y0: np.ndarray, z0: np.ndarray) -> Any:
    """exp(−Φ(θ)) (x0, y0, z0) and the right-Jacobian coefficients b, c (``rotate_soa``); at the
    first step (θ = 0, ``it == 0``) the points themselves and no coefficients."""
    if it == 0:
        return x0, y0, z0, None, None
    sx, sy, sz, _, b, c = rotate_soa(theta, x0, y0, z0)
    return sx, sy, sz, b, c


def _image_plane_soa(sx: np.ndarray, sy: np.ndarray, sz: np.ndarray, F: float) -> Any:
    """(px, py) = s_xy/s_z and the rows (g0, g1) of G = P Φ(s) (``_image_plane_G``, in units of F),
    component by component: the image-plane model's projection and Jacobian at s."""
    iz = 1.0 / sz
    px, py = sx * iz, sy * iz
    return px, py, ((-F * px * py, F * (1.0 + px * px), -F * py), (-F * (1.0 + py * py), F * px * py, F * px))


class _Convergence:
    """Per-run Gauss-Newton bookkeeping: ``iterations`` steps for every run, then (with
    ``max_iterations``) further steps only for the runs not yet ``step_converged`` — a converged
    run's θ is frozen, so its result does not depend on the other runs of its chunk."""

    def __init__(self, runs: int, iterations: int, max_iterations: Any) -> None:
        self.min = int(iterations)
        self.flag = max_iterations is not None
        self.n_max = max(self.min, int(max_iterations)) if self.flag else self.min
        self.active = np.ones(runs, bool)
        self.converged = np.zeros(runs, bool)
        self.prev = np.full((runs, 3), np.inf)

    def update(self, step: np.ndarray, it: int) -> Any:
        """The step to apply (R, 3): zero for frozen runs."""
        if not self.flag:
            return step
        ok = step_converged(step, self.prev)
        self.prev = step
        applied = np.where(self.active[:, None], step, 0.0)
        self.converged = np.where(self.active, ok, self.converged)
        if it + 1 >= self.min:
            self.active &= ~ok
        return applied

    def done(self, it: int) -> bool:
        return self.flag and it + 1 >= self.min and not self.active.any()

    def result(self, theta: np.ndarray) -> Any:
        return (theta, self.converged.copy()) if self.flag else theta


def _rows_times(G0: Any, J: Any) -> Any:
    """G0 (R, ..., 2, 3) @ J (R, 3, 3) without a broadcast matmul over the middle axes."""
    shape = G0.shape
    return np.matmul(G0.reshape(shape[0], -1, 3), J).reshape(shape)


def _soa(a: Any) -> Any:
    """(R, K, ...) → run axis last, (K, ..., R), contiguous (structure of arrays)."""
    return np.ascontiguousarray(np.moveaxis(a, 0, -1))


def _normal_equations_soa(rows: Any) -> Any:
    """Unit-weight Gauss-Newton step from residual rows [(g0, g1, g2, q), ...], each (V, R):
    B = Σ g gᵀ, y = Σ g q summed over observations in a fixed order (``_sum0``), step = B⁻¹ y (3, R)."""
    B = [0.0] * 6
    y = [0.0] * 3
    for g0, g1, g2, q in rows:
        g = (g0, g1, g2)
        for k, (i, j) in enumerate(zip(_PI, _PJ)):
            B[k] = B[k] + _sum0(g[i] * g[j])
        for i in range(3):
            y[i] = y[i] + _sum0(g[i] * q)
    P = _inv6(B)
    return np.stack(
        [
            P[0] * y[0] + P[1] * y[1] + P[2] * y[2],
            P[1] * y[0] + P[3] * y[1] + P[4] * y[2],
            P[2] * y[0] + P[4] * y[1] + P[5] * y[2],
        ]
    )


def _times_right_jacobian(g: Any, theta: np.ndarray, b: Any, c: Any) -> Any:
    """Row (g0, g1, g2) times J_r(θ) = (1 − cφ²) E − b Φ(θ) + c θθᵀ, component by component (SoA)."""
    t0, t1, t2 = theta
    d = 1.0 - c * (t0 * t0 + t1 * t1 + t2 * t2)
    j00, j11, j22 = d + c * t0 * t0, d + c * t1 * t1, d + c * t2 * t2
    j01, j10 = c * t0 * t1 + b * t2, c * t0 * t1 - b * t2
    j02, j20 = c * t0 * t2 - b * t1, c * t0 * t2 + b * t1
    j12, j21 = c * t1 * t2 + b * t0, c * t1 * t2 - b * t0
    ga, gb, gc = g
    return ga * j00 + gb * j10 + gc * j20, ga * j01 + gb * j11 + gc * j21, ga * j02 + gb * j12 + gc * j22


def ground_plane_kernel(obs: Any, s0: np.ndarray, iterations: int = 2, *, max_iterations: int | None = None) -> Any:
    """Gauss-Newton on Algorithm 2 (Kiev 2012 eqs 14-18, ``algorithms.ground_plane``), batched.

    The module's model written in the nominal camera frame K0, where everything but the
    measured rays is θ-independent: with u = exp(Φ(θ)) s′, n and the east/north rows t_k of
    each landmark's plane in K0 (n_K, T_K) and s0 = C_IK,nom (r_L − r),

        λ = n_K·s0 / n_K·u,   q = T_K (s0 − λ u),
        G = λ [u × t_k − (t_k·u)/(n_K·u) u × n_K]_k J_l(θ)

    (the module's T λ (E − d nᵀ/nᵀd) C_KI (−Φ(u)) J_l(θ) with C_KI moved through). Returns θ̂ (R, 3)
    (and the converged flags with ``max_iterations``, as ``image_plane_kernel``).
    ``obs``: the rows' set (an ``ObservationSet``), ``s0`` (R, K, 3) its ``camera_vectors0``.
    DECISION: structure of arrays over the rows (as ``image_plane_kernel``): numpy's small-axis
    products ((R, K, 2, 3) einsums, batched 3 × 3 matmuls) cost more than the arithmetic.
    """
    from boresight.core.algorithms.ground_plane import landmark_plane_axes

    F = float(obs.focal_length_m)
    R = obs.runs
    img, tgt = obs.image_index, obs.target_index
    C = obs.nominal_camera_attitude()[:, img]  # (R, K, 3, 3) C_IK,nom
    up_g, T_g = landmark_plane_axes(obs)  # (R, T, 3), (R, T, 2, 3) in G
    CG = np.asarray(obs.C_GI)[img]  # (K, 3, 3)
    # two two-operand products (a three-operand einsum without a contraction path is ~10× slower)
    n_k = np.einsum("rvij,rvj->rvi", C, np.einsum("vjk,rvk->rvj", CG, up_g[:, tgt]))
    T_k = np.einsum("rvij,rvlj->rvli", C, np.einsum("vjk,rvlk->rvlj", CG, T_g[:, tgt]))
    nk = _soa(n_k)
    Tk = _soa(T_k)  # (K, 2, 3, R)
    S0 = _soa(s0)  # (K, 3, R)
    XY = _soa(obs.xy_m)  # (K, 2, R)
    spx, spy, spz = XY[:, 0], XY[:, 1], np.full_like(XY[:, 0], -F)
    ns0 = nk[:, 0] * S0[:, 0] + nk[:, 1] * S0[:, 1] + nk[:, 2] * S0[:, 2]
    theta = np.zeros((3, R))
    conv = _Convergence(R, iterations, max_iterations)
    for it in range(conv.n_max):
        ux, uy, uz, b, c = _rotated_soa(-theta, it, spx, spy, spz)  # u = exp(Φ(θ)) s′
        nu = nk[:, 0] * ux + nk[:, 1] * uy + nk[:, 2] * uz
        lam = ns0 / nu
        wx, wy, wz = S0[:, 0] - lam * ux, S0[:, 1] - lam * uy, S0[:, 2] - lam * uz
        # u × n_K
        cnx, cny, cnz = uy * nk[:, 2] - uz * nk[:, 1], uz * nk[:, 0] - ux * nk[:, 2], ux * nk[:, 1] - uy * nk[:, 0]
        rows = []
        for k in range(2):
            tx, ty, tz = Tk[:, k, 0], Tk[:, k, 1], Tk[:, k, 2]
            q = tx * wx + ty * wy + tz * wz
            f = (tx * ux + ty * uy + tz * uz) / nu
            g = (
                lam * ((uy * tz - uz * ty) - f * cnx),
                lam * ((uz * tx - ux * tz) - f * cny),
                lam * ((ux * ty - uy * tx) - f * cnz),
            )
            if it > 0:
                g = _times_right_jacobian(g, -theta, b, c)
            rows.append((*g, q))
        theta = theta + conv.update(_normal_equations_soa(rows).T, it).T
        if conv.done(it):
            break
    return conv.result(theta.T.copy())


def unit_vector_kernel(obs: Any, s0: np.ndarray, iterations: int = 2, *, max_iterations: int | None = None) -> Any:
    """Gauss-Newton on the unit-vector algorithm (Kiev 2012 eqs 29-31, ``algorithms.unit_vector``).

    e* = exp(−Φ(θ)) e0, e0 = s0/|s0|; T = [t1; t2] the module's tangent basis of e* (t1 the camera
    x axis made orthogonal to e*, t2 = e* × t1); q = T (e − e*), G = T Φ(e*) J_r(θ) = [−t2; t1] J_r(θ)
    (t1ᵀΦ(e*) = −t2ᵀ, t2ᵀΦ(e*) = t1ᵀ). Returns θ̂ (R, 3) (and the converged flags with
    ``max_iterations``, as ``image_plane_kernel``). Structure of arrays over the rows, as
    ``ground_plane_kernel``.
    """
    F = float(obs.focal_length_m)
    R = obs.runs
    S0 = _soa(s0)
    n0 = np.sqrt(S0[:, 0] * S0[:, 0] + S0[:, 1] * S0[:, 1] + S0[:, 2] * S0[:, 2])
    e0x, e0y, e0z = S0[:, 0] / n0, S0[:, 1] / n0, S0[:, 2] / n0
    XY = _soa(obs.xy_m)
    ns = np.sqrt(XY[:, 0] * XY[:, 0] + XY[:, 1] * XY[:, 1] + F * F)
    ex, ey, ez = XY[:, 0] / ns, XY[:, 1] / ns, -F / ns
    theta = np.zeros((3, R))
    conv = _Convergence(R, iterations, max_iterations)
    for it in range(conv.n_max):
        sx, sy, sz, b, c = _rotated_soa(theta, it, e0x, e0y, e0z)
        # tangent basis of e*: t1 = (x̂ − e*_x e*)/|…|, t2 = e* × t1
        ax, ay, az = 1.0 - sx * sx, -sx * sy, -sx * sz
        na = np.sqrt(ax * ax + ay * ay + az * az)
        t1x, t1y, t1z = ax / na, ay / na, az / na
        t2x, t2y, t2z = sy * t1z - sz * t1y, sz * t1x - sx * t1z, sx * t1y - sy * t1x
        dx, dy, dz = ex - sx, ey - sy, ez - sz
        rows = []
        for g, (tx, ty, tz) in (((-t2x, -t2y, -t2z), (t1x, t1y, t1z)), ((t1x, t1y, t1z), (t2x, t2y, t2z))):
            if it > 0:
                g = _times_right_jacobian(g, theta, b, c)
            rows.append((*g, tx * dx + ty * dy + tz * dz))
        theta = theta + conv.update(_normal_equations_soa(rows).T, it).T
        if conv.done(it):
            break
    return conv.result(theta.T.copy())


def weighted_kernel(
    obs: Any,
    algorithm: str,
    weighting: str,
    model: Any,
    iterations: int = 2,
    *,
    max_iterations: int | None = None,
    theta0_arcsec: Any = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """θ̂ (R, 3) arcsec, the reported variances (R, 3) arcsec² and the converged flags (R,) of
    ``boresight.estimate(obs, algorithm, weighting=weighting, model=model)`` run by run, batched.

    The library estimator does the math (``weighting="gls"``: the block-sparse campaign GLS of
    ``boresight.core.gls.campaign``, batched over runs; ``"diagonal"``: 1/total variance per residual with
    the sandwich covariance). This function only drives its Gauss-Newton iterations: one
    ``estimate(..., iterate=1, theta0_arcsec=θ)`` per step on the runs still iterating, so each
    run stops at the library's own criterion (``estimate.converged``: correction < 1e-6″) after at
    least ``iterations`` and at most ``max_iterations`` steps.
    DECISION: per-run freezing instead of one ``estimate(iterate=N)`` on the whole chunk, which
    re-linearises every run until the *slowest* one has converged: a run's result would then depend
    on the other runs of its chunk (at the round-off level), and the study's numbers on the chunk
    size. Each run's sequence of steps here depends on that run alone (the estimator is
    row-independent, ``tests/studies/test_montecarlo_weighting.py``). Without ``max_iterations`` every run
    takes exactly ``iterations`` steps and all are reported converged (as the unit kernels).
    ``theta0_arcsec`` (R, 3): the first linearisation point (default 0, as ``estimate``'s).
    ``ObservabilityError`` from the estimator propagates.
    """
    from boresight.core.estimation import TOLERANCE_RAD, estimate
    from orbits.rotations import ARCSEC

    R = obs.runs
    n_min = int(iterations)
    n_max = n_min if max_iterations is None else max(n_min, int(max_iterations))
    theta = np.zeros((R, 3)) if theta0_arcsec is None else np.array(np.broadcast_to(theta0_arcsec, (R, 3)), float)
    var = np.zeros((R, 3))
    converged = np.zeros(R, bool)
    active = np.arange(R)
    for it in range(n_max):
        sub = obs if active.size == R else obs.run(active)
        est = estimate(sub, algorithm, weighting=weighting, model=model, iterate=1, theta0_arcsec=theta[active])
        previous = theta[active]
        theta[active] = est.theta.to_value("arcsec").reshape(-1, 3)
        var[active] = np.diagonal(est.covariance.to_value("arcsec2").reshape(-1, 3, 3), axis1=-2, axis2=-1)
        ok = np.asarray(est.converged, bool).reshape(-1)
        if est.effects:
            # DECISION: effects floated (estimate's default on star and landmark rows) restart at 0 in each
            # one-step fit (estimate takes a θ0 only), so a step's correction always holds theirs: a run has
            # converged when θ stops moving (< 1e-6″). θ then differs from estimate(iterate=True)'s by the
            # effects' second-order linearisation, ~5e-5″ for a 50 m GNSS bias on stars-and-landmarks (1e-4 σ).
            ok |= np.max(np.abs(theta[active] - previous), axis=1) < TOLERANCE_RAD / ARCSEC
        converged[active] = ok
        if max_iterations is not None and it + 1 >= n_min:
            active = active[~ok]
            if active.size == 0:
                break
    if max_iterations is None:
        converged[:] = True
    return theta, var, converged


class _CachedObs:
    """An ``ObservationSet`` proxy whose θ-independent per-image arrays are computed once.

    The algorithms' ``linearize`` call ``nominal_camera_attitude()`` (a quaternion → DCM conversion
    per image) on every Gauss-Newton iteration; a Monte Carlo chunk needs it once. Each name in
    ``_CACHED`` becomes an attribute of the proxy holding a memoised zero-argument method of the
    wrapped set; anything else is looked up on the set (its rows, tables and row gathers).
    DECISION: the names are checked when the proxy is built — a renamed method is an
    ``AttributeError`` naming it, never a proxy that silently stops caching.
    """

    _CACHED = ("attitude_st", "nominal_camera_attitude")

    def __init__(self, obs: Any) -> None:
        missing = [n for n in self._CACHED if not callable(getattr(type(obs), n, None))]
        if missing:
            raise AttributeError(f"_CachedObs: {type(obs).__name__} has no method(s) {missing}; update _CachedObs._CACHED")
        self._obs = obs
        for name in self._CACHED:
            setattr(self, name, functools.cache(getattr(obs, name)))

    def __getattr__(self, name: str) -> Any:  # only called for names not set in __init__
        return getattr(self.__dict__["_obs"], name)


def gauss_newton(obs: Any, linearize: Any, iterations: int = 2) -> np.ndarray:
    """θ̂ (R, 3) by unit-weight Gauss-Newton from θ0 = 0 on any algorithm's ``linearize(obs, θ)``.

    Each step accumulates eq 18's B = Σ GᵀG, y = Σ Gᵀq and solves the 3 × 3 system per run.
    DECISION: a plain batched ``solve`` instead of ``NormalEquations.solve``: its per-run
    eigen-decomposition (condition number, weak axis) is 70 % of the time of a Monte Carlo
    chunk; a singular run shows up as a non-finite θ̂ and is counted (``nonfinite``).
    """
    o = _CachedObs(obs)
    R = obs.runs
    theta = np.zeros((R, 3))
    for _ in range(iterations):
        G, q = linearize(o, theta)
        G = G.reshape(R, -1, 3)
        B = np.matmul(np.swapaxes(G, 1, 2), G)
        y = np.einsum("rki,rk->ri", G, q.reshape(R, -1))
        theta = theta + _solve3(B, y)
    return theta


def kalman_theta_kernel(
    s0: np.ndarray, xy_m: np.ndarray, row_start: Any, focal_length_m: float, W: Any, sigma0_rad: Any, iterations: int = 3
) -> Any:
    """Iterated Kalman filter for θ (Kiev 2012 eq 32, A = 0), information form, batched.

    ``s0`` (R, K, 3) = C_SK,nom A (r_L − r) of each row; ``xy_m`` (R, K, 2); ``row_start`` (N + 1,)
    the rows' CSR offsets (image n's rows ``row_start[n]:row_start[n + 1]``, m_n of them);
    ``W``: N blocks (2m_n, 2m_n), the inverse of each image's residual covariance R_n over its rows
    [x₁, y₁, x₂, …] (``studies.montecarlo.preflight.kalman_setup``, at the nominal geometry, shared by all runs);
    ``sigma0_rad``: prior σ of θ (scalar or (3,)), prior mean 0. Per image n, ``iterations``
    IEKF steps about the current estimate: with H, r the Algorithm 3 Jacobian and residual at
    x_lin, P⁺ = (P⁻⁻¹ + Hᵀ W H)⁻¹, x⁺ = x⁻ + P⁺ Hᵀ W (r + H (x_lin − x⁻)) — algebraically the
    Joseph-form update of ``algorithms.kalman.kalman_filter`` (tested against it).
    Returns the θ history (R, N, 3) and the posterior covariance history (R, N, 3, 3).

    DECISION: structure of arrays — every quantity is a stack of length-R vectors with the run
    axis last (θ as (3, R), H as (2m_n, 3, R)), the 3 × 3 and 2 × 3 algebra written out component
    by component and W H as one broadcast product summed in a fixed order (not a BLAS product:
    gemm's edge kernels round differently with the width, which would break the bit-for-bit
    chunk invariance). numpy's batched small-matrix
    routines (matmul, einsum, inv over (R, 3, 3)) spend more time per matrix than the arithmetic;
    here every call works on contiguous runs. 4-5× faster than the array-of-structures version.
    """
    R = s0.shape[0]
    start = np.asarray(row_start)
    N = start.size - 1
    F = float(focal_length_m)
    S0 = _soa(s0)  # (K, 3, R)
    XY = _soa(xy_m)  # (K, 2, R)
    sig0 = np.broadcast_to(np.asarray(sigma0_rad, float), (3,))
    # information matrix as its 6 unique components (00, 01, 02, 11, 12, 22), each (R,)
    info = [
        np.full(R, 1.0 / sig0[0] ** 2),
        np.zeros(R),
        np.zeros(R),
        np.full(R, 1.0 / sig0[1] ** 2),
        np.zeros(R),
        np.full(R, 1.0 / sig0[2] ** 2),
    ]
    x = np.zeros((3, R))
    xh = np.empty((R, N, 3))
    Ph6 = np.empty((N, 6, R))  # posterior covariance, 6 unique components per image
    P = None
    for n in range(N):
        a, b = int(start[n]), int(start[n + 1])
        m = b - a
        x_prior, info_prior = x, info
        if m == 0:
            P = P if P is not None else _inv6(info)
            xh[:, n], Ph6[n] = x.T, P
            continue
        Wn = np.ascontiguousarray(W[n])  # (2m, 2m)
        if Wn.shape != (2 * m, 2 * m):
            raise InputValueError(
                f"kalman_theta_kernel: image {n} has {m} rows, its weight block W[{n}] is {Wn.shape}, not ({2 * m}, {2 * m})"
            )
        K = 2 * m
        sx0, sy0, sz0 = S0[a:b, 0], S0[a:b, 1], S0[a:b, 2]  # (m, R)
        xm, ym = XY[a:b, 0], XY[a:b, 1]
        x_lin = x_prior
        for _ in range(iterations):
            sx, sy, sz, _, aj, bj = rotate_soa(x_lin, sx0, sy0, sz0)
            px, py, g = _image_plane_soa(sx, sy, sz, F)
            r: Any = np.empty((m, 2, R))
            np.add(xm, F * px, out=r[:, 0])
            np.add(ym, F * py, out=r[:, 1])
            r = r.reshape(K, R)
            # H = G J_r(θ), G = P Φ(s) (``_image_plane_G``) with f = −F/sz: rows in units of F
            H: Any = np.empty((m, 2, 3, R))
            for row, gk in enumerate(g):
                H[:, row, 0], H[:, row, 1], H[:, row, 2] = _times_right_jacobian(gk, x_lin, aj, bj)
            H = H.reshape(K, 3, R)
            # W symmetric: (Hᵀ W)ᵀ = W H, summed term by term. DECISION: not a BLAS product —
            # gemm's edge kernels round differently with the width, which would break the
            # bit-for-bit chunk invariance; elementwise multiply-adds are exact per run.
            # Σ_l W[k, l] H[l], accumulated over l in order (no (K, K, 3, R) temporary)
            WT = Wn.T
            HtW = WT[0][:, None, None] * H[0]
            tmp = np.empty_like(HtW)
            for l in range(1, K):
                np.multiply(WT[l][:, None, None], H[l], out=tmp)
                HtW += tmp  # (K, 3, R)
            # the unique entries of Hᵀ W H, each summed over k in order (6 × (R,))
            inc = [_sum0(HtW[:, i] * H[:, j]) for i, j in zip(_PI, _PJ)]
            info_post = [info_prior[q] + inc[q] for q in range(6)]
            P = _inv6(info_post)
            dx = x_lin - x_prior
            y = r + H[:, 0] * dx[0] + H[:, 1] * dx[1] + H[:, 2] * dx[2]
            g = _sum0(HtW * y[:, None, :])  # (3, R)
            x_post = x_prior + np.stack(
                [
                    P[0] * g[0] + P[1] * g[1] + P[2] * g[2],
                    P[1] * g[0] + P[3] * g[1] + P[4] * g[2],
                    P[2] * g[0] + P[4] * g[1] + P[5] * g[2],
                ]
            )
            x_lin = x_post
        x, info = x_post, info_post
        xh[:, n], Ph6[n] = x.T, P
    return xh, _full3(np.moveaxis(Ph6, 0, -1)).reshape(R, N, 3, 3)


_PI = np.array([0, 0, 0, 1, 1, 2])
_PJ = np.array([0, 1, 2, 1, 2, 2])


def _sum0(a: np.ndarray) -> Any:
    """Sum over the first axis in a fixed sequential order.

    ``a.sum(0)`` switches to pairwise summation when the first axis happens to be contiguous
    (one run: shape (K, 1)), which would make a one-run chunk round differently.
    """
    acc = a[0].copy()
    for k in range(1, a.shape[0]):
        acc += a[k]
    return acc


def _full3(p: Any) -> Any:
    """(R, 3, 3) from 6 symmetric components."""
    return np.stack([p[0], p[1], p[2], p[1], p[3], p[4], p[2], p[4], p[5]], axis=-1).reshape(-1, 3, 3)
