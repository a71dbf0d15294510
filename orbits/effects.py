"""The effects catalogue: physical effects a calibration model may miss, each written once.

Every effect is a small, named perturbation of one stage of the measurement model (Kiev 2012
eqs 3, 20, 24 with the project's conventions):

    xy = D( −F (s_x, s_y)/s_z ),     s = exp(−Φ(θ + φ)) C_SK,nom A_true (C_GI r_L,true − r_true)

* ``misalignment`` stage — a rotation φ (camera axes) added to θ: ``thermal``, ``alignment_drift``.
* ``star_tracker`` stage — the reported attitude is ``A_rep = exp(Φ(ε)) A_true`` with ε in
  star-tracker axes (the sign of the Kiev 2012 star-tracker error δ): ``time_tag``, ``aberration``.
* ``position`` stage — the reported GNSS position is ``r_rep = r_true + Δr``: ``gnss_bias``.
* ``landmark`` stage — the catalogue is ``r_L,cat = r_L,true + Δr_L`` (Earth-fixed): ``landmark_height_bias``.
* ``image`` stage — the camera maps the ideal point x0 = −F s_xy/s_z (nominal F) to the measured
  point through D, applied in catalogue order: ``focal_scale`` (x ← (1 + s) x),
  ``radial_distortion`` (``x ← x (1 + k1 |x|²/F²)``), ``principal_point`` (x ← x + c).

For the four non-image stages the perturbation is (but for ``time_tag``) *linear in the parameters* with a basis that
depends only on reported quantities (the "context": reported attitude, position, velocity,
catalogue, attitude rate): φ, ε, Δr, Δr_L = B(context) p. That one basis is the single
definition of the effect: the simulator applies it forward (``forward_*``: from the truth to
what the sensors report, solving the implicit relation "the context is the reported quantity"
by fixed-point iteration), and the estimators invert it exactly (``boresight.core.effect_model``:
A_true = exp(−Φ(ε)) A_rep, r_true = r_rep − Δr, …) and differentiate it for the Jacobian. The
image stage is a chain of exact maps with analytic derivatives, used by both sides.

DECISION: contexts are built from *reported* quantities on both sides (the RTN frame of the
reported orbit, the reported star-tracker attitude, the catalogue's own vertical), so that
noise-free simulated data are fitted by θ plus the effect to round-off. The physical definition
with true quantities differs at second order (``|Δr|/|r|`` ≈ 1e-5 of the effect). The one exception
is ``time_tag``, not linear in dt: the exact shift A_rep(t) = A_true(t + dt), which the simulator
evaluates with the attitude law (``orbits.scenario``) and the estimator with the polynomial of the
reported quaternion sequence (``boresight.core.effect_model.attitude_polynomial``) through
``Effect.value``.

Out-of-catalogue perturbations for tests (``UNMODELLED``: tangential distortion, a local shift of
part of the landmark catalogue) are deliberately *not* effects: nothing fits them, so a diagnosis
must report them as unexplained structure.

Example
-------
>>> sorted(EFFECTS)[:3]
['aberration', 'alignment_drift', 'alignment_step']
>>> EFFECTS["gnss_bias"].param_names
('radial_m', 'along_track_m', 'cross_track_m')
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Callable

import numpy as np

from .errors import EffectError, MissingContextError
from .sight import SPEED_OF_LIGHT_M_S  # the one definition (the star tracker's aberration uses it here)

__all__ = [
    "Effect",
    "EffectError",
    "MissingContextError",
    "EFFECTS",
    "EffectContext",
    "EffectSizes",
    "SPEED_OF_LIGHT_M_S",
    "STAGES",
    "UNMODELLED",
    "Unmodelled",
    "TangentialDistortion",
    "LandmarkShift",
    "argument_of_latitude",
    "rtn_basis",
    "effect_sizes",
    "apply_image_chain",
    "LineEffect",
    "LINE_EFFECTS",
    "line_scan_truth",
    "line_catalogue_markdown",
]

#: stages in the order the forward model applies them
STAGES = ("landmark", "position", "star_tracker", "misalignment", "image")
#: star-tracker boresight in its own axes (+z_S, the usual convention of star-tracker outputs)
STAR_TRACKER_BORESIGHT_S = np.array([0.0, 0.0, 1.0])


# ---------------------------------------------------------------------------- context


@dataclass
class EffectContext:
    """What an effect's basis may depend on (reported quantities, leading run axis R).

    ``focal_length_m``; ``C_SK`` (3, 3) nominal star tracker → camera; ``C_IS`` (R, N, 3, 3)
    reported star-tracker attitude; ``r_i_m`` (R, N, 3) reported position; ``v_i_m_s``
    (R, N, 3) velocity or None; ``attitude_poly_s`` (R, N, 3, J) the reported attitude about each
    image as a polynomial, A_rep(t + τ) = exp(−Φ(φ(τ))) A_rep(t), φ(τ) = Σ_j c_j τ^j (j = 1…J,
    star-tracker axes, rad/s^j; c_1 = ω the angular rate, dA/dt = −Φ(ω) A) or None;
    ``rate_s_rad_s`` (R, N, 3) the rate alone (the same as J = 1) or None; ``landmark_g_m``
    (R, M, 3) catalogue; ``C_GI`` (N, 3, 3); ``t_s`` (N,) image times (campaign time, s from one
    epoch) or None.
    """

    focal_length_m: float
    C_SK: np.ndarray
    C_IS: np.ndarray
    r_i_m: np.ndarray
    landmark_g_m: np.ndarray
    C_GI: np.ndarray
    v_i_m_s: np.ndarray | None = None
    rate_s_rad_s: np.ndarray | None = None
    attitude_poly_s: np.ndarray | None = None
    t_s: np.ndarray | None = None
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    def cached(self, key: str, func: Any) -> Any:
        if key not in self._cache:
            self._cache[key] = func()
        return self._cache[key]


def _need(ctx: EffectContext, name: str, what: str) -> Any:
    v = getattr(ctx, name)
    if v is None:
        raise MissingContextError(what)
    return v


def _unit(v: Any) -> Any:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def argument_of_latitude(r_i_m: Any, v_i_m_s: Any) -> np.ndarray:
    """Argument of latitude u (rad) from inertial position and velocity (Z-polar axes), ``(..., 3) -> (...)``.

    u is the angle in the orbit plane from the ascending node n = ẑ × h to r, positive in the
    direction of motion (h = r × v): r ∝ cos u n̂ + sin u (ĥ × n̂). For an equatorial orbit
    (n undefined) the node is taken on the inertial x axis.

    >>> round(float(argument_of_latitude(np.array([0.0, 0.0, 7e6]), np.array([-7e3, 0.0, 0.0]))), 12)  # over the pole
    1.570796326795
    """
    r = np.asarray(r_i_m, float)
    v = np.asarray(v_i_m_s, float)
    h = _unit(np.cross(r, v))
    n = np.cross(np.array([0.0, 0.0, 1.0]), h)
    nn = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.where(nn > 1e-12, n / np.where(nn > 1e-12, nn, 1.0), np.array([1.0, 0.0, 0.0]))
    m = np.cross(h, n)
    result: np.ndarray = np.arctan2(np.sum(r * m, axis=-1), np.sum(r * n, axis=-1))
    return result


def rtn_basis(r_i_m: Any, v_i_m_s: Any) -> np.ndarray:
    """Columns radial, along-track, cross-track unit vectors in I, ``(..., 3) -> (..., 3, 3)``.

    ``R̂ = r/|r|``, ``N̂ = (r × v)/|r × v|``, T̂ = N̂ × R̂ (along the velocity for a circular orbit).
    A vector with RTN components b is ``rtn_basis(r, v) @ b`` in I.
    """
    r = np.asarray(r_i_m, float)
    R = _unit(r)
    N = _unit(np.cross(r, np.asarray(v_i_m_s, float)))
    T = np.cross(N, R)
    return np.stack([R, T, N], axis=-1)


# ---------------------------------------------------------------------------- the Effect type


@dataclass(frozen=True)
class Effect:
    """One catalogue effect: metadata, and its single definition (``basis`` or ``image``).

        ``param_names`` carry their unit in the name; ``unit_names`` the unit of each parameter as
        astropy spells it (``""`` dimensionless), ``unit`` the astropy units (astropy imported on first use);
        ``si`` the factor from the parameter's unit to SI (arcsec → rad); ``physical_range`` the
        (low, high) a flight value can take, in the parameter's unit; ``scale`` a typical size (for
        conditioning and for "what it would do at a typical size"). ``look_alikes`` names what its
        signature resembles on common campaigns (catalogue effects, or "per-pass star-tracker bias"):
        the diagnosis reports its canonical correlation with each. ``needs_velocity`` /
        ``needs_attitude_rate`` say what the basis needs beyond attitude, position and catalogue.
    ``scan`` names a parameter located by a scan instead of fitted (``alignment_step``'s boundary).

        ``basis(ctx) -> B`` (non-image stages): the stage quantity is ``B @ p_si`` — shapes
        (R, N, 3, k) for misalignment/star_tracker/position, (R, M, 3, k) for landmark. An effect
        that is not linear in its parameters gives ``value(ctx, p_si) -> (quantity, ∂quantity/∂p_si)``
        instead (``time_tag``).
        ``image(x, p_si, F) -> (x', ∂x'/∂x (…, 2, 2), ∂x'/∂p_si (…, 2, k))`` (image stage).
    """

    name: str
    stage: str
    param_names: tuple[Any, ...]
    unit_names: tuple[Any, ...]
    physical_range: tuple[Any, ...]
    scale: tuple[Any, ...]
    cause: str
    separated_by: str
    equation: str
    needs_velocity: bool = False
    needs_attitude_rate: bool = False
    look_alikes: tuple[Any, ...] = ()
    #: a parameter the data locate by a scan, not by least squares (its Jacobian column is 0): the
    #: diagnosis tests the others at each candidate value with a multiple-testing correction
    scan: str = ""
    basis: Callable[..., Any] | None = field(default=None, repr=False, compare=False)
    image: Callable[..., Any] | None = field(default=None, repr=False, compare=False)
    value: Callable[..., Any] | None = field(default=None, repr=False, compare=False)

    def stage_value(self, ctx: Any, p_si: Any) -> Any:
        """(stage quantity, its derivative with respect to p_si) for parameters p_si (R, k)."""
        if self.value is not None:
            return self.value(ctx, p_si)
        assert self.basis is not None  # an effect defines value or basis (checked at registration)
        B = self.basis(ctx)
        p = np.asarray(p_si, float)
        p = np.broadcast_to(p, B.shape[:1] + p.shape[-1:])
        return np.einsum("r...ik,rk->r...i", B, p), B

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @cached_property
    def unit(self) -> tuple[Any, ...]:
        """The astropy unit of each parameter (k,)."""
        from astropy import units as u

        return tuple(u.Unit(n) for n in self.unit_names)

    @cached_property
    def si(self) -> np.ndarray:
        """Factor from each parameter's unit to SI (rad for angles), (k,)."""
        from astropy import units as u

        return np.array([(1.0 * un).si.value if un.physical_type != "angle" else (1.0 * un).to_value(u.rad) for un in self.unit])

    @property
    def labels(self) -> tuple[Any, ...]:
        """Column labels ``name.param`` (k,)."""
        return tuple(f"{self.name}.{p}" for p in self.param_names)

    def describe(self) -> str:
        """Equation, units, range, cause and what separates it from θ, as text."""
        units = ", ".join(
            f"{p} [{un.to_string() or '1'}] in [{lo:g}, {hi:g}]"
            for p, un, (lo, hi) in zip(self.param_names, self.unit, self.physical_range)
        )
        return (
            f"{self.name} ({self.stage} stage): {self.equation}\nparameters: {units}\n"
            f"cause in flight: {self.cause}\nseparated from θ by: {self.separated_by}"
        )

    def check_range(self, values: Any, where: str, error: Any = ValueError) -> np.ndarray:
        """Values (k,) in the effect's units, finite and inside ``physical_range``; else ``error``."""
        v = np.asarray(values, float)
        for j, (name, un, (lo, hi)) in enumerate(zip(self.param_names, self.unit, self.physical_range)):
            x = v[..., j]
            if not np.all(np.isfinite(x)):
                raise error(f"{where}.{name} must be finite, got {x.tolist()!r}")
            if np.any((x < lo) | (x > hi)):
                raise error(
                    f"{where}.{name} = {x.tolist()!r} is outside the physical range [{lo:g}, {hi:g}] {un.to_string() or '(dimensionless)'} of {self.name}"
                )
        return v


# ---------------------------------------------------------------------------- bases (non-image stages)


def _thermal_basis(ctx: EffectContext) -> np.ndarray:
    v = _need(ctx, "v_i_m_s", "velocity")
    uarg = argument_of_latitude(ctx.r_i_m, v)  # (R, N)
    s, c = np.sin(uarg)[..., None, None], np.cos(uarg)[..., None, None]
    eye = np.eye(3)
    return np.concatenate([s * eye, c * eye], axis=-1)  # (R, N, 3, 6)


def campaign_time_s(t_s: Any) -> np.ndarray:
    """Campaign time τ (N,) s of each image from the mean image time of the data: τ = t − mean t.

    DECISION: the drift's reference is the mean time of the images, so θ with a drift named is the
    alignment at mid-campaign — what θ of a model *without* the drift estimates (the time average
    of a drifting alignment). An undetected drift then leaves θ honest instead of biased by the
    drift since some end point (with the first image as reference, a 1″/day drift under the
    detectable size left θ_y 2–3σ off in 3 of 3 seeds of a 5-day campaign), and θ hardly moves
    when the drift is named. A reference at the file's epoch would make the column nearly θ's
    when the epoch is far from the data (ρ → 1: "not separable" although detectable). The cost:
    the reference is a property of the image set, so a subset of the images has its own.
    """
    t = np.asarray(t_s, float)
    result: np.ndarray = t - t.mean()
    return result


def _drift_basis(ctx: EffectContext) -> np.ndarray:
    t = _need(ctx, "t_s", "image times")
    tau = campaign_time_s(t)  # (N,)
    B = tau[:, None, None] * np.eye(3)  # (N, 3, 3): φ = τ · rate, rate in rad/s
    return np.broadcast_to(B, (ctx.C_IS.shape[0],) + B.shape)


def _time_tag_value(ctx: EffectContext, p: Any) -> tuple[Any, Any]:
    """A_rep(t) = A_true(t + dt) ⇔ A_true(t) = A_rep(t − dt) = exp(−Φ(φ(−dt))) A_rep(t): ε = φ(−dt)
    from the reported attitude's polynomial about t (exact shift, any dt the polynomial covers);
    with the rate alone, ε = −ω dt."""
    c = ctx.attitude_poly_s
    if c is None:
        c = _need(ctx, "rate_s_rad_s", "attitude rate")[..., None]
    c = np.asarray(c, float)  # (R, N, 3, J)
    J = c.shape[-1]
    x = -np.asarray(p, float)[:, 0].reshape((-1,) + (1,) * (c.ndim - 2))  # −dt, (R, 1, 1)
    j = np.arange(1, J + 1)
    pw = x[..., None] ** j  # (R, 1, 1, J)
    eps = np.sum(c * pw, axis=-1)
    deps = -np.sum(c * j * x[..., None] ** (j - 1), axis=-1)  # ∂ε/∂dt
    return eps, deps[..., None]


def _aberration_basis(ctx: EffectContext) -> np.ndarray:
    v = _need(ctx, "v_i_m_s", "velocity")
    v_s = np.einsum("rnij,rnj->rni", ctx.C_IS, np.broadcast_to(v, ctx.r_i_m.shape))
    return (np.cross(STAR_TRACKER_BORESIGHT_S, v_s) / SPEED_OF_LIGHT_M_S)[..., None]  # (R, N, 3, 1)


def _gnss_basis(ctx: EffectContext) -> np.ndarray:
    v = _need(ctx, "v_i_m_s", "velocity")
    return rtn_basis(ctx.r_i_m, np.broadcast_to(v, ctx.r_i_m.shape))  # (R, N, 3, 3)


def _height_basis(ctx: EffectContext) -> np.ndarray:
    result: np.ndarray = _unit(np.asarray(ctx.landmark_g_m, float))[..., None]  # (R, M, 3, 1)
    return result


def _step_value(ctx: EffectContext, p: Any) -> tuple[Any, Any]:
    """φ = s H(t − t_b): the alignment after the boundary t_b is θ + s (camera axes), before it θ.
    Parameters (R, 4) = [s_x, s_y, s_z (rad), t_b (s, the images' time axis)]; ∂φ/∂t_b is 0 (a
    step has no derivative in its position: the diagnosis scans it, ``Effect.scan``)."""
    t = np.asarray(_need(ctx, "t_s", "image times"), float)  # (N,)
    p = np.asarray(p, float)
    after = (t[None, :] > p[:, 3:4]).astype(float)  # (R, N)
    eye = np.broadcast_to(np.eye(3), after.shape + (3, 3)) * after[..., None, None]
    J = np.concatenate([eye, np.zeros(after.shape + (3, 1))], axis=-1)  # (R, N, 3, 4)
    return np.einsum("rnik,rk->rni", J[..., :3], p[:, :3]), J


def _datum_basis(ctx: EffectContext) -> np.ndarray:
    """Local east and north unit vectors at each catalogue landmark (Earth-fixed; of the geocentric
    vertical û, east = ẑ × û/|ẑ × û|, north = û × east), (R, M, 3, 2)."""
    up = _unit(np.asarray(ctx.landmark_g_m, float))
    east = np.cross(np.array([0.0, 0.0, 1.0]), up)
    en = np.linalg.norm(east, axis=-1, keepdims=True)
    east = np.where(en > 1e-12, east / np.where(en > 1e-12, en, 1.0), np.array([0.0, 1.0, 0.0]))  # at a pole: +y
    north = np.cross(up, east)
    result: np.ndarray = np.stack([east, north], axis=-1)
    return result


# ---------------------------------------------------------------------------- image-stage maps


def _per_run(p: Any, x: Any) -> Any:
    """Parameters (R, k) shaped to broadcast against points x (R, ..., 2): (R, 1, …, 1, k)."""
    p = np.asarray(p, float)
    return p.reshape(p.shape[:1] + (1,) * (x.ndim - 2) + p.shape[-1:])


def _focal_scale_image(x: Any, p: Any, F: Any) -> tuple[Any, Any, Any]:
    k = 1.0 + _per_run(p, x)  # (R, 1, …, 1)
    return k * x, np.broadcast_to(k[..., None] * np.eye(2), x.shape + (2,)), x[..., None]


def _radial_image(x: Any, p: Any, F: Any) -> tuple[Any, Any, Any]:
    k1 = _per_run(p, x)
    r2 = np.sum(x * x, axis=-1, keepdims=True) / F**2  # (..., 1)
    xd = x * (1.0 + k1 * r2)
    Dx = (1.0 + k1 * r2)[..., None] * np.eye(2) + 2.0 * k1[..., None] / F**2 * x[..., :, None] * x[..., None, :]
    return xd, Dx, (x * r2)[..., None]


def _principal_point_image(x: Any, p: Any, F: Any) -> tuple[Any, Any, Any]:
    return x + _per_run(p, x), np.broadcast_to(np.eye(2), x.shape + (2,)), np.broadcast_to(np.eye(2), x.shape + (2,))


def apply_image_chain(x0: Any, names: Any, params_si: dict[str, Any], focal_length_m: float, jacobian: bool = False) -> Any:
    """Apply the image-stage effects among ``names`` (catalogue order) to ideal points x0 (R, ..., 2).

    ``params_si[name]`` is (R, k). Returns ``x`` and, with ``jacobian``, ``D`` (R, ..., 2, 2) =
    ∂x/∂x0 and ``{name: ∂x/∂p_si (R, ..., 2, k)}``.
    """
    x = np.asarray(x0, float)
    D = None
    jp: dict[str, Any] = {}
    for name in [n for n in EFFECTS if n in names and EFFECTS[n].stage == "image"]:
        p = np.asarray(params_si[name], float)
        image = EFFECTS[name].image
        assert image is not None  # every image-stage effect has its image map
        x, Dx, Dp = image(x, p, focal_length_m)
        if jacobian:
            jp = {k: Dx @ v for k, v in jp.items()}
            jp[name] = np.array(Dp)
            D = Dx if D is None else Dx @ D
    if not jacobian:
        return x
    if D is None:
        D = np.broadcast_to(np.eye(2), x.shape + (2,))
    return x, D, jp


# ---------------------------------------------------------------------------- the catalogue

# DECISION: units as strings, made astropy units on first use, so importing the catalogue (every
# scenario load, every command's start) does not import astropy.
_ARCSEC = "arcsec"
_ONE = ""

EFFECTS: dict[str, Effect] = {}


def _register(e: Effect) -> None:
    assert e.stage in STAGES, e.stage
    assert len(e.unit_names) == len(e.param_names) == len(e.physical_range) == len(e.scale)
    assert (e.image is not None) if e.stage == "image" else (e.value is not None or e.basis is not None), e.name
    EFFECTS[e.name] = e


_register(
    Effect(
        name="time_tag",
        stage="star_tracker",
        param_names=("dt_s",),
        unit_names=("s",),
        physical_range=((-1.0, 1.0),),
        scale=(0.01,),
        needs_attitude_rate=True,
        equation="the reported star-tracker attitude is the true one at t + dt: A_rep(t) = A_true(t + dt), i.e. "
        "A_true(t) = A_rep(t − dt) = exp(−Φ(ε)) A_rep(t) with ε = φ(−dt), φ(τ) the rotation of the reported "
        "attitude sequence from t to t + τ (star-tracker axes); to first order ε = −ω dt, ω the angular rate",
        cause="the star-tracker quaternion and the image exposure are time-tagged by different clocks or at different "
        "instants of the exposure (mid- vs start-of-exposure, an unmodelled processing latency, a leap second or "
        "clock-synchronisation error)",
        separated_by="a varying attitude rate: under nadir pointing ω is constant in the body, so −ω dt is a constant "
        "rotation absorbed into θ; a site-tracking pass (the pitch rate peaks at closest approach) or passes "
        "with different attitude laws separate it",
        value=_time_tag_value,
    )
)
_register(
    Effect(
        name="focal_scale",
        stage="image",
        param_names=("scale",),
        unit_names=(_ONE,),
        physical_range=((-0.01, 0.01),),
        scale=(1e-5,),
        equation="F_true = F (1 + s): x ← (1 + s) x",
        cause="the effective focal length differs from the calibrated one: thermal defocus of the telescope, a change "
        "of the focal-plane spacing on launch, a ground calibration error",
        separated_by="landmarks spread across the field (the offset grows with image radius, θ shifts every point "
        "alike); a radial GNSS bias changes the range and hence the image scale alike — distinguished only "
        "by range variation (site-tracking passes at varying slant range, different altitudes)",
        image=_focal_scale_image,
    )
)
_register(
    Effect(
        name="principal_point",
        stage="image",
        param_names=("x_m", "y_m"),
        unit_names=("m", "m"),
        physical_range=((-1e-3, 1e-3), (-1e-3, 1e-3)),
        scale=(1e-5, 1e-5),
        equation="x ← x + c (c the principal-point offset on the focal plane, m)",
        cause="the detector is displaced in its plane relative to the optical axis (integration tolerance, launch "
        "shift, thermal expansion of the focal-plane mount)",
        separated_by="a principal-point offset c is the image of a rotation about the camera x/y axes (θ_y ≈ c_x/F, "
        "θ_x ≈ −c_y/F) to first order; they separate only through the second-order field terms "
        "(x y/F, x²/F of the exact Jacobian), i.e. a wide field — usually not separable; any physical use "
        "of θ (pointing) absorbs it harmlessly",
        image=_principal_point_image,
    )
)
_register(
    Effect(
        name="radial_distortion",
        stage="image",
        param_names=("k1",),
        unit_names=(_ONE,),
        physical_range=((-1.0, 1.0),),
        scale=(0.01,),
        equation="x_d = x (1 + k1 r²/F²), r = |x| (F the nominal focal length; applied after the focal scale, about the "
        "principal point)",
        cause="third-order (Seidel) radial distortion of the optics not in, or changed since, the ground calibration "
        "(thermal gradients, launch loads, refocusing)",
        separated_by="landmarks at several image radii (the offset ∝ r³ is odd in radius, θ is constant): a field "
        "filled out to its edge; indistinguishable from focal_scale if all landmarks sit at one radius",
        image=_radial_image,
    )
)
_register(
    Effect(
        name="thermal",
        stage="misalignment",
        param_names=("sin_x_arcsec", "sin_y_arcsec", "sin_z_arcsec", "cos_x_arcsec", "cos_y_arcsec", "cos_z_arcsec"),
        unit_names=(_ARCSEC,) * 6,
        physical_range=((-120.0, 120.0),) * 6,
        scale=(1.0,) * 6,
        needs_velocity=True,
        equation="orbit-periodic misalignment θ(u) = θ0 + a sin u + b cos u (camera axes, u the argument of latitude; θ0 is θ): "
        "φ = a sin u + b cos u, parameters a = sin_*, b = cos_*",
        cause="the camera–star-tracker structure bends with the orbit-periodic thermal load (sun/eclipse, Earth IR), "
        "at the orbital period",
        separated_by="passes at different arguments of latitude: within one short pass u changes by a few degrees and "
        "a sin u + b cos u is a constant absorbed into θ; passes ≈90° apart in u separate a and b (the "
        "roll terms about the boresight, sin_z and cos_z, only through the field rotation: ~50× weaker)",
        look_alikes=("alignment_drift", "per-pass star-tracker bias"),
        basis=_thermal_basis,
    )
)
_register(
    Effect(
        name="alignment_drift",
        stage="misalignment",
        param_names=("rate_x_arcsec_per_day", "rate_y_arcsec_per_day", "rate_z_arcsec_per_day"),
        unit_names=("arcsec / d",) * 3,
        physical_range=((-100.0, 100.0),) * 3,
        scale=(1.0,) * 3,
        equation="misalignment drifting linearly in campaign time: θ(t) = θ + r τ (camera axes), τ = t − t̄ the "
        "time from the mean image time of the data (θ is the mid-campaign alignment): φ = r τ, parameters r = rate_*",
        cause="the camera–star-tracker alignment settles or ages over days: thermal settling after launch or a "
        "manoeuvre, moisture outgassing of composite structure, creep of the mounts",
        separated_by="passes spread over days (the offset grows with campaign time, θ is constant); within one pass it "
        "is a rotation linear in time (a time-in-pass look-alike, ~1e-5 of a day's drift); its look-alikes "
        "are thermal when the arguments of latitude of the passes change steadily with the day, and "
        "per-pass star-tracker biases (any per-pass rotation contains a linear trend over passes): passes at "
        "several arguments of latitude and more passes than the drift has parameters separate it",
        look_alikes=("thermal", "per-pass star-tracker bias"),
        basis=_drift_basis,
    )
)
_register(
    Effect(
        name="aberration",
        stage="star_tracker",
        param_names=("kappa",),
        unit_names=(_ONE,),
        physical_range=((-0.2, 2.2),),
        scale=(1.0,),
        needs_velocity=True,
        equation="the star tracker reports A_rep = exp(Φ(ε)) A_true with ε = κ b_S × v_S / c (b_S = +z_S its boresight, "
        "v_S the spacecraft's inertial velocity in star-tracker axes): κ is the fraction of the orbital "
        "velocity aberration (≈ 5″ in LEO) left uncorrected (0 corrected, 1 not corrected, 2 corrected with "
        "the wrong sign)",
        cause="the star tracker's on-board (or ground) processing does not apply, or wrongly applies, the velocity "
        "aberration correction of the star directions; annual aberration (Earth's 30 km/s) is nearly constant "
        "over a campaign and is absorbed into θ",
        separated_by="a changing angle between the star-tracker boresight and the velocity: constant under nadir "
        "pointing (absorbed into θ); site-tracking passes, passes with different attitude laws or yaw, "
        "ascending vs descending passes separate it",
        basis=_aberration_basis,
    )
)
_register(
    Effect(
        name="gnss_bias",
        stage="position",
        param_names=("radial_m", "along_track_m", "cross_track_m"),
        unit_names=("m", "m", "m"),
        physical_range=((-500.0, 500.0),) * 3,
        scale=(10.0, 10.0, 10.0),
        needs_velocity=True,
        equation="r_rep = r_true + [R̂ T̂ N̂] b (radial R̂ = r̂, cross-track N̂ = r × v/|r × v|, along-track T̂ = N̂ × R̂, "
        "from the reported orbit)",
        cause="a constant error of the GNSS navigation solution in the orbital frame: an antenna lever-arm or phase-"
        "centre error, a timing (along-track) offset of the position tags, a reference-frame or datum mismatch",
        separated_by="along/cross-track: a change of the viewing geometry (site tracking, different passes), else it "
        "is a constant rotation absorbed into θ; radial: changes the range, so it mimics focal_scale — "
        "separated by varying slant range (site-tracking passes, different altitudes)",
        basis=_gnss_basis,
    )
)
_register(
    Effect(
        name="landmark_height_bias",
        stage="landmark",
        param_names=("height_m",),
        unit_names=("m",),
        physical_range=((-500.0, 500.0),),
        scale=(10.0,),
        equation="r_L,cat = r_L,true + h û (û the catalogue landmark's geocentric vertical): every catalogue height is off by h",
        cause="the landmark heights refer to another vertical datum (geoid vs ellipsoid heights differ by up to "
        "≈ 100 m), a DEM bias, or a unit/offset error in the catalogue",
        separated_by="off-nadir viewing: a height error moves a landmark along the vertical, seen as an image shift ∝ "
        "tan(off-nadir angle); under nadir pointing over a small field it is nearly a scale change "
        "(mimics focal_scale and radial gnss_bias); site-tracking passes with large off-nadir angles "
        "separate it",
        basis=_height_basis,
    )
)

_register(
    Effect(
        name="landmark_datum_shift",
        stage="landmark",
        param_names=("east_m", "north_m"),
        unit_names=("m", "m"),
        physical_range=((-1000.0, 1000.0),) * 2,
        scale=(10.0, 10.0),
        equation="r_L,cat = r_L,true + e ê + n n̂ (ê, n̂ the local east and north of each catalogue landmark, from its "
        "geocentric vertical û: ê = ẑ × û/|ẑ × û|, n̂ = û × ê): every landmark of the catalogue is off by the same "
        "horizontal offset; its vertical part is landmark_height_bias (the same column, kept there once)",
        cause="the catalogue refers to another horizontal datum (a local datum against WGS 84: tens to hundreds of "
        "metres), a map-projection or false-easting slip, or a systematic offset of the survey",
        separated_by="passes that see it from different directions: a horizontal offset seen from an ascending pass turns "
        "the image the other way from a descending one, as thermal's orbit-periodic rotation does, and along-"
        "track it looks like an along-track gnss_bias; passes at several latitudes (several arguments of "
        "latitude per direction: thermal is a function of the argument of latitude, the shift of the ground "
        "direction) and site-tracking passes at different off-nadir angles (the offset is fixed on the ground, a "
        "GNSS bias in the orbit frame) separate them; landmark_height_bias is its vertical, orthogonal part",
        look_alikes=("thermal", "gnss_bias", "landmark_height_bias"),
        basis=_datum_basis,
    )
)
_register(
    Effect(
        name="alignment_step",
        stage="misalignment",
        param_names=("step_x_arcsec", "step_y_arcsec", "step_z_arcsec", "at_s"),
        unit_names=(_ARCSEC, _ARCSEC, _ARCSEC, "s"),
        physical_range=((-600.0, 600.0),) * 3 + ((-1e10, 1e10),),
        scale=(1.0, 1.0, 1.0, 86400.0),
        equation="a jump of the alignment at an unknown time t_b: θ(t) = θ + s for images after t_b (t > t_b, the images' "
        "time axis), θ before it (camera axes): φ = s H(t − t_b), parameters s = step_* and the boundary t_b = at_s, which "
        "the data locate by a scan (between passes), not by least squares",
        cause="a star-tracker head switch, a thermal snap or a mechanical slip at a manoeuvre, a re-mount or a "
        "reference change between passes: the alignment holds, jumps once, and holds again",
        separated_by="passes on both sides of the boundary (the offset is constant within each side, θ is the average); "
        "its look-alikes: alignment_drift (a ramp: a step is flat before and after, so three or more passes on "
        "each side separate them), thermal (a sin/cos of the argument of latitude: passes at one argument of "
        "latitude on both sides of the boundary separate them) and per-pass star-tracker biases (any per-pass "
        "rotation contains a step: a step is one rotation shared by every pass after the boundary, so more "
        "passes than boundaries separate it); the boundary is scanned over the gaps between passes with a "
        "Bonferroni correction over the scan, so a step inside a pass is not located",
        look_alikes=("alignment_drift", "thermal", "per-pass star-tracker bias"),
        scan="at_s",
        value=_step_value,
    )
)


# ---------------------------------------------------------------------------- sizes (scenario [effects])


class EffectSizes(Mapping[str, np.ndarray]):
    """Immutable, hashable mapping effect name → parameter values (k,) in the effect's units."""

    def __init__(self, items: dict[str, Any] | None = None) -> None:
        self._d = {k: tuple(float(x) for x in np.atleast_1d(v)) for k, v in (items or {}).items()}

    def __getitem__(self, key: str) -> Any:
        return np.array(self._d[key])

    def __iter__(self) -> Iterator[str]:
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)

    def __hash__(self) -> int:
        return hash(tuple(sorted(self._d.items())))

    def __eq__(self, other: Any) -> bool:
        return (
            isinstance(other, Mapping)
            and set(self) == set(other)
            and all(np.array_equal(self[k], np.asarray(other[k], float)) for k in self)
        )

    def __repr__(self) -> str:
        return f"EffectSizes({self._d!r})"

    def si(self) -> dict[str, Any]:
        """{name: (k,) array in SI units (rad for angles)}."""
        return {k: self[k] * EFFECTS[k].si for k in self}


def effect_sizes(table: Any, where: str = "effects", error: Any = ValueError) -> EffectSizes:
    """Validate a scenario ``[effects]`` table and return ``EffectSizes``.

    Each key is a catalogue name; its value is a number (one-parameter effects), a list in the
    order of ``param_names``, or a table keyed by ``param_names`` (missing parameters are 0).
    Sizes must be finite and inside the effect's ``physical_range``; anything else raises
    ``error`` naming the key as written.

    >>> effect_sizes({"focal_scale": 2e-5, "time_tag": {"dt_s": 0.02}})["time_tag"].tolist()
    [0.02]
    """
    if table is None:
        return EffectSizes()
    if not isinstance(table, Mapping):
        raise error(f"[{where}] must be a table of effect sizes, got {table!r}")
    out = {}
    for name, value in table.items():
        if name not in EFFECTS:
            hint = ""
            if name in UNMODELLED:
                hint = f" ({name!r} is deliberately outside the catalogue: put it in [unmodelled])"
            raise error(f"{where}.{name}: unknown effect{hint}; the catalogue has {sorted(EFFECTS)}")
        e = EFFECTS[name]
        key = f"{where}.{name}"
        if isinstance(value, Mapping):
            bad = sorted(set(value) - set(e.param_names))
            if bad:
                raise error(f"{key}: unknown parameter(s) {bad}; {name} has {list(e.param_names)}")
            vals = [value.get(p, 0.0) for p in e.param_names]
        elif isinstance(value, (list, tuple)):
            vals = list(value)
            if len(vals) != e.n_params:
                raise error(f"{key} must list {e.n_params} values {list(e.param_names)}, got {len(vals)}: {value!r}")
        else:
            if e.n_params != 1:
                raise error(f"{key} needs {e.n_params} values {list(e.param_names)} (a list or a table), got {value!r}")
            vals = [value]
        for p, v in zip(e.param_names, vals):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise error(f"{key}.{p} must be a number, got {v!r}")
        out[name] = e.check_range(np.array(vals, float), key, error)
    return EffectSizes(out)


# ---------------------------------------------------------------------------- forward (simulator)


def stage_offset(names: Any, params_si: dict[str, Any], ctx: EffectContext, stage: str) -> Any:
    """Σ B_e(ctx) p_e over the effects of ``stage`` among ``names``; None if there are none."""
    total = None
    for name in names:
        e = EFFECTS[name]
        if e.stage != stage:
            continue
        term = e.stage_value(ctx, params_si[name])[0]
        total = term if total is None else total + term
    return total


#: fixed-point iterations of the forward model (each divides the residual by ~|effect|/|quantity| ≲ 1e-4)
FORWARD_ITERATIONS = 4


def forward_reported(true_value: Any, noise_free_reported: Any, names: Any, params_si: Any, make_ctx: Any, stage: Any) -> Any:
    """Reported quantity y = y0 + B(ctx(y)) p, solved by fixed-point iteration from y = y0.

    ``noise_free_reported`` is y0 (truth plus sensor noise); ``make_ctx(y)`` builds the context in
    which the stage's bases are evaluated from the current reported value.
    """
    y = noise_free_reported
    if not any(EFFECTS[n].stage == stage for n in names):
        return y
    for _ in range(FORWARD_ITERATIONS):
        y = noise_free_reported + stage_offset(names, params_si, make_ctx(y), stage)
    return y


# ---------------------------------------------------------------------------- out-of-catalogue (tests)


@dataclass(frozen=True)
class Unmodelled:
    """A perturbation deliberately outside the catalogue (a test case for "unexplained structure").

    ``image(xy (R, K, 2), F) -> xy`` perturbs measured image points (one per row); ``catalogue(lm_g (R, M, 3))
    -> lm_g`` perturbs the catalogue (the truth is unchanged). Both default to the identity.
    Subclasses are plain dataclasses, so they pickle (Monte Carlo workers).
    """

    name = "unmodelled"

    @property
    def description(self) -> str:
        return repr(self)

    def image(self, xy: Any, focal_length_m: Any) -> Any:
        return xy

    def catalogue(self, lm_g: Any) -> Any:
        return lm_g


@dataclass(frozen=True)
class TangentialDistortion(Unmodelled):
    """Brown–Conrady decentring distortion in OpenCV's convention with normalised x = X/F:
    Δx = 2 p1 x y + p2 (r² + 2 x²), Δy = p1 (r² + 2 y²) + 2 p2 x y (times F)."""

    p1: float
    p2: float
    name = "tangential_distortion"

    @property
    def description(self) -> str:
        return f"tangential distortion p1={self.p1:g}, p2={self.p2:g}"

    def image(self, xy: Any, focal_length_m: Any) -> Any:
        F = focal_length_m
        x, y = xy[..., 0] / F, xy[..., 1] / F
        r2 = x * x + y * y
        dx = 2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x)
        dy = self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y
        return xy + F * np.stack([dx, dy], axis=-1)


@dataclass(frozen=True)
class LandmarkShift(Unmodelled):
    """Catalogue landmarks within ``radius_m`` of ``center_g_m`` (Earth-fixed) moved by ``shift_g_m``
    (a local survey or datum error of part of the catalogue)."""

    center_g_m: tuple[Any, ...]
    radius_m: float
    shift_g_m: tuple[Any, ...]
    name = "landmark_shift"

    @property
    def description(self) -> str:
        return f"catalogue landmarks within {self.radius_m:g} m moved by {list(self.shift_g_m)} m"

    def catalogue(self, lm_g: Any) -> Any:
        near = np.linalg.norm(lm_g - np.asarray(self.center_g_m, float), axis=-1, keepdims=True) <= self.radius_m
        return lm_g + np.where(near, np.asarray(self.shift_g_m, float), 0.0)


def tangential_distortion(p1: float, p2: float) -> Unmodelled:
    """``TangentialDistortion(p1, p2)``."""
    return TangentialDistortion(float(p1), float(p2))


def landmark_shift(center_g_m: Any, radius_m: float, shift_g_m: Any) -> Unmodelled:
    """``LandmarkShift``: catalogue landmarks within ``radius_m`` of ``center_g_m`` moved by ``shift_g_m``."""
    return LandmarkShift(tuple(float(x) for x in center_g_m), float(radius_m), tuple(float(x) for x in shift_g_m))


#: out-of-catalogue perturbation factories by name (NOT effects: nothing in EFFECTS fits them)
UNMODELLED = {"tangential_distortion": tangential_distortion, "landmark_shift": landmark_shift}


def _markdown_section(heading: str, equation: str, e: Effect | LineEffect, units: Iterable[str]) -> str:
    """One effect's section of ``docs/effects.md``: its heading, equation, parameter table (name, unit — ``units``,
    one string per parameter, ``"1"`` for none —, physical range, typical size), cause and separation."""
    rows = "\n".join(
        f"| `{p}` | {un or '1'} | [{lo:g}, {hi:g}] | {s:g} |"
        for p, un, (lo, hi), s in zip(e.param_names, units, e.physical_range, e.scale)
    )
    return (
        f"### `{e.name}` ({heading})\n\n{equation}\n\n| parameter | unit | physical range | typical size |\n|---|---|---|---|\n"
        f"{rows}\n\n*Cause in flight:* {e.cause}.\n\n*Separated from θ by:* {e.separated_by}.\n"
    )


def catalogue_markdown() -> str:
    """The catalogue as Markdown (one section per effect), as in ``docs/effects.md``."""
    out = []
    for e in EFFECTS.values():
        needs = [w for w, f in (("velocity", e.needs_velocity), ("attitude rate", e.needs_attitude_rate)) if f]
        heading = f"{e.stage} stage{'; needs ' + ' and '.join(needs) if needs else ''}"
        out.append(_markdown_section(heading, e.equation, e, [un.to_string() for un in e.unit]))
    return "\n".join(out)


# ---------------------------------------------------------------------------- line-scanner effects

_ARCSEC_RAD = np.pi / 180.0 / 3600.0


@dataclass(frozen=True)
class LineEffect:
    """One effect of a pushbroom line scanner (``docs/effects.md``, "Line-scanner effects"): metadata as ``Effect``'s
    and its one definition, the ``orbits.pushbroom.LineScanParameters`` fields it sets (``truth``: the simulator's
    forward model and, differentiated by ``boresight.core.line_scan``, the estimator's columns).

    ``param_names`` carry their unit; ``scan`` names a parameter located by a scan (the jitter's frequency), with
    ``scan_range`` its (low, high); ``per_chip`` effects act on one chip (``chip`` in the scenario's table).
    """

    name: str
    param_names: tuple[str, ...]
    unit_names: tuple[str, ...]
    physical_range: tuple[tuple[float, float], ...]
    scale: tuple[float, ...]
    equation: str
    cause: str
    separated_by: str
    look_alikes: tuple[str, ...] = ()
    scan: str = ""
    scan_range: tuple[float, float] = (0.0, 0.0)
    per_chip: bool = False

    @property
    def n_params(self) -> int:
        return len(self.param_names)


LINE_EFFECTS: dict[str, LineEffect] = {}


def _register_line(e: LineEffect) -> None:
    assert len(e.unit_names) == len(e.param_names) == len(e.physical_range) == len(e.scale), e.name
    LINE_EFFECTS[e.name] = e


_register_line(
    LineEffect(
        name="line_time_offset",
        param_names=("dt_s",),
        unit_names=("s",),
        physical_range=((-1.0, 1.0),),
        scale=(1e-3,),
        equation="every line is exposed at t(L) + δt: t(L) = t_nom(L) + δt",
        cause="the line clock and the platform clock (GNSS time) are offset: a latency of the line-time stamp, "
        "start- vs mid-of-integration dating, a clock-synchronisation error",
        separated_by="a time shift moves the spacecraft by v δt along the track, which from the slant range ρ looks "
        "like a pitch rotation v δt/ρ: on one strip it trades with θ about the across-track axis and is separated "
        "only by parallax (GCP heights h give v δt h/ρ² differences) and the orbit's curvature (canonical correlation "
        "with θ 0.99995 on pushbroom-strip: not separable); strips at roll angles far enough apart (different ρ) "
        "separate it: −40°, 0°, 40° do (0.982), pushbroom-campaign's −25°, 0°, 15°, 30° do not (0.9965, above the "
        "0.995 cut; docs/pushbroom.md)",
        look_alikes=("theta about the across-track axis",),
    )
)
_register_line(
    LineEffect(
        name="line_period_error",
        param_names=("relative",),
        unit_names=(_ONE,),
        physical_range=((-1e-3, 1e-3),),
        scale=(1e-6,),
        equation="the line period is T (1 + ε): t(L) = t_nom(L) + ε (t_nom(L) − t_nom(L_ref))",
        cause="the line-rate oscillator runs off its nominal frequency (temperature, ageing), or the commanded line "
        "rate is quantised",
        separated_by="the time error grows along the strip, an along-track stretch: separated from θ (constant) by "
        "GCPs spread along the strip; from a line-time offset by the same spread (the offset is constant)",
        look_alikes=("alignment drift about the across-track axis",),
    )
)
_register_line(
    LineEffect(
        name="focal_scale",
        param_names=("scale",),
        unit_names=(_ONE,),
        physical_range=((-0.01, 0.01),),
        scale=(1e-5,),
        equation="the look angles are scaled by 1/(1 + s): τ_c(j) ← τ_c(j)/(1 + s) (the frame camera's x ← (1 + s) x)",
        cause="the effective focal length differs from the calibrated one (thermal defocus, launch)",
        separated_by="GCPs across the whole swath: the across-track offset grows with the distance from the boresight "
        "column, θ shifts every column alike; a radial orbit error scales the swath alike (separated only by "
        "strips at different slant ranges)",
    )
)
_register_line(
    LineEffect(
        name="chip_offset",
        param_names=("along_track_arcsec", "across_track_arcsec"),
        unit_names=("arcsec", "arcsec"),
        physical_range=((-600.0, 600.0), (-600.0, 600.0)),
        scale=(1.0, 1.0),
        equation="chip c's look angles are shifted: τ_c(j) ← τ_c(j) + (δψx, δψy) (a shift of the chip on the focal "
        "plane by F δψ)",
        cause="a chip moved on the focal plane (launch loads, thermal distortion of the focal-plane assembly)",
        separated_by="GCPs on the other chips, which fix θ: the same offset on every chip is θ (so one chip is the "
        "reference, as in operational calibration: alignment first, then per-chip look angles); an across-track "
        "offset of the centre chip resembles a focal scale only when the outer chips hold no GCPs",
        per_chip=True,
    )
)
_register_line(
    LineEffect(
        name="jitter",
        param_names=(
            "amplitude_x_arcsec",
            "amplitude_y_arcsec",
            "amplitude_z_arcsec",
            "phase_x_rad",
            "phase_y_rad",
            "phase_z_rad",
        ),
        unit_names=("arcsec", "arcsec", "arcsec", "rad", "rad", "rad"),
        physical_range=((0.0, 60.0),) * 3 + ((-2 * np.pi, 2 * np.pi),) * 3,
        scale=(1.0, 1.0, 1.0, 1.0, 1.0, 1.0),
        equation="the camera turns against the star tracker by j_a(t) = A_a sin(2π f t + φ_a) about camera axis a: "
        "C_IK = exp(−Φ(θ)) exp(−Φ(j(t))) C_SK,nom A(t)",
        cause="attitude jitter the star tracker does not sample: structural vibration between the camera and the "
        "tracker (ZY-3: about 0.65 Hz, 0.5-1.5 px), reaction-wheel or solar-array drive harmonics",
        separated_by="at least one period within the strip (the strip lasts longer than 1/f; shorter, a sinusoid is "
        "a rotation plus a drift that θ and the line timing absorb); from the star tracker's per-sample noise by a "
        "tracker noise small against the amplitude at the sample rate (the samples can follow any smooth attitude); "
        "the frequency is found by a scan, tested with the scan's multiple-testing correction",
        scan="frequency_hz",
        scan_range=(0.05, 5.0),
    )
)


def line_scan_truth(theta_rad: Any, effects: Mapping[str, Any] | None, n_chips: int, where: str = "effects") -> Any:
    """The ``orbits.pushbroom.LineScanParameters`` of θ (3,) rad and a scenario's line-scanner ``[effects]`` table:
    each key a ``LINE_EFFECTS`` name with a table of its parameters (missing ones 0); ``chip_offset`` also takes
    ``chip`` (an index), ``jitter`` ``frequency_hz``. Values are checked against ``physical_range``.

    >>> p = line_scan_truth([0, 0, 0], {"line_time_offset": {"dt_s": 0.002}, "chip_offset": {"chip": 1, "across_track_arcsec": 1.0}}, 3)
    >>> p.line_time_offset_s, round(float(p.chip_offsets_rad[1, 1] / _ARCSEC_RAD), 9)
    (0.002, 1.0)
    """
    from .pushbroom import LineScanParameters

    kw: dict[str, Any] = dict(theta_rad=np.asarray(theta_rad, float))
    for name, table in (effects or {}).items():
        if name not in LINE_EFFECTS:
            raise EffectError(f"{where}.{name}: unknown line-scanner effect; the catalogue has {sorted(LINE_EFFECTS)}")
        e = LINE_EFFECTS[name]
        if not isinstance(table, Mapping):
            raise EffectError(f"{where}.{name} must be a table of {list(e.param_names)}, got {table!r}")
        extra = {"chip"} if e.per_chip else ({e.scan} if e.scan else set())
        bad = sorted(set(table) - set(e.param_names) - extra)
        if bad:
            raise EffectError(f"{where}.{name}: unknown parameter(s) {bad}; {name} has {list(e.param_names) + sorted(extra)}")
        vals = np.array([float(table.get(p, 0.0)) for p in e.param_names])
        for p, v, (lo, hi) in zip(e.param_names, vals, e.physical_range):
            if not (np.isfinite(v) and lo <= v <= hi):
                raise EffectError(f"{where}.{name}.{p} = {v!r} is outside the physical range [{lo:g}, {hi:g}]")
        if name == "line_time_offset":
            kw["line_time_offset_s"] = float(vals[0])
        elif name == "line_period_error":
            kw["line_period_error"] = float(vals[0])
        elif name == "focal_scale":
            kw["focal_scale"] = float(vals[0])
        elif name == "chip_offset":
            chip = table.get("chip")
            if isinstance(chip, bool) or not isinstance(chip, (int, np.integer)) or not 0 <= chip < n_chips:
                raise EffectError(f"{where}.chip_offset.chip must be a chip index 0 … {n_chips - 1}, got {chip!r}")
            off = np.zeros((n_chips, 2))
            off[chip] = vals * _ARCSEC_RAD
            kw["chip_offsets_rad"] = off
        else:  # jitter
            f = float(table.get("frequency_hz", np.nan))
            lo, hi = e.scan_range
            if not (np.isfinite(f) and f > 0):
                raise EffectError(
                    f"{where}.jitter.frequency_hz must be > 0 (scanned by diagnose in [{lo:g}, {hi:g}] Hz), got {f!r}"
                )
            kw.update(jitter_frequency_hz=[f], jitter_amplitude_rad=[vals[:3] * _ARCSEC_RAD], jitter_phase_rad=[vals[3:]])
    return LineScanParameters(**kw)


def line_catalogue_markdown() -> str:
    """The line-scanner effects as Markdown, as in ``docs/effects.md`` ("Line-scanner effects")."""
    out = []
    for e in LINE_EFFECTS.values():
        more = ""
        if e.per_chip:
            more = " The chip is named by `chip` (an index) in the table."
        if e.scan:
            more = f" `{e.scan}` is located by a scan over [{e.scan_range[0]:g}, {e.scan_range[1]:g}] Hz."
        out.append(_markdown_section("line scanner", f"{e.equation}.{more}", e, e.unit_names))
    return "\n".join(out)
