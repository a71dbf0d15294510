"""The measurement model of a pushbroom line on rows, and θ estimated with the one GLS.

A set whose images are lines (``ObservationSet.line_scan``: ``orbits.strip.LineScanRecords``; built by
``boresight.observations.strip``) has one row per detection: ground-control point t seen at the measured (line L,
chip c, index j). **Instantaneous line dating**: the measured line fixes the exposure's time t(L) (the datation with
the line-time offset δt and period error ε, ``orbits.pushbroom.line_time_s``), and the residual of the row is the
focal-plane mismatch at that time,

    r_k(x) = F [τ_c(j; κ, δψ_c) − τ(u_K(t(L; δt, ε); θ, jitter))]          (m on the focal plane, 2-vector)

with τ_c the pixel's look angles (``LineSensor.tan_psi``: focal scale κ, chip offsets δψ) and τ(u_K) where the point's
apparent direction (light time, aberration) is imaged by the line's camera attitude
(``orbits.pushbroom.sight_tan_psi`` after ``line_sight``: the frame camera's one projection, ``orbits.camera.project``). The pixel
noise of a detection, σ (pixels) on L and on j, enters r through J_k = ∂r/∂(L, j): each row's 2 × 2 covariance is
σ² J_k J_kᵀ (to first order; along-track one line ≈ one pixel), and the row is whitened by it. At the truth r = 0
(inverse location solves τ(u_K(L)) = τ_c(j) to 1e-8 line), so a noise-free strip gives x back to round-off.

The unknowns x (``LineScanUnknowns``): θ (3, rad, eq 24's sign), and optionally δt (s), ε, κ, per-chip look-angle
offsets (rad, along/across track) and jitter sinusoids at given frequencies (per camera axis a_s, a_c in rad:
j_a(t) = a_s sin 2πft + a_c cos 2πft = A sin(2πft + φ), A = |(a_s, a_c)|, φ = atan2(a_c, a_s)). Their Jacobian
X = ∂p/∂x − ∂m/∂x = −∂r/∂x is taken by central differences of r (steps ``_STEPS``): the model is the simulator's own
function, so an estimate, its Jacobian and the truth cannot drift apart.

The nuisances (``boresight.core.gls.structure.scaled_columns``, the one builder, with the noise model's σ and modes):
a tracker error δ at the samples (A_meas = exp(Φ(δ)) A) acts as a misalignment −C_ESᵀ δ, so ∂r/∂δ = X_θ C_ESᵀ
(``StripTrajectory.tracker_sample_weights``), its per-image columns carried on the attitude-sample table
(``gls.rows``: a line interpolates its two samples); a GNSS error ξ of the position moves the point seen by −ξ,
∂r/∂ξ = −(∂r/∂g) C_GIᵀ; a catalogue error ε of the point ∂r/∂ε = ∂r/∂g (central differences in g, 1 m).
DECISION: the noise model's "per image" modes are per *sample* here (a line has no error of its own: its attitude is
the tracker's samples' and its position the orbit's); a GNSS error per sample is the model's coarse stand-in for an
orbit error and "per pass" (one bias over the strip) is the sensible mode for a strip of seconds.

**The star tracker's correlated error** (``DisturbanceModel.sigma_star_tracker_correlated_rad`` σ_c and
``star_tracker_correlation_time_s`` τ; the simulator's ``orbits.strip.TrackerNoise``). A tracker's attitude error is not
white: thermal and low-frequency errors wander over tens of seconds. Per axis, the error of sample k (time t_k) is
δ_k = w_k + c_k, w white of σ_w, c a first-order Gauss–Markov process — the Ornstein–Uhlenbeck process
dc = −c/τ dt + σ_c √(2/τ) dW of stationary variance σ_c² (Gelb 1974, *Applied Optimal Estimation*, table 3.2-1) —
whose exact discretisation on the (possibly uneven) sample times is the AR(1)

    c_k = φ_k c_{k−1} + σ_c √(1 − φ_k²) e_k,   φ_k = exp(−(t_k − t_{k−1})/τ),   e_k ~ N(0, 1),   c_0 ~ N(0, σ_c²),

so Cov(c_k, c_m) = σ_c² Π φ = σ_c² exp(−|t_k − t_m|/τ) = σ_c² K_km and Cov(δ) = σ_w² I + σ_c² K per axis. K is dense,
but e = M c/σ_c with M lower bidiagonal (M_kk = 1/√(1 − φ_k²), M_k,k−1 = −φ_k/√(1 − φ_k²)) is white, so
K⁻¹ = MᵀM is **tridiagonal** (Rybicki & Press 1995, ApJ 442, 1; it is the information form of the Kalman/RTS
smoother of the process, Rauch, Tung & Striebel 1965). The GLS therefore carries c as a second set of per-sample
nuisances — columns J_δ σ_c beside the white J_δ σ_w, the same ∂r/∂δ — with that tridiagonal prior instead of E
(``gls.rows``: ``RowStructure.sample_correlation`` holds the φ_k; ``tracker_correlation`` computes them), exactly, with
memory and time linear in samples and no S × S matrix. DECISION: the second set of columns (w and c apart, six
nuisances a sample, not δ alone with the dense prior σ_w² I + σ_c² K or the pair (δ, c) with δ | c ~ N(c, σ_w²)): each
keeps the one GLS's form — columns scaled by σ, a prior of the samples — and σ_w = 0 or σ_c = 0 simply drops one set
(σ_c = 0 is today's model, bit for bit). The strips of a campaign are separate processes (``stacked_rows``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.campaign import single_threaded_blas
from boresight.core.gls.rows import RowColumns, RowFit, RowStructure, row_gls
from boresight.core.gls.structure import scaled_columns
from boresight.core.weighting import iteration_limit
from boresight.errors import InputValueError, NoiseModelError
from orbits.pushbroom import LineScanParameters, LineSight, SightCorrections, line_sight, sight_tan_psi

__all__ = [
    "LineScanUnknowns",
    "quantity_and_unit",
    "LineScanFit",
    "line_scan_residuals",
    "line_scan_jacobian",
    "pixel_jacobian",
    "line_scan_rows",
    "stacked_rows",
    "estimate_line_scan",
    "is_line_scan_input",
    "estimate_lines",
    "tracker_correlation",
]

#: central-difference steps of each kind of unknown (SI): small enough that the model's curvature is negligible
#: (θ: 1e-6 rad moves a point by 0.5 m; its second-order term is ~1e-12 of that), large enough for 1e-10 differences
_STEPS = {"theta": 1e-6, "line_time_offset_s": 1e-5, "line_period_error": 1e-6, "focal_scale": 1e-6, "chip": 1e-6, "jitter": 1e-6}
_GROUND_STEP_M = 1.0
_ARCSEC = np.pi / 180.0 / 3600.0
_LINE_STEP = 0.5


@dataclass(frozen=True)
class LineScanUnknowns:
    """Which parameters of the line model are estimated besides θ: the line-time offset δt, the line-period error ε,
    the focal scale κ, ``chip_offsets`` (a tuple of (chip, axis) with axis 0 along track δψx, 1 across δψy) and
    ``jitter_hz`` (frequencies: six unknowns each, a_s and a_c per camera axis)."""

    line_time_offset: bool = False
    line_period_error: bool = False
    focal_scale: bool = False
    chip_offsets: tuple[tuple[int, int], ...] = ()
    jitter_hz: tuple[float, ...] = ()

    @property
    def names(self) -> list[str]:
        """The unknowns in x's order, with their units."""
        out = ["theta_x_rad", "theta_y_rad", "theta_z_rad"]
        out += ["line_time_offset_s"] if self.line_time_offset else []
        out += ["line_period_error"] if self.line_period_error else []
        out += ["focal_scale"] if self.focal_scale else []
        out += [f"chip{c}_{'along' if a == 0 else 'across'}_rad" for c, a in self.chip_offsets]
        for f in self.jitter_hz:
            out += [f"jitter_{f:g}Hz_{part}_{axis}_rad" for part in ("sin", "cos") for axis in "xyz"]
        return out

    def steps(self) -> np.ndarray:
        """The central-difference step of each unknown."""
        s = [_STEPS["theta"]] * 3
        s += [_STEPS["line_time_offset_s"]] if self.line_time_offset else []
        s += [_STEPS["line_period_error"]] if self.line_period_error else []
        s += [_STEPS["focal_scale"]] if self.focal_scale else []
        s += [_STEPS["chip"]] * len(self.chip_offsets) + [_STEPS["jitter"]] * 6 * len(self.jitter_hz)
        return np.array(s)

    def timing(self) -> np.ndarray:
        """(n,) bool: the unknowns that move the lines' times (δt, ε)."""
        out = [False] * 3 + [True] * (int(self.line_time_offset) + int(self.line_period_error))
        out += [False] * (int(self.focal_scale) + len(self.chip_offsets) + 6 * len(self.jitter_hz))
        return np.array(out, bool)

    def parameters(self, x: Any, n_chips: int) -> LineScanParameters:
        """The forward model's ``LineScanParameters`` at x (n,)."""
        x = np.asarray(x, float)
        i = 3
        kw: dict[str, Any] = dict(theta_rad=x[:3])
        for name, on in (
            ("line_time_offset_s", self.line_time_offset),
            ("line_period_error", self.line_period_error),
            ("focal_scale", self.focal_scale),
        ):
            if on:
                kw[name] = float(x[i])
                i += 1
        if self.chip_offsets:
            off = np.zeros((n_chips, 2))
            for c, a in self.chip_offsets:
                off[c, a] = x[i]
                i += 1
            kw["chip_offsets_rad"] = off
        if self.jitter_hz:
            ab = x[i : i + 6 * len(self.jitter_hz)].reshape(-1, 2, 3)  # (F, [sin, cos], axis)
            kw.update(
                jitter_frequency_hz=np.asarray(self.jitter_hz, float),
                jitter_amplitude_rad=np.hypot(ab[:, 0], ab[:, 1]),
                jitter_phase_rad=np.arctan2(ab[:, 1], ab[:, 0]),
            )
        return LineScanParameters(**kw)


#: the SI unit suffixes of ``LineScanUnknowns.names`` (an angle in rad, a time in s; no suffix: dimensionless)
_SI_SUFFIXES = ("rad", "s")


def quantity_and_unit(name: str) -> tuple[str, str]:
    """(the quantity, its SI unit) of an unknown named as ``LineScanUnknowns.names`` names it, the one place that
    reads a name's unit: an estimate reports the quantity (``Estimate.effects``, ``joint_labels``) with its value in
    ``joint_units``, and the command line prints it with the unit of the value it prints (``theta_x … arcsec``).

    >>> quantity_and_unit("chip1_along_rad"), quantity_and_unit("line_time_offset_s"), quantity_and_unit("focal_scale")
    (('chip1_along', 'rad'), ('line_time_offset', 's'), ('focal_scale', ''))
    """
    for unit in _SI_SUFFIXES:
        if name.endswith("_" + unit):
            return name[: -len(unit) - 1], unit
    return name, ""


def _records(obs: Any) -> Any:
    ls = getattr(obs, "line_scan", None)
    if ls is None:
        raise InputValueError("line_scan: the set's images are not pushbroom lines (ObservationSet.line_scan is None)")
    if obs.runs != 1:
        raise InputValueError(f"line_scan: one run at a time (the trajectory is the run's), got {obs.runs} runs")
    return ls


def _sight(obs: Any, params: LineScanParameters, ground_g_m: Any = None, line: Any = None) -> LineSight:
    ls = _records(obs)
    img = np.asarray(obs.image_index)
    g = obs.landmark_g_m[0, obs.target_index] if ground_g_m is None else np.asarray(ground_g_m, float)
    L = np.asarray(ls.line, float)[img] if line is None else np.asarray(line, float)
    return line_sight(ls.datation, ls.trajectory, L, g, params, SightCorrections(ls.light_time, ls.aberration))


def _residual(obs: Any, sight: LineSight, params: LineScanParameters) -> np.ndarray:
    ls = obs.line_scan
    sensor = ls.sensor
    img = np.asarray(obs.image_index)
    tau_c = sensor.effective_tan_psi(ls.tan_psi_law[img], np.asarray(ls.chip)[img], params.focal_scale, params.chip_offsets_rad)
    out: np.ndarray = sensor.focal_length_m * (tau_c - sight_tan_psi(sensor, sight, params))
    return out


def line_scan_residuals(obs: Any, x: Any, unknowns: LineScanUnknowns, ground_g_m: Any = None, line: Any = None) -> np.ndarray:
    """r (K, 2) m: measured − predicted focal-plane point of each row at the unknowns x (module docstring);
    ``ground_g_m`` (K, 3) and ``line`` (K,) replace the rows' catalogue points and measured lines (for differences)."""
    params = unknowns.parameters(x, _records(obs).sensor.n_chips)
    return _residual(obs, _sight(obs, params, ground_g_m, line), params)


def _timing_key(params: LineScanParameters) -> tuple[float, float]:
    return (float(params.line_time_offset_s), float(params.line_period_error))


def line_scan_jacobian(
    obs: Any, x: Any, unknowns: LineScanUnknowns, sight_memo: dict[str, Any] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(r (K, 2), X = −∂r/∂x (K, 2, n)) by central differences (steps ``LineScanUnknowns.steps``). DECISION: only the
    timing unknowns (δt, ε) move the lines' times and so need the trajectory again (``orbits.pushbroom.line_sight``);
    θ, the jitter, κ and the chip offsets reuse the sight at x (``sight_tan_psi``): the same differences of the same
    function, ~10× fewer interpolations of the orbit, the tracker and the Earth.

    ``sight_memo`` (a dict the caller keeps for this ``obs`` over a fit's steps): the sight at x's timing (δt, ε) is
    kept in it and taken back while the timing is unchanged — always, when no timing unknown is estimated — the same
    object ``line_sight`` would compute again (it depends on x only through δt and ε), so the fit is unchanged bit for
    bit while a θ-only fit interpolates the trajectory once instead of once per step. One entry: a fit that floats δt
    or ε moves its timing every step and misses, at no extra memory."""
    x = np.asarray(x, float)
    n_chips = _records(obs).sensor.n_chips
    params = unknowns.parameters(x, n_chips)
    key = _timing_key(params)
    if sight_memo is not None and sight_memo.get("timing") == key:
        sight = sight_memo["sight"]
    else:
        sight = _sight(obs, params)
        if sight_memo is not None:
            sight_memo.update(timing=key, sight=sight)
    r = _residual(obs, sight, params)
    h, timing = unknowns.steps(), unknowns.timing()
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h[i]
        pair = []
        for y in (x + e, x - e):
            p = unknowns.parameters(y, n_chips)
            pair.append(_residual(obs, _sight(obs, p) if timing[i] else sight, p))
        cols.append(-(pair[0] - pair[1]) / (2 * h[i]))
    return r, np.stack(cols, axis=-1)


def _central(f: Any, x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(K, 2, n): central differences of f (K, 2) in each component of x."""
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h[i]
        cols.append((f(x + e) - f(x - e)) / (2 * h[i]))
    return np.stack(cols, axis=-1)


def pixel_jacobian(obs: Any, x: Any, unknowns: LineScanUnknowns, r0: np.ndarray | None = None) -> np.ndarray:
    """J (K, 2, 2) = ∂r/∂(L, j): how a row's residual moves with its measured line (central difference, ±0.5 line; a
    forward one from the residual ``r0`` at x when given: the line's motion is uniform to ~1e-6 over half a line) and
    chip index (``LineChip.tan_psi_derivative``); the row's pixel covariance is σ² J Jᵀ."""
    ls = _records(obs)
    sensor = ls.sensor
    img = np.asarray(obs.image_index)
    L0 = np.asarray(ls.line, float)[img]
    up = line_scan_residuals(obs, x, unknowns, line=L0 + _LINE_STEP)
    if r0 is None:
        dr_dL = (up - line_scan_residuals(obs, x, unknowns, line=L0 - _LINE_STEP)) / (2 * _LINE_STEP)
    else:
        dr_dL = (up - r0) / _LINE_STEP
    kappa = unknowns.parameters(x, sensor.n_chips).focal_scale
    chip = np.asarray(ls.chip)[img]
    dr_dj = np.empty_like(dr_dL)
    for c, ch in enumerate(sensor.chips):
        sel = chip == c
        dr_dj[sel] = sensor.focal_length_m * ch.tan_psi_derivative(ls.chip_index[img][sel]) / (1.0 + kappa)
    out: np.ndarray = np.stack([dr_dL, dr_dj], axis=-1)
    return out


def line_scan_rows(
    obs: Any,
    x: Any,
    unknowns: LineScanUnknowns,
    model: DisturbanceModel,
    sigma_pixel_px: float | None = None,
    pixel_jac: Any = None,
    sight_memo: dict[str, Any] | None = None,
) -> tuple[RowStructure, RowColumns]:
    """The row structure (with the attitude-sample table) and the whitened row columns at x (one run): X = −∂r/∂x,
    q = r, the scaled nuisance columns of ``model``; each row whitened by σ² J Jᵀ, J = ∂r/∂(L, j) (``pixel_jacobian``,
    or ``pixel_jac`` given, or a callable (obs, r) → J given the residuals), σ in pixels (``sigma_pixel_px``; default ``model.sigma_pixel_m`` over the pixel pitch);
    ``sight_memo`` as ``line_scan_jacobian``'s."""
    ls = _records(obs)
    sensor = ls.sensor
    x = np.asarray(x, float)
    img = np.asarray(obs.image_index)
    if sigma_pixel_px is None:
        if not sensor.pixel_pitch_m or not model.sigma_pixel_m > 0:
            raise NoiseModelError("line_scan_rows: need sigma_pixel_px, or model.sigma_pixel_m > 0 and the sensor's pixel pitch")
        sigma_pixel_px = model.sigma_pixel_m / sensor.pixel_pitch_m
    if not (np.isfinite(sigma_pixel_px) and sigma_pixel_px > 0):
        raise InputValueError(f"line_scan_rows: the pixel σ must be > 0, got {sigma_pixel_px!r} px")
    q, X = line_scan_jacobian(obs, x, unknowns, sight_memo)
    if callable(pixel_jac):  # the caller keeps J: computed here from q
        pixel_jac = pixel_jac(obs, q)
    if model.sigma_gnss_m > 0 or model.sigma_catalogue_m > 0:
        g0 = obs.landmark_g_m[0, obs.target_index]
        dr_dg = _central(
            lambda g: line_scan_residuals(obs, x, unknowns, ground_g_m=g0 + g), np.zeros(3), np.full(3, _GROUND_STEP_M)
        )
    else:  # no position or catalogue error in the model: their columns are not built (scaled_columns drops σ = 0)
        dr_dg = np.zeros(q.shape + (3,))
    J = pixel_jacobian(obs, x, unknowns) if pixel_jac is None else np.asarray(pixel_jac, float)
    C_ES = ls.trajectory.C_ES
    jac = {
        "star_tracker": (X[..., :3] @ C_ES.T)[None],
        "gnss": (-dr_dg @ np.swapaxes(np.asarray(obs.C_GI)[img], -1, -2))[None],
        "catalogue": dr_dg[None],
    }
    white = replace(model, sigma_star_tracker_correlated_rad=(0.0, 0.0, 0.0))
    A, B, C = (np.zeros((1, q.shape[0], 2, 0)) if Z is None else Z for Z in scaled_columns(jac, white))
    st = RowStructure.of(obs)
    if model.has_correlated_tracker:  # the Gauss–Markov part: σ_c-scaled columns after the white ones, AR(1) prior
        A, st = _gauss_markov_columns(obs, st, A, jac["star_tracker"], model)
    Wh = np.linalg.inv(np.linalg.cholesky(sigma_pixel_px**2 * (J @ np.swapaxes(J, -1, -2))))[None]
    return st, RowColumns(X=Wh @ X[None], q=(Wh @ q[None, ..., None])[..., 0], A=Wh @ A, B=Wh @ B, C=Wh @ C)


def tracker_correlation(sample_t_s: Any, correlation_time_s: float) -> np.ndarray:
    """φ (S,) of a first-order Gauss–Markov process between consecutive tracker samples: φ_s = exp(−(t_s − t_{s−1})/τ),
    φ_0 = 0 (module docstring; ``gls.rows``' AR(1) prior). The sample times must increase strictly (φ < 1)."""
    t = np.asarray(sample_t_s, float).ravel()
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size or not np.all(np.isfinite(t)):
        k = int(bad[0]) + 1 if bad.size else int(np.argmax(~np.isfinite(t)))
        raise InputValueError(
            f"tracker_correlation: the attitude samples' times must be finite and strictly increasing, got sample {k} at "
            f"{float(t[k])} s" + (f" after {float(t[k - 1])} s" if k else "")
        )
    out: np.ndarray = np.concatenate([[0.0], np.exp(-dt / float(correlation_time_s))])
    return out


def _gauss_markov_columns(
    obs: Any, st: RowStructure, A: np.ndarray, J_tracker: np.ndarray, model: DisturbanceModel
) -> tuple[np.ndarray, RowStructure]:
    """A with one column J_δ,k σ_c,k per axis k of σ_c > 0 appended, and the structure with their AR(1) correlation on
    the attitude samples (the white columns φ = 0)."""
    if getattr(obs, "sample_t_s", None) is None:
        raise InputValueError("line_scan_rows: the star tracker's Gauss–Markov error needs the set's attitude-sample times")
    sig = np.asarray(model.sigma_star_tracker_correlated_rad, float)
    axes = [k for k in range(3) if sig[k] > 0]
    A = np.concatenate([A] + [J_tracker[..., k : k + 1] * sig[k] for k in axes], axis=-1)
    phi = tracker_correlation(obs.sample_t_s, model.star_tracker_correlation_time_s)
    corr = np.zeros((phi.size, A.shape[-1]))
    corr[:, A.shape[-1] - len(axes) :] = phi[:, None]
    return A, replace(st, sample_correlation=corr)


@dataclass
class LineScanFit:
    """The estimate of a line model: ``x`` (n,) SI in ``names``' order, its ``covariance`` (n, n), the GLS χ² at the
    solution and its degrees of freedom, the Gauss–Newton steps taken, the last ``RowFit``."""

    names: list[str]
    x: np.ndarray
    covariance: np.ndarray
    chi2: float
    dof: int
    iterations: int
    fit: RowFit = field(repr=False)
    #: False when ``max_iter`` steps ended with a step still above ``tol_sigma`` σ (x and σ then are the last step's)
    converged: bool = True
    #: a robust fit: its loss and the final IRLS weight (K,) of each row (``core.robust``); χ² and dof are then those of
    #: the rows with z ≤ ``core.robust.CHI2_INLIER_Z``. ``z`` (K,), every fit: each row's pixel-level normalised residual
    #: length, the residual over the pixel σ once the fit's MAP tracker-sample, per-pass and catalogue errors given x are
    #: removed (``gls.rows.row_residuals``; the frame fits' ``whitened_residual_norm``)
    loss: str | None = None
    weights: np.ndarray | None = field(default=None, repr=False)
    z: np.ndarray | None = field(default=None, repr=False)

    @property
    def sigma(self) -> np.ndarray:
        """(n,) the standard deviation of each unknown."""
        out: np.ndarray = np.sqrt(np.diag(self.covariance))
        return out

    @property
    def theta_arcsec(self) -> np.ndarray:
        """θ (3,) in arcseconds."""
        out: np.ndarray = np.degrees(self.x[:3]) * 3600.0
        return out


def estimate_line_scan(
    obs: Any,
    unknowns: LineScanUnknowns = LineScanUnknowns(),
    model: DisturbanceModel | None = None,
    sigma_pixel_px: float | None = None,
    x0: Any = None,
    max_iter: int | None = None,
    tol_sigma: float = 1e-4,
    loss: str | None = None,
) -> LineScanFit:
    """Gauss–Newton on the line model of ``obs`` (one strip, or a list of strips: ``stacked_rows``) with the GLS on rows (``gls.rows.row_gls``: the nuisances of ``model`` on the
    attitude-sample table eliminated exactly) until every step is below ``tol_sigma`` times its unknown's σ (or
    ``max_iter`` steps, default 10; from θ = 0 on pushbroom-strip the steps are ~400 σ, ~0.05 σ and ~1e-8 σ: three steps, and a
    noise-free strip is then at the inverse location's 1e-8-line floor). ``model`` None: pixel noise only (σ = ``sigma_pixel_px``, default 1 px).

    ``loss`` (``"huber"``, ``"cauchy"``, ``"tukey"``: ``core.robust``): iteratively reweighted, each row weighted by
    w(z) of its pixel-level normalised residual length z (the MAP nuisances of the weighted fit removed, as the frame
    camera's robust fits), Tukey starting from three Huber steps, until the step is below
    ``core.robust.ROBUST_TOLERANCE_SIGMA`` σ and no weight moves by ``ROBUST_WEIGHT_TOLERANCE`` (default at most
    ``MAX_ITER_ROBUST`` steps); the covariance is the M-estimator sandwich (``robust.m_estimator_covariance_rows``)."""
    if model is None:
        model = DisturbanceModel()
        sigma_pixel_px = 1.0 if sigma_pixel_px is None else sigma_pixel_px
    lines = _LineProblem(list(obs) if isinstance(obs, (list, tuple)) else [obs], unknowns, model, sigma_pixel_px)
    x = np.zeros(len(unknowns.names)) if x0 is None else np.array(x0, float)
    with single_threaded_blas():
        if loss is None:
            return _gauss_newton(lines, x, max_iter or 10, tol_sigma)
        from boresight.core.robust import LOSSES

        if loss not in LOSSES:
            raise InputValueError(f"estimate_line_scan: loss must be None or one of {sorted(LOSSES)}, got {loss!r}")
        return _robust_gauss_newton(lines, x, max_iter or MAX_ITER_ROBUST, loss)


def stacked_rows(
    strips: Sequence[Any],
    x: Any,
    unknowns: LineScanUnknowns,
    model: DisturbanceModel,
    sigma_pixel_px: float | None = None,
    pixel_jacs: Sequence[Any] | None = None,
    sight_memos: Sequence[dict[str, Any]] | None = None,
) -> tuple[RowStructure, RowColumns]:
    """``line_scan_rows`` of several strips (each an ``ObservationSet`` of lines with its own trajectory) as one
    campaign: rows, images, targets and attitude samples side by side, strip k the pass k (its per-pass errors
    shared by its lines), x common; ``pixel_jacs`` each strip's ``pixel_jacobian`` (None: computed), ``sight_memos``
    each strip's ``line_scan_jacobian`` memo (None: none kept). One strip: its own rows."""
    jacs = [None] * len(strips) if pixel_jacs is None else list(pixel_jacs)
    memos: list[dict[str, Any] | None] = [None] * len(strips) if sight_memos is None else list(sight_memos)
    parts = [line_scan_rows(o, x, unknowns, model, sigma_pixel_px, J, m) for o, J, m in zip(strips, jacs, memos, strict=True)]
    if len(parts) == 1:
        return parts[0]
    img, tgt, si, sw, corr = [], [], [], [], []
    n_img = n_tgt = n_smp = 0
    for st, _ in parts:
        img.append(st.image_index + n_img)
        tgt.append(st.target_index + n_tgt)
        assert st.sample_index is not None and st.sample_weight is not None and st.n_samples is not None
        si.append(st.sample_index + n_smp)
        sw.append(st.sample_weight)
        # DECISION: each strip's Gauss–Markov tracker error is its own process (φ = 0 at its first sample): strips of a
        # campaign are orbits apart, ≫ τ (the simulator draws them independently, ``orbits.strip.simulate_campaign``)
        corr.append(st.sample_correlation)
        n_img, n_tgt, n_smp = n_img + st.n_images, n_tgt + st.n_targets, n_smp + st.n_samples
    passes = np.concatenate([np.full(st.n_images, k) for k, (st, _) in enumerate(parts)])
    st = RowStructure(
        np.concatenate(img),
        np.concatenate(tgt),
        passes,
        n_tgt,
        sample_index=np.concatenate(si),
        sample_weight=np.concatenate(sw),
        n_samples=n_smp,
        sample_correlation=None if any(c is None for c in corr) else np.concatenate([c for c in corr if c is not None]),
    )
    cat = {name: np.concatenate([getattr(c, name) for _, c in parts], axis=1) for name in ("X", "q", "A", "B", "C")}
    return st, RowColumns(**cat)


@dataclass(frozen=True)
class _LineProblem:
    """What a line fit keeps fixed over its steps: the strips, the unknowns, the noise model and the pixel σ, and each
    strip's sight memo (``line_scan_jacobian``: a θ-only fit interpolates each strip's trajectory once)."""

    strips: list[Any]
    unknowns: LineScanUnknowns
    model: DisturbanceModel
    sigma_pixel_px: float | None
    sight_memos: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.sight_memos[:] = [{} for _ in self.strips]

    def rows(self, x: np.ndarray, pixel_jacs: Sequence[Any]) -> tuple[RowStructure, RowColumns]:
        """``stacked_rows`` of the strips at x."""
        return stacked_rows(self.strips, x, self.unknowns, self.model, self.sigma_pixel_px, pixel_jacs, self.sight_memos)


def _gauss_newton(lines: _LineProblem, x: np.ndarray, max_iter: int, tol_sigma: float) -> LineScanFit:
    strips, unknowns = lines.strips, lines.unknowns
    # DECISION: each row's pixel covariance (σ² J Jᵀ) is taken at the first iterate and kept: J moves with θ and κ by
    # ~|θ| ≈ 1e-4 relative, and the whitening does not move the fit's fixed point (r = 0 on noise-free data)
    jacs: list[Any] = []

    def first(o: Any, r0: np.ndarray) -> np.ndarray:  # J at the first iterate, from its residuals (pixel_jacobian)
        jacs.append(pixel_jacobian(o, x, unknowns, r0))
        out: np.ndarray = jacs[-1]
        return out

    it, converged = 0, False
    for it in range(1, max_iter + 1):
        st, cols = lines.rows(x, jacs if jacs else [first] * len(strips))
        fit = row_gls(st, cols)
        step = fit.normal_equations.solve(check=False)
        dx = step.theta[0]
        x = x + dx
        converged = bool(np.all(np.abs(dx) <= tol_sigma * np.sqrt(np.diag(step.covariance[0]))))
        if converged:
            break
    # the last step is below tol_sigma·σ: its fit's covariance and χ² (minimised over that step) are those at x to
    # first order in the step (≤ 1e-6 σ), so the rows are not built again; so is z, each row's pixel-level normalised
    # residual length: the last fit's MAP nuisances given x moved by the last step, as the frame GLS's
    # (``estimation._final_residuals``: ``gls.rows.row_residuals`` at the last step, the one implementation)
    from boresight.core.gls.rows import row_residuals

    z = np.linalg.norm(row_residuals(fit, step.theta), axis=-1)[0]
    dof = int(fit.normal_equations.n_residuals[0]) - x.size
    return LineScanFit(unknowns.names, x, step.covariance[0], float(step.chi2[0]), dof, it, fit, converged, z=z)


#: a robust line fit reweights at most this many times by default (Huber from θ = 0 on a strip with 2 % gross
#: outliers: ~8 steps)
MAX_ITER_ROBUST = 50


def _first_jacobians(strips: list[Any], x: np.ndarray, unknowns: LineScanUnknowns) -> list[np.ndarray]:
    """Each strip's ``pixel_jacobian`` at x (forward difference from its residuals), as the least-squares loop takes them."""
    return [pixel_jacobian(o, x, unknowns, line_scan_residuals(o, x, unknowns)) for o in strips]


def _robust_gauss_newton(lines: _LineProblem, x: np.ndarray, max_iter: int, loss: str) -> LineScanFit:
    from boresight.core.gls.rows import row_residuals
    from boresight.core.robust import (
        CHI2_INLIER_Z,
        ROBUST_TOLERANCE_SIGMA,
        ROBUST_WEIGHT_TOLERANCE,
        m_estimator_covariance_rows,
        robust_weights,
    )

    strips, unknowns = lines.strips, lines.unknowns
    jacs = _first_jacobians(strips, x, unknowns)  # kept, as in the least-squares loop (its DECISION)
    zero = np.zeros((1, x.size))
    w: np.ndarray | None = None
    it, converged = 0, False
    for it in range(1, max_iter + 1):
        st, cols = lines.rows(x, jacs)
        z = np.linalg.norm(row_residuals(row_gls(st, cols, w), zero), axis=-1)
        # DECISION: Tukey's redescending loss starts from Huber weights (3 steps), as the frame camera's robust fits
        w_new = robust_weights(z, "huber" if (loss == "tukey" and it <= 3) else loss)
        step = row_gls(st, cols, w_new).normal_equations.solve(check=False)
        dx = step.theta[0]
        x = x + dx
        stable = w is not None and float(np.max(np.abs(w_new - w))) < ROBUST_WEIGHT_TOLERANCE
        small = bool(np.all(np.abs(dx) <= ROBUST_TOLERANCE_SIGMA * np.sqrt(np.diag(step.covariance[0]))))
        w = w_new
        converged = small and stable and not (loss == "tukey" and it <= 3)
        if converged:
            break
    st, cols = lines.rows(x, jacs)
    fit = row_gls(st, cols, w)
    z = np.linalg.norm(row_residuals(fit, zero), axis=-1)
    cov = m_estimator_covariance_rows(st, cols, z, loss, None)[0]
    kept = z[0] <= CHI2_INLIER_Z
    chi2 = float(row_gls(st, cols, kept[None].astype(float)).normal_equations.solve(check=False).chi2[0])
    assert w is not None  # at least one step
    return LineScanFit(
        unknowns.names, x, cov, chi2, int(2 * kept.sum()) - x.size, it, fit, converged, loss=loss, weights=w[0], z=z[0]
    )


def is_line_scan_input(observations: Any) -> bool:
    """True for what ``estimate_lines`` takes: a set whose images are pushbroom lines (``ObservationSet.line_scan``), or a
    non-empty list or tuple of such sets (a campaign of strips)."""
    items = list(observations) if isinstance(observations, (list, tuple)) else [observations]
    return bool(items) and all(getattr(o, "line_scan", None) is not None for o in items)


def estimate_lines(
    obs: Any,
    *,
    weighting: str = "gls",
    iterate: Any = True,
    model: DisturbanceModel | None = None,
    prior_sigma_arcsec: Any = None,
    unknowns: LineScanUnknowns | None = None,
    sigma_pixel_px: float | None = None,
    x0: Any = None,
    loss: str | None = None,
) -> Any:
    """``boresight.estimate(strips)`` on pushbroom lines (registry name ``line_scan``): ``estimate_line_scan`` as an
    ``Estimate``.

    ``obs``: one set of lines or a list of them (a campaign, ``stacked_rows``). Only ``weighting="gls"`` under a noise
    model (``model``, or the first strip's own ``noise``: ``estimate`` passes it) — the line model's σ is the GLS's,
    with the tracker's errors on the attitude-sample table; no prior on θ. ``unknowns`` (default θ only) floats the
    line's own parameters; each is reported in ``effects`` ({quantity: (value, σ)}, Quantities in arcsec, s or
    dimensionless; the quantity is the unknown's name without its SI suffix, ``quantity_and_unit``: ``chip1_along``) and
    with θ in ``joint_covariance`` over ``joint_labels`` (``theta_x``, …, the same quantities) in ``joint_units``. ``residuals`` (K, 2) are the rows'
    focal-plane residuals (m) at the solution, strip after strip; ``algorithm_result`` is the ``LineScanFit``.

    >>> import numpy as np
    >>> from boresight import estimate
    >>> from boresight.observations.strip import simulate_strip_scenario
    >>> from orbits.strip import load_strip_scenario
    >>> strips = simulate_strip_scenario(load_strip_scenario("pushbroom-strip"), np.random.default_rng(1))
    >>> est = estimate(strips)                                    # doctest: +SKIP
    >>> est.algorithm, est.weighting                              # doctest: +SKIP
    ('line_scan', 'gls')
    """
    from astropy import units as u

    from boresight.core.result import Estimate, estimate_warnings, sigma_includes, top_residuals
    from boresight.errors import InputValueError

    strips = list(obs) if isinstance(obs, (list, tuple)) else [obs]
    if not is_line_scan_input(strips):
        raise InputValueError("estimate: algorithm 'line_scan' takes a set of pushbroom lines or a list of them")
    if weighting != "gls" or model is None:
        raise InputValueError(
            f"estimate: algorithm 'line_scan' is a GLS under a noise model (weighting='gls' with model= or the set's own "
            f"noise), got weighting={weighting!r} and {'no model' if model is None else 'a model'}"
        )
    if prior_sigma_arcsec is not None:
        raise InputValueError("estimate: algorithm 'line_scan' takes no prior on θ (prior_sigma_arcsec)")
    unknowns = LineScanUnknowns() if unknowns is None else unknowns
    fit = estimate_line_scan(strips, unknowns, model, sigma_pixel_px, x0, iteration_limit(iterate), loss=loss)
    res = np.concatenate([line_scan_residuals(o, fit.x, unknowns) for o in strips])
    labels, si = zip(*(quantity_and_unit(n) for n in fit.names))
    units = [u.arcsec if s == "rad" else (u.s if s == "s" else u.dimensionless_unscaled) for s in si]
    scale = np.array([_ARCSEC if s == "rad" else 1.0 for s in si])
    joint = fit.covariance / np.outer(scale, scale)
    values = fit.x / scale
    d = np.sqrt(np.diag(fit.covariance))
    cond = float(np.linalg.cond(fit.covariance / np.outer(d, d)))
    theta, cov = fit.x[None, :3], fit.covariance[None]
    warnings = estimate_warnings(
        strips[0],
        theta,
        cov,
        None,
        np.array([True]),
        np.zeros(1),
        fit.iterations,
        np.array([fit.chi2]),
        float(fit.dof),
        True,
        None,
        {},
        tolerance_rad=0.0,
    )
    if not fit.converged:
        warnings.insert(0, f"did not converge in {fit.iterations} Gauss–Newton steps (a step still above its tolerance)")
    if fit.weights is not None and fit.z is not None:
        from boresight.core.robust import REJECTED_WEIGHT

        bad = np.flatnonzero(fit.weights < REJECTED_WEIGHT)
        if bad.size:
            k = int(bad[np.argmax(fit.z[bad])])
            warnings.append(
                f"the {loss} loss rejected {bad.size} detection(s) outright (weight < {REJECTED_WEIGHT:g}); worst: row {k} of "
                f"the stacked strips, normalised residual {fit.z[k]:.4g}. θ ignores them: check those detections"
            )
    return Estimate(
        theta=fit.theta_arcsec * u.arcsec,
        covariance=joint[:3, :3] * u.arcsec**2,
        residuals=res,
        chi2=np.asarray(fit.chi2),
        dof=np.asarray(fit.dof),
        condition_number=np.asarray(cond),
        iterations=fit.iterations,
        converged=np.asarray(fit.converged),
        algorithm="line_scan",
        weighting="gls",
        residual_unit="m (focal plane)",
        warnings=tuple(warnings),
        sigma_includes=sigma_includes(model, "gls", False, len(fit.names) - 3, loss),
        loss=loss,
        robust_weights=fit.weights,
        whitened_residual_norm=fit.z,
        largest_residuals=top_residuals(np.arange(res.shape[0]), _row_labels(strips), fit.z) if fit.z is not None else (),
        chi2_kept_observations=None if fit.z is None or loss is None else int(np.sum(fit.z <= _inlier_z())),
        effects={n: (values[j] * units[j], d[j] / scale[j] * units[j]) for j, n in enumerate(labels) if j >= 3},
        chi2_model=np.asarray(fit.chi2),
        dof_model=float(fit.dof),
        joint_covariance=joint,
        joint_labels=labels,
        joint_units=tuple(str(x) for x in units),
        algorithm_result=fit,
    )


def _row_labels(strips: Sequence[Any]) -> np.ndarray:
    """Each row of the stacked ``strips`` named as a user finds it in the file: its measured line and its point's id,
    prefixed by its strip (0, 1, … in the order given) when there are several."""
    out = []
    for s, o in enumerate(strips):
        lines = np.asarray(o.line_scan.line, float)[np.asarray(o.image_index)]
        ids = np.asarray(o.landmark_ids)[np.asarray(o.target_index)]
        prefix = f"strip {s} " if len(strips) > 1 else ""
        out += [f"{prefix}line {ln:.1f} {i}" for ln, i in zip(lines, ids, strict=True)]
    return np.array(out, dtype=object)


def _inlier_z() -> float:
    from boresight.core.robust import CHI2_INLIER_Z

    return CHI2_INLIER_Z
