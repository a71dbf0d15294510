"""The estimators' side of the effects catalogue: predictions, offsets and Jacobians by name.

``effect_columns(obs, θ, names, params)`` evaluates the exact measurement model of
``orbits.effects`` with the named effects at parameter values p,

    xy(θ, p) = D_p( −F (s_x, s_y)/s_z ),
    s = exp(−Φ(θ + φ(p))) C_SK,nom exp(−Φ(ε(p))) A_rep (C_GI (r_L,cat − Δr_L(p)) − (r_rep − Δr(p)))

(the inverse of the simulator's forward perturbation, from the same bases), and returns the
offset ``xy(θ, p) − xy(θ, 0)`` and the exact Jacobian ∂xy/∂p by the chain rule:

* image stage (``focal_scale``, ``radial_distortion``, ``principal_point``): the maps' own
  derivatives, chained through the later maps;
* misalignment (``thermal``, ``alignment_drift``, φ = B p): ∂xy/∂p = D P Φ(s) J_r(θ + φ) B, with P the projection
  Jacobian and J_r the SO(3) right Jacobian (``orbits.rotations.right_jacobian``);
* star tracker (``time_tag``, ``aberration``, ε = B p): ∂xy/∂p = D P M Φ(w) J_r(ε) B, with
  M = exp(−Φ(θ + φ)) C_SK,nom and w = exp(−Φ(ε)) A_rep (r_L − r);
* position (``gnss_bias``, Δr = B p): ∂xy/∂p = D P C_IK B;
* landmark (``landmark_height_bias``, Δr_L = B p): ∂xy/∂p = −D P C_IK C_GI B.

A star row (``docs/stars.md``) has s = exp(−Φ(θ + φ)) C_SK,nom exp(−Φ(ε)) A_rep u_k: the image,
misalignment and star-tracker stages as above with w = exp(−Φ(ε)) A_rep u_k, and no position or
landmark stage (their columns are 0 on star rows: ``gnss_bias`` and ``landmark_height_bias`` cannot
act on a star, which is how star frames separate them from θ).

where D = ∂x/∂x0 of the image chain. Because the bases depend only on reported quantities, the
model is exact: noise-free data simulated with an effect are fitted by θ plus that effect to
round-off (``tests/core/test_effects.py``).

Inputs the bases need beyond attitude, position and catalogue:

* velocity (``thermal``, ``aberration``, ``gnss_bias``): ``obs.velocity_i_m_s()`` when the
  ObservationSet provides it (the file's GNSS velocity, else one derived from dense positions by
  ``boresight.observations.velocity``, the one derivation); else ``obs.v_sc_i_m_s``. None →
  status ``"needs velocity"``.
* attitude about each image (``time_tag``, which needs A_rep at t − dt): from the pass's sequence
  of reported star-tracker attitudes (``attitude_polynomial``: the quartic least-squares
  polynomial through the rotation vectors of up to 7 neighbouring images of the pass, relative to
  that image, evaluated at −dt; its first coefficient is the rate); a single-image
  pass falls back on the nadir-pointing rate r × v/|r|² when a velocity is known, else the status
  is ``"needs attitude rate"``.

Example
-------
>>> import numpy as np
>>> from boresight import simulate
>>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0))
>>> cols = effect_columns(obs, obs.truth["theta_rad"], ["focal_scale", "principal_point"])
>>> cols.jacobian.shape, cols.labels
((1, 40, 2, 3), ('focal_scale.scale', 'principal_point.x_m', 'principal_point.y_m'))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from astropy import units as u

from boresight.core.measurement import observation_rows, projection_jacobian
from boresight.errors import UnknownEffectError
from orbits import effects as fx
from orbits.camera import project
from orbits.effects import EFFECTS, EffectContext, EffectError
from orbits.rotations import misalignment_dcm, right_jacobian, rotvec_dcm, skew

__all__ = [
    "EffectColumns",
    "EffectError",
    "UnknownEffectError",
    "effect_names",
    "check_effect_names",
    "effect_columns",
    "attitude_rate",
    "attitude_polynomial",
    "observation_velocity",
]

STATUS_OK = "ok"
STATUS_NEEDS_VELOCITY = "needs velocity"
STATUS_NEEDS_RATE = "needs attitude rate"
#: images per pass used by the derivative of the attitude sequence (and the velocity fallback)
STENCIL = 7
#: polynomial degree of that derivative (Savitzky–Golay: least squares on the STENCIL images)
# DECISION: 7 images, degree 4. The interpolating degree 6 is ~30× more exact noise-free (1e-6
# vs 4e-5 relative on the 6-pass campaign) but passes 4× more star-tracker noise into the rate
# (26 % of the orbital rate in its dense nadir passes): a time_tag column made of noise would
# look separable where physics says it is not. 4e-5 of the rate is 0.002″ at dt = 20 ms.
DEGREE = 4


def effect_names() -> list[str]:
    """The catalogue's effect names, in the order the forward model applies them.

    >>> effect_names()[:3]
    ['time_tag', 'focal_scale', 'principal_point']
    """
    return list(EFFECTS)


def check_effect_names(names: Any) -> list[str]:
    """``names`` (a list, or one comma-separated string) checked against the catalogue: an
    ``UnknownEffectError`` lists the valid names (the one check of ``estimate --effects``,
    ``diagnose --candidates`` and ``catalogue_candidates``)."""
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    names = list(names)
    bad = [n for n in names if n not in EFFECTS]
    if bad:
        hint = ""
        if any(b in fx.UNMODELLED for b in bad):
            hint = " (tangential distortion and local catalogue shifts are deliberately outside the catalogue)"
        else:
            from orbits.errors import did_you_mean

            hint = "".join(did_you_mean(b, EFFECTS) for b in bad)
        raise UnknownEffectError(f"unknown effect(s) {bad}{hint}; valid names: {', '.join(EFFECTS)}")
    if len(set(names)) != len(names):
        raise UnknownEffectError(f"effect names repeated in {names}")
    checked: list[str] = names
    return checked


@dataclass(frozen=True)
class EffectColumns:
    """Offsets and Jacobian columns of named effects (``effect_columns``).

    One row per observation. ``offset (R, K, 2) m: xy(θ, p) − xy(θ, 0); ``jacobian`` (R, K, 2, K):
    ∂xy/∂p at (θ, p), metres per unit of each parameter (``units``); ``labels`` (K,)
    ``"effect.param"``; ``units`` (K,) astropy units; ``scales`` (K,) a typical size per
    parameter (for conditioning); ``status`` {name: "ok" | "needs velocity" | "needs attitude
    rate"} — the columns and offset of an effect that is not "ok" are zero; ``slices`` {name:
    slice of K}; ``predicted`` (R, K, 2) xy(θ, p); ``theta_jacobian`` (R, K, 2, 3) ∂xy/∂θ at
    (θ, p) in m/rad; ``notes`` {name: where its context came from}.
    """

    offset: np.ndarray
    jacobian: np.ndarray
    labels: tuple[str, ...]
    units: tuple[str, ...]
    scales: np.ndarray
    status: dict[str, str]
    slices: dict[str, slice]
    predicted: np.ndarray
    theta_jacobian: np.ndarray
    notes: dict[str, str]


# ---------------------------------------------------------------------------- context


def _polynomial_weights(
    t_s: Any, pass_index: Any, n_points: int = STENCIL, degree: int | None = DEGREE
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stencils (N, S), coefficient weights (N, D, S) and ``ok`` (N,) of the least-squares
    polynomial of ``degree`` (default DEGREE; None: the interpolating one) through up to
    ``n_points`` images of each image's pass nearest in time (centred where the pass allows):
    for values y_k at the stencil, the polynomial about t_n is Σ_j c_j (t − t_n)^j with
    c_j = Σ_k W[n, j−1, k] y_k, j = 1…D (the constant term is left out: it is 0 for rotation
    vectors relative to image n). Images alone in their pass get weights 0 and ``ok`` False.

    The derivative weights W[:, 0] are the minimum-norm solution of the moment conditions
    Σ_k w_k (t_k − t_n)^j = δ_j1, j ≤ degree (Savitzky–Golay; a Vandermonde solve when degree =
    S − 1), in times scaled by the stencil's span for conditioning. Star-tracker noise σ_δ per
    image enters the rate as σ_δ ‖W[:, 0]‖ per axis.
    """
    t = np.asarray(t_s, float)
    pidx = np.asarray(pass_index)
    n = t.size
    S = n_points
    D = S - 1 if degree is None else degree
    idx = np.tile(np.arange(n)[:, None], (1, S))
    W = np.zeros((n, D, S))
    ok = np.zeros(n, bool)
    for p in np.unique(pidx):
        sel = np.flatnonzero(pidx == p)
        sel = sel[np.argsort(t[sel], kind="stable")]
        k = min(S, sel.size)
        if k < 2:
            continue
        start = np.clip(np.arange(sel.size) - k // 2, 0, sel.size - k)
        st = sel[start[:, None] + np.arange(k)]  # (n_p, k)
        ts = t[st] - t[sel][:, None]
        h = np.abs(ts).max(axis=1, keepdims=True)
        d = min(D, k - 1)
        V = (ts / h)[:, None, :] ** np.arange(d + 1)[None, :, None]  # V[i, j, a] = τ_a^j
        # least-squares coefficients (V Vᵀ)⁻¹ V, the minimum-norm moment solution
        C = np.linalg.solve(V @ np.swapaxes(V, 1, 2), V)  # (n_p, d + 1, k)
        for j in range(1, d + 1):
            W[sel, j - 1, :k] = C[:, j, :] / h**j
        idx[sel, :k] = st
        ok[sel] = True
    return idx, W, ok


def _lagrange_derivative_weights(
    t_s: Any, pass_index: Any, n_points: int = STENCIL, degree: int | None = DEGREE
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stencils (N, S), derivative weights (N, S) and ``ok``: ``_polynomial_weights``' c_1."""
    idx, W, ok = _polynomial_weights(t_s, pass_index, n_points, degree)
    return idx, W[:, 0], ok


def attitude_polynomial(obs: Any, n_points: int = STENCIL, degree: int | None = DEGREE) -> tuple[np.ndarray, np.ndarray]:
    """The reported star-tracker attitude about each image as a polynomial rotation (R, N, 3, D).

    At image n, φ_k = −log(A_k A_nᵀ) (so that A_k = exp(−Φ(φ_k)) A_n) for up to ``n_points``
    images k of the same pass; the degree-``degree`` least-squares polynomial through (t_k, φ_k)
    gives A(t_n + τ) ≈ exp(−Φ(Σ_j c_j τ^j)) A_n, c_j in rad/s^j (star-tracker axes). c_1 is the
    angular rate ω_S (the derivative of the log map at 0 is the identity, so the polynomial is
    the only approximation). Returns ``(coefficients, ok)``, ``ok`` (N,) False for images alone in
    their pass (coefficients 0 there).
    """
    from scipy.spatial.transform import Rotation

    idx, W, ok = _polynomial_weights(obs.t_s, obs.pass_index, n_points, degree)
    A = obs.attitude_st()  # (R, N, 3, 3)
    rel = A[:, idx] @ np.swapaxes(A, -1, -2)[:, :, None]  # (R, N, S, 3, 3) = A_k A_nᵀ
    phi = -Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(rel.shape[:-2] + (3,))
    return np.einsum("njs,rnsi->rnij", W, phi), ok


def attitude_rate(obs: Any, n_points: int = STENCIL, degree: int | None = DEGREE) -> tuple[np.ndarray, np.ndarray]:
    """Star-tracker angular rate ω_S (R, N, 3) rad/s in its own axes from the reported attitudes:
    c_1 of ``attitude_polynomial``. Returns ``(rate, ok)``."""
    c, ok = attitude_polynomial(obs, n_points, degree)
    return c[..., 0], ok


def observation_velocity(obs: Any) -> tuple[np.ndarray | None, str]:
    """(velocity (R, N, 3) or None, where it came from)."""
    f = getattr(obs, "velocity_i_m_s", None)
    if callable(f):
        v = f()
        return v, str(getattr(obs, "velocity_status", "ObservationSet.velocity_i_m_s()"))
    v = getattr(obs, "v_sc_i_m_s", None)
    if v is not None:
        return np.asarray(v, float), "given"
    # DECISION: velocity is derived from positions in one place, ``boresight.observations.velocity``
    # (Legendre least squares with a stated criterion), reached through ``obs.velocity_i_m_s()``;
    # an object without either has no velocity here (the effect's status says so).
    return None, "no velocity in the data (an ObservationSet derives one from dense positions)"


def _context(obs: Any, names: Any) -> tuple[Any, Any, Any]:
    """EffectContext for ``names`` and per-effect status / notes."""
    need_v = any(EFFECTS[n].needs_velocity or EFFECTS[n].needs_attitude_rate for n in names)
    v, v_note = observation_velocity(obs) if need_v else (None, "")
    poly, rate_note = None, ""
    if any(EFFECTS[n].needs_attitude_rate for n in names):
        poly, ok = attitude_polynomial(obs)
        rate_note = "attitude from the star-tracker quaternion sequence of each pass (quartic about each image)"
        if not ok.all():
            if v is not None:
                # DECISION: a single-image pass has no rate from its quaternions; assume nadir pointing
                # (the body turns with the orbital frame, ω_I = r × v/|r|², a constant axis: exact) and say so.
                r = obs.r_sc_i_m
                w_i = np.cross(r, v) / np.sum(r * r, axis=-1, keepdims=True)
                w_s = np.einsum("rnij,rnj->rni", obs.attitude_st(), w_i)
                nadir = np.zeros_like(poly)
                nadir[..., 0] = w_s
                poly = np.where(ok[None, :, None, None], poly, nadir)
                rate_note += f"; {int((~ok).sum())} single-image pass image(s): nadir-pointing rate from the velocity"
            else:
                poly = None
                rate_note = "no attitude rate: single-image passes and no velocity"
    ctx = EffectContext(
        focal_length_m=float(obs.focal_length_m),
        C_SK=np.asarray(obs.C_SK_nominal, float),
        C_IS=obs.attitude_st(),
        r_i_m=np.asarray(obs.r_sc_i_m, float),
        landmark_g_m=np.asarray(obs.landmark_g_m, float),
        C_GI=np.asarray(obs.C_GI, float),
        v_i_m_s=v,
        attitude_poly_s=poly,
        t_s=np.asarray(obs.t_s, float),
    )
    status, notes = {}, {}
    for n in names:
        e = EFFECTS[n]
        if e.needs_attitude_rate and poly is None:
            status[n] = STATUS_NEEDS_RATE
        elif e.needs_velocity and v is None:
            status[n] = STATUS_NEEDS_VELOCITY
        else:
            status[n] = STATUS_OK
        notes[n] = "; ".join(
            x for x in ((f"velocity: {v_note}" if e.needs_velocity else ""), (rate_note if e.needs_attitude_rate else "")) if x
        )
    return ctx, status, notes


def _params_si(names: Any, params: Any, runs: int) -> dict[str, np.ndarray]:
    out = {}
    params = params or {}
    bad = [k for k in params if k not in names]
    if bad:
        raise UnknownEffectError(f"params given for effect(s) {bad} not among the names {names}")
    for n in names:
        e = EFFECTS[n]
        if n not in params or params[n] is None:
            out[n] = np.zeros((runs, e.n_params))
            continue
        v: Any = params[n]
        if isinstance(v, u.Quantity):
            q: Any = np.atleast_1d(v)  # still a Quantity (atleast_1d keeps the subclass)
            try:
                v = (
                    np.stack([q[..., j].to_value(e.unit[j]) for j in range(e.n_params)], axis=-1)
                    if v.ndim
                    else v.to_value(e.unit[0])
                )
            except (u.UnitsError, IndexError) as exc:
                raise EffectError(
                    f"effect_columns: params[{n!r}] = {v!r} cannot be read as {list(e.param_names)} in {[str(x) for x in e.unit]}: {exc}"
                ) from None
        v = np.atleast_1d(np.asarray(v, float))
        if v.shape[-1] != e.n_params or v.ndim > 2 or (v.ndim == 2 and v.shape[0] not in (1, runs)):
            raise EffectError(
                f"effect_columns: params[{n!r}] must have shape ({e.n_params},) or ({runs}, {e.n_params}), got {v.shape}"
            )
        if not np.all(np.isfinite(v)):
            raise EffectError(f"effect_columns: params[{n!r}] must be finite, got {v.tolist()!r}")
        out[n] = np.broadcast_to(v * e.si, (runs, e.n_params)).copy()
    return out


# ---------------------------------------------------------------------------- model


def _relative(obs: Any, L: Any, r: Any, ni: Any, mi: Any) -> tuple[np.ndarray, np.ndarray]:
    """The inertial target vector of each observed pair (R, n_obs, 3) — C_GI r_L − r of the effects' catalogue L
    and positions r (``ObservationSet.landmark_vectors_i``: with the set's landmark sight), or a star row's apparent
    direction (no position or landmark stage) — and the star rows (n_obs,)."""
    star: np.ndarray = ~obs.landmark_rows(mi)
    if not star.any():
        lm_only: np.ndarray = obs.landmark_vectors_i(ni, mi, landmark_g_m=L, r_sc_i_m=r)
        return lm_only, star
    rel = np.empty((np.shape(r)[0], np.size(ni), 3))
    rel[:, ~star] = obs.landmark_vectors_i(ni[~star], mi[~star], landmark_g_m=L, r_sc_i_m=r)
    rel[:, star] = obs.star_directions_i(ni[star], mi[star])[None]
    return rel, star


def _model(obs: Any, theta: Any, names: Any, p_si: Any, ctx: Any, jacobian: bool) -> Any:
    """xy(θ, p) (R, K, 2) and, with ``jacobian``, (∂xy/∂θ, {name: ∂xy/∂p_si}), one row per
    observation: gathers of the image and target tables (cost ∝ observations, no images × targets array).
    """
    R = obs.runs
    F = float(obs.focal_length_m)
    ni, mi = observation_rows(obs)  # the observations' images and targets, (K,)
    dvals = {}

    def stage(name: str) -> np.ndarray | None:
        total: np.ndarray | None = None
        for n in names:
            e = EFFECTS[n]
            if e.stage == name:
                v, dvals[n] = e.stage_value(ctx, p_si[n])
                total = v if total is None else total + v
        return total

    L = obs.landmark_g_m
    dL = stage("landmark")
    if dL is not None:
        L = L - dL
    r = obs.r_sc_i_m
    dr = stage("position")
    if dr is not None:
        r = r - dr
    A = ctx.C_IS
    eps = stage("star_tracker")
    if eps is not None:
        A = rotvec_dcm(-eps) @ A
    phi = stage("misalignment")
    th = np.broadcast_to(theta[:, None, :], (R, obs.n_images, 3)) if phi is None else theta[:, None, :] + phi
    Mx = misalignment_dcm(th) @ ctx.C_SK  # (R, N, 3, 3)
    C_IK = (Mx @ A)[:, ni]  # (R, n_obs, 3, 3)
    rel, star = _relative(obs, L, r, ni, mi)
    s = np.einsum("roij,roj->roi", C_IK, rel)
    x0 = project(s, F)

    if not jacobian:
        return fx.apply_image_chain(x0, names, p_si, F)
    x, D, jp = fx.apply_image_chain(x0, names, p_si, F, jacobian=True)
    Dh = D @ projection_jacobian(s, F)  # (R, n_obs, 2, 3)
    G_theta = Dh @ skew(s) @ right_jacobian(th)[:, ni]
    cols = {}
    for n in names:
        e = EFFECTS[n]
        if e.stage == "image":
            cols[n] = jp[n]
            continue
        B = dvals[n]  # ∂(stage quantity)/∂p_si
        if e.stage == "misalignment":
            cols[n] = G_theta @ B[:, ni]
        elif e.stage == "star_tracker":
            w = np.einsum("roij,roj->roi", A[:, ni], rel)
            Je = right_jacobian(eps)  # d[exp(−Φ(ε)) w] = Φ(w') J_r(ε) dε
            cols[n] = Dh @ Mx[:, ni] @ skew(w) @ (Je @ B)[:, ni]
        elif e.stage == "position":
            cols[n] = np.where(star[None, :, None, None], 0.0, Dh @ (C_IK @ B[:, ni]))
        elif e.stage == "landmark":
            cols[n] = np.where(star[None, :, None, None], 0.0, -Dh @ (C_IK @ obs.C_GI[ni] @ B[:, mi]))
    return x, G_theta, cols


def effect_columns(obs: Any, theta_rad: Any, names: Any, params: Any = None) -> EffectColumns:
    """Offsets and Jacobian columns of the named effects at θ and p (interface 3).

    Parameters
    ----------
    obs : ObservationSet
    theta_rad : (3,) or (R, 3) misalignment (rad) about which to evaluate.
    names : effect names (a list, or a comma-separated string); an unknown name raises
        ``UnknownEffectError`` listing the valid ones.
    params : {name: (k,) or (R, k) values in the effect's units (or a Quantity)}; missing → 0.

    Returns ``EffectColumns``; the Jacobian is exact at (θ, p) and in metres per unit of each
    parameter. Vectorised over runs and observations.
    """
    names = check_effect_names([] if names is None else names)
    R = obs.runs
    try:
        theta = np.broadcast_to(np.asarray(theta_rad, float), (R, 3))
    except ValueError:
        raise EffectError(f"effect_columns: theta_rad must have shape (3,) or ({R}, 3), got {np.shape(theta_rad)}") from None
    if not np.all(np.isfinite(theta)):
        raise EffectError(f"effect_columns: theta_rad must be finite, got {np.asarray(theta_rad).tolist()!r}")
    p_si = _params_si(names, params, R)
    ctx, status, notes = _context(obs, names)
    active = [n for n in names if status[n] == STATUS_OK]
    pred, G_theta, cols = _model(obs, theta, active, p_si, ctx, jacobian=True)
    if any(np.any(p_si[n] != 0) for n in active):
        offset = pred - _model(obs, theta, [], p_si, ctx, jacobian=False)
    else:
        offset = np.zeros_like(pred)
    K = sum(EFFECTS[n].n_params for n in names)
    J = np.zeros(pred.shape + (K,))
    labels: list[str] = []
    units: list[str] = []
    scales: list[float] = []
    slices: dict[str, slice] = {}
    k = 0
    for n in names:
        e = EFFECTS[n]
        sl = slice(k, k + e.n_params)
        slices[n] = sl
        if n in cols:
            J[..., sl] = cols[n] * e.si  # per unit of the parameter
        labels += e.labels
        units += e.unit
        scales += e.scale
        k += e.n_params
    return EffectColumns(
        offset=offset,
        jacobian=J,
        labels=tuple(labels),
        units=tuple(units),
        scales=np.array(scales, float),
        status=status,
        slices=slices,
        predicted=pred,
        theta_jacobian=G_theta,
        notes=notes,
    )
