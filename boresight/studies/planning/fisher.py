"""Fisher information of candidate campaigns: per-pass blocks that add.

The augmented model of one campaign (linearised at θ = 0 and effect parameters p = 0):

    q = G θ + J p + e,   e = ε_pix + Σ_n A_n a_n + Σ_passes B_j b_j + Σ_m C_m c_m

with G the image-plane Jacobian of θ (``boresight.core.algorithms.image_plane``), J the effects'
columns (``boresight.core.effect_model.effect_columns``: one definition shared with the simulator and
the estimators), and the nuisances of the disturbance model (``boresight.core.crlb``): pixel noise,
per-image star-tracker/GNSS errors a_n, per-pass star-tracker/GNSS errors b_j and catalogue
errors c_m. Marginalising the Gaussian nuisances gives the information of x = [θ, p]

    I(x) = Xᵀ Σ⁻¹ X,   X = [G J],   Σ = cov(e)

computed by the one GLS on rows (``boresight.core.gls.rows``, with the nuisance columns of
``boresight.core.gls.structure`` on the rows): the planner's Fisher blocks are the GLS's reduced
information, one row per observation (``docs/architecture.md``, "The row model"; no images ×
landmarks array). ``crlb.full_residual_covariance`` (a dense Σ) is the independent route the tests
compare to.

Every nuisance belongs to one pass (a pass's landmarks are its own, as in the simulator), so Σ
is block-diagonal over passes and **the information of a campaign is the sum of its passes'
blocks**: I_campaign = Σ_j I_j (tested against the dense bound of the whole campaign in
``tests/studies/test_planning.py``). A block is computed once per pass option; scoring a candidate is a
sum of small (3 + K)² matrices and one inverse — so 10⁵ candidates score in about a second.

From the covariance P = I⁻¹ (θ in arcsec, effects in their units):

* predicted σθ = √diag(P)[:3] with the required effects floated (the fit the analyst will run);
* minimum detectable size of effect e (k parameters, required vector p_e): the likelihood-ratio
  (= Wald, linear Gaussian model) test of p_e = 0 at level α/K (the diagnosis' Bonferroni level,
  ``n_candidates`` = K) has non-centrality λ(p) = pᵀ (P_ee)⁻¹ p; it detects with the stated
  power when λ ≥ λ*(k, α/K, power) (non-central χ²). The detectable size along the required
  direction is ρ_e p_e with ρ_e = √(λ*/λ(p_e)); the requirement is met when ρ_e ≤ 1.

**The scanned rival ``alignment_step``** (a constant camera rotation s of every image after a
boundary t_b, ``orbits.effects``) is not a per-pass column, but its information is still a sum of
per-pass blocks: the passes of a candidate are flown in the order of its option indices (pass k of
the scenario k days after the first; star-frame segments after the passes, ``campaign_arrays``), and
a step at the gap before pass b has, over passes b…n, exactly θ's columns and none before. Its Gram
blocks with [θ, effects] are therefore T_b = Σ_{j≥b} I_j[θ, ·] (and its own T_b[θ, θ]): suffix sums
of the blocks' θ rows over the ordered passes (``step_terms``; the same for R). The diagnosis scans
the B = n − 1 gaps and keeps the best-fitting boundary; the planner scores the worst one for each
required effect: as a look-alike the largest ρ_e over b, as a naming rival the b whose step takes the
largest share λ_f = pᵀ S_ef S_ff⁻¹ S_fe p of e's signal (so the smallest λ_sep), charged as the
diagnosis charges a scan (level/B, 2 ln B: ``naming_power.nameable_sizes``).

Whether the diagnosis will *name* a detectable effect (separability, BIC, its ambiguity rule) is
``naming``'s question; it needs, beside I, the information with only the per-image errors
marginalised (``information_block(..., raw=True)``), which also adds over passes.

A direction the campaign cannot separate (a singular information) gets a ridge of 1e-12 (after
scaling to unit diagonal), i.e. a σ ~10⁶ times its diagonal scale: ρ is then huge and reported
as "not separable".

DECISION: a σθ beyond the small-angle range (``orbits.rotations.SMALL_ANGLE_LIMIT_ARCSEC``, 10°) is
reported as ``inf`` — "this campaign does not determine θ on that axis". Such a value only reflects
the ridge and the last bits of the arithmetic (321 624″ on one BLAS kernel was 321 624.70″ on
another), and the linear error model it comes from does not hold that far from zero anyway. In the
same way a ratio ρ above ``NOT_SEPARABLE_RATIO`` (10⁴: an effect detectable only at 10⁴ times its
required size) is reported as ``inf``: the campaign cannot separate it, and the digits of such a ρ
come from the ridge, not from the data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbits.rotations import ARCSEC, SMALL_ANGLE_LIMIT_ARCSEC

__all__ = [
    "noise_free_observations",
    "information_block",
    "linear_gls",
    "covariance_batch",
    "Scores",
    "score_candidates",
    "step_terms",
    "naming_with_step",
    "NOT_SEPARABLE_RATIO",
]

#: a detectable-size ratio above this means the campaign cannot separate the effect at all
NOT_SEPARABLE_RATIO = 1e4
#: ridge added to the unit-diagonal information before inverting (see ``covariance_batch``)
EIGEN_FLOOR = 1e-12
#: a unit-diagonal-scaled variance above this flags a direction the data cannot determine
SINGULAR_VARIANCE = 1e8


def noise_free_observations(scenario):
    """The ``ObservationSet`` of a scenario with every error set to zero (one run), and its
    ``DisturbanceModel`` — the geometry the information is evaluated at."""
    from boresight.core.disturbances import DisturbanceModel
    from boresight.observations.simulate import nominal_observations

    obs = nominal_observations(scenario)
    return obs, DisturbanceModel.from_scenario(scenario)


def design_columns(obs, effect_names) -> tuple[np.ndarray, tuple]:
    """X (R, 2K, 3 + k): ∂q/∂θ per arcsec, then ∂q/∂p per unit of each effect parameter, for the K
    observations (rows in the set's canonical order, their two components interleaved); labels."""
    R = obs.runs
    if effect_names:
        from boresight.core.effect_model import effect_columns

        cols = effect_columns(obs, np.zeros(3), list(effect_names))
        X = np.concatenate([np.asarray(cols.theta_jacobian, float) * ARCSEC, np.asarray(cols.jacobian, float)], axis=-1)
        labels = ("theta_x", "theta_y", "theta_z") + tuple(cols.labels)
        bad = {k: v for k, v in cols.status.items() if v != "ok"}
        if bad:
            from boresight.studies.planning.spec import PlanError

            raise PlanError(f"the effect columns cannot be evaluated for this pass: {bad}")
    else:
        from boresight.core.algorithms.image_plane import linearize

        G, _ = linearize(obs, np.zeros(3))  # (R, K, 2, 3) on the rows
        X = G * ARCSEC
        labels = ("theta_x", "theta_y", "theta_z")
    return X.reshape(R, -1, X.shape[-1]), labels


def _check_pixel(model):
    if not model.sigma_pixel_m > 0:
        from boresight.studies.planning.spec import PlanError

        raise PlanError(
            f"[pixel] sigma_m = {model.sigma_pixel_m!r}: the planner needs a pixel noise > 0 (the information is infinite without it)"
        )


def _gls_information(obs, model, X, q=None):
    """The GLS on rows (``boresight.core.gls.campaign.fit_rows``) of design columns X (R, 2K, P) and
    residuals q (R, 2K) or none, at θ = 0: its ``NormalEquations`` (information XᵀΣ⁻¹X, XᵀΣ⁻¹q)."""
    from boresight.core.gls.campaign import fit_rows

    R, K = obs.runs, obs.n_observations
    X = np.asarray(X, float).reshape(R, K, 2, -1)
    q = np.zeros((R, K, 2)) if q is None else np.asarray(q, float).reshape(R, K, 2)
    return fit_rows(obs, np.zeros(3), X, q, model).normal_equations


def information_block(obs, model, effect_names=(), raw: bool = False):
    """Fisher information (P, P) of [θ (arcsec), effect parameters (their units)] of ``obs``
    (one run) with every nuisance of ``model`` marginalised; and the labels (P,).

    The reduced information of the GLS on rows (``boresight.core.gls.rows``: the nuisances of
    ``boresight.core.gls.structure`` eliminated exactly) with the design columns X in place of the
    algorithm's Jacobian: I = XᵀΣ⁻¹X. ``crlb.full_residual_covariance`` (a dense Σ) is the
    independent route the tests compare to.

    ``raw=True`` returns (I, R, n_rows, labels) with also R, the information with only the
    per-image errors marginalised (``gls.structure.restricted(model, ("image",))``: the
    whitening of ``boresight.diagnose``; ``naming``), and n_rows the number of observed residuals
    (2 per landmark observation).
    """
    from boresight.core.gls.structure import restricted

    _check_pixel(model)
    X, labels = design_columns(obs, effect_names)

    def info_with(m):
        info = _gls_information(obs, m, X).data_information[0]
        return 0.5 * (info + info.T)

    info = info_with(model)
    if not raw:
        return info, labels
    return info, info_with(restricted(model, ("image",))), int(2 * obs.n_observations), labels


def linear_gls(obs, model, effect_names=()) -> tuple[np.ndarray, np.ndarray, tuple]:
    """GLS fit of [θ (arcsec), effects (their units)] by one Gauss–Newton step from θ = 0, p = 0,
    every nuisance marginalised: x̂ = I⁻¹ Xᵀ Σ⁻¹ q per run. Returns x̂ (R, P), covariance
    (R, P, P), labels.

    The Monte Carlo checks' fast fit (``checks``): the GLS of ``boresight.estimate``
    (``boresight.core.gls.rows``, batched over runs) linearised once about θ0 = 0
    (``iterate=False``; equal to it in ``tests/studies/test_planning.py``), with effects floated. One step
    from 0 leaves an error O(|θ|²) ≈ 0.01″ at |θ| = 50″.
    """
    from boresight.core.algorithms.image_plane import linearize

    _check_pixel(model)
    X, labels = design_columns(obs, effect_names)
    _, q = linearize(obs, np.zeros(3))
    ne = _gls_information(obs, model, X, q)
    info = 0.5 * (ne.data_information + np.swapaxes(ne.data_information, -1, -2))
    cov = np.linalg.inv(info)
    return np.einsum("rij,rj->ri", cov, ne.vector), cov, labels


def covariance_batch(info: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Covariance (C, P, P) of a batch of information matrices, and a flag (C,) True where the
    information is (nearly) singular — a direction the data cannot determine.

    DECISION: each matrix is scaled to unit diagonal and a ridge of ``EIGEN_FLOOR`` added before
    the (batched LU) inverse, so a singular direction gets a scaled variance of ~1/EIGEN_FLOOR
    instead of an error: the batch never stops on one degenerate candidate, and that candidate's
    detectable sizes come out huge ("not separable"). The ridge changes a well-determined
    variance by a relative ~1e-12 × its condition number (negligible below 1e8, the flag's
    threshold). A batched LU is 4× faster than a batched eigendecomposition here; the flagged
    matrices are inverted again through their eigenvalues (floored at 1e-12 of the largest),
    which stays positive where the LU of a near-singular matrix loses every digit.
    """
    P = info.shape[-1]
    d = np.sqrt(np.clip(np.diagonal(info, axis1=-2, axis2=-1), 0.0, None))
    dz = np.where(d > 0, d, 1.0)
    outer = dz[..., :, None] * dz[..., None, :]
    s = info / outer
    cov_s = np.linalg.inv(s + EIGEN_FLOOR * np.eye(P))
    dg = np.diagonal(cov_s, axis1=-2, axis2=-1)
    singular = np.any(dg > SINGULAR_VARIANCE, axis=-1) | np.any(d == 0, axis=-1) | np.any(~(dg > 0), axis=-1)
    if singular.any():  # the few degenerate ones again, by eigenvalues (exactly PSD, floored)
        lam, V = np.linalg.eigh(s[singular])
        lam = np.maximum(lam, EIGEN_FLOOR * np.maximum(lam[..., -1:], 1e-300))
        cov_s[singular] = (V / lam[..., None, :]) @ np.swapaxes(V, -1, -2)
    cov_s /= outer  # the covariance, in place (the batch's temporaries are its largest arrays)
    cov = cov_s + np.swapaxes(cov_s, -1, -2)
    cov *= 0.5
    return cov, singular


@dataclass(frozen=True)
class Scores:
    """Scores of C candidates.

    ``sigma_theta_arcsec`` (C, 3) with the required effects floated; ``sigma_theta_only_arcsec``
    (C, 3) with no effect floated; ``detect_ratio`` (C, E) ρ_e (detectable size / required
    size; ≤ 1 meets the requirement) — the worst of ``detect_ratio_joint`` (C, E) (θ + the
    required effects floated) and ``lookalike_ratio`` (C, E, F) (θ + the required effects + one
    look-alike f floated); ``cost`` (C,); ``singular`` (C,).
    """

    sigma_theta_arcsec: np.ndarray
    sigma_theta_only_arcsec: np.ndarray
    detect_ratio: np.ndarray
    cost: np.ndarray
    singular: np.ndarray
    detect_ratio_joint: np.ndarray | None = None
    lookalike_ratio: np.ndarray | None = None
    name_ratio: np.ndarray | None = None
    name_probability: np.ndarray | None = None
    canonical_rho: np.ndarray | None = None
    binding_rival: np.ndarray | None = None


def effect_lambda(cov, effect_slices, required):
    """λ (…, E) = pᵀ (P_ee)⁻¹ p of each effect at its required size."""
    lam = np.empty(cov.shape[:-2] + (len(effect_slices),))
    for j, (sl, p) in enumerate(zip(effect_slices, required)):
        Pe = cov[..., sl, sl]
        lam[..., j] = np.linalg.solve(Pe, np.broadcast_to(p, Pe.shape[:-1])[..., None])[..., 0] @ p
    return lam


def _rho(cov, effect_slices, required, lam_star):
    return np.sqrt(np.asarray(lam_star) / np.maximum(effect_lambda(cov, effect_slices, required), 1e-300))


def _covariance_with(cov, I_bf, I_ff):
    """Covariance of the base parameters b when a look-alike f is added to the model, from the base
    covariance Σ_b (…, nb, nb) and the information blocks I_bf (…, nb, kf), I_ff (…, kf, kf):
    Σ_b' = Σ_b + M W Mᵀ, M = Σ_b I_bf, W = (I_ff − I_bfᵀ M)⁻¹ (block inversion; equal to inverting
    the (nb + kf)² information, tested, at a small fraction of the cost). W is inverted after
    scaling to I_ff's unit diagonal with the ridge ``EIGEN_FLOOR`` (as ``covariance_batch``), so a
    look-alike the base absorbs entirely makes the variances huge instead of failing; one with no
    signal (zero diagonal) adds nothing."""
    M = cov @ I_bf
    S = I_ff - np.swapaxes(I_bf, -1, -2) @ M
    d = np.sqrt(np.clip(np.diagonal(I_ff, axis1=-2, axis2=-1), 0.0, None))
    live = d > 0
    dz = np.where(live, d, 1.0)
    Ss = S / (dz[..., :, None] * dz[..., None, :]) + EIGEN_FLOOR * np.eye(S.shape[-1])
    W = np.linalg.inv(Ss) / (dz[..., :, None] * dz[..., None, :])
    W = W * (live[..., :, None] & live[..., None, :])
    out = cov + M @ W @ np.swapaxes(M, -1, -2)
    return 0.5 * (out + np.swapaxes(out, -1, -2))


def _determined(sigma_arcsec: np.ndarray) -> np.ndarray:
    """σθ (arcsec) with values beyond the small-angle range set to inf: not determined (see the module's DECISION)."""
    return np.where(sigma_arcsec > SMALL_ANGLE_LIMIT_ARCSEC, np.inf, sigma_arcsec)


def _base_scores(base, effect_slices, required, lam_star):
    """From the base information [θ, required effects] (C, nb, nb): its covariance, singular flags,
    σθ with the effects floated and with none, λ and ρ of each required effect (jointly floated)."""
    cov, singular = covariance_batch(base)
    sig = _determined(np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1)[..., :3]))
    cov_t, _ = covariance_batch(base[..., :3, :3])
    sig_only = _determined(np.sqrt(np.diagonal(cov_t, axis1=-2, axis2=-1)))
    lam_joint = effect_lambda(cov, effect_slices, required)
    return cov, singular, sig, sig_only, lam_joint, np.sqrt(np.asarray(lam_star) / np.maximum(lam_joint, 1e-300))


def step_terms(blocks: np.ndarray, idx, raw_blocks=None) -> tuple:
    """The step's Gram terms of candidates ``idx`` ((C, n) option indices in flight order, −1 = none, or a
    list of index lists): (T (C, n − 1, 3, P), T_raw or None, B (C,)) with T[:, b − 1] = Σ_{k ≥ b} blocks[idx[:, k]][:3]
    — the information rows of a step at the gap before the (b+1)-th pass (module docstring) — and B = max(n_c − 1, 1) the
    boundaries the diagnosis scans in a campaign of n_c passes. A boundary past the last pass has T = 0 (no signal)."""
    if not isinstance(idx, np.ndarray):
        n = max(len(x) for x in idx)
        idx = np.array([list(x) + [-1] * (n - len(x)) for x in idx], np.int64)
    idx = np.atleast_2d(idx)
    O, P, _ = blocks.shape
    ii = np.where(idx < 0, O, idx)

    def suffix(bl):
        th = np.concatenate([np.asarray(bl)[:, :3, :], np.zeros((1, 3, P))])
        T = np.zeros((ii.shape[0], max(ii.shape[1] - 1, 0), 3, P))
        acc = np.zeros((ii.shape[0], 3, P))
        for k in range(ii.shape[1] - 1, 0, -1):
            acc += th[ii[:, k]]
            T[:, k - 1] = acc
        return T

    B = np.maximum((idx >= 0).sum(axis=1) - 1, 1).astype(float)
    return suffix(blocks), None if raw_blocks is None else suffix(raw_blocks), B


def _augment(info, Tb):
    """[x, s] information (C, P + 3, P + 3) from that of x (C, P, P) and the step's rows Tb (C, 3, P)."""
    C, P, _ = info.shape
    out = np.empty((C, P + 3, P + 3))
    out[:, :P, :P] = info
    out[:, P:, :P] = Tb
    out[:, :P, P:] = np.swapaxes(Tb, -1, -2)
    out[:, P:, P:] = 0.5 * (Tb[..., :3] + np.swapaxes(Tb[..., :3], -1, -2))
    return out


def _step_rho(cov, step, nb, rho_joint, effect_slices, required, lam_star):
    """ρ (C, E) with the step floated at its worst boundary (the largest ρ over b)."""
    rho_s = rho_joint.copy()
    for b in range(step[0].shape[1]):
        Tb = step[0][:, b]
        cov_f = _covariance_with(cov, np.swapaxes(Tb[..., :nb], -1, -2), 0.5 * (Tb[..., :3] + np.swapaxes(Tb[..., :3], -1, -2)))
        rho_s = np.maximum(rho_s, _rho(cov_f, effect_slices, required, lam_star))
    return rho_s


def naming_with_step(info, raw, n_rows, effect_slices, required, lam_joint, rival_slices, rule, step=None) -> tuple:
    """``naming.naming_scores`` with, when ``step`` (``step_terms``) is given, ``alignment_step`` as one more
    rival (the last: index len(rival_slices) of the binding rival) at each required effect's worst boundary,
    charged for the scan of its B boundaries (module docstring)."""
    from boresight.studies.planning.naming import naming_scores, theta_schur

    if step is None or step[0].shape[1] == 0 or step[1] is None:
        return naming_scores(info, raw, n_rows, effect_slices, required, lam_joint, rival_slices, rule)
    T, T_raw, B = step
    C, P, _ = info.shape
    rivals = list(rival_slices) + [slice(P, P + 3)]
    scans = [None] * len(rival_slices) + [B]
    out = None
    rows = np.arange(C)
    for j, (sl, p) in enumerate(zip(effect_slices, required)):
        share = np.zeros((C, T.shape[1]))
        for b in range(T.shape[1]):
            S = theta_schur(_augment(info, T[:, b]))
            v = np.swapaxes(S[:, sl.start - 3 : sl.stop - 3, P - 3 :], -1, -2) @ np.asarray(p, float)  # S_fe p (C, 3)
            share[:, b] = np.einsum("ci,cij,cj->c", v, np.linalg.pinv(S[:, P - 3 :, P - 3 :], rcond=1e-10, hermitian=True), v)
        worst = np.argmax(share, axis=1)
        got = naming_scores(
            _augment(info, T[rows, worst]),
            _augment(raw, T_raw[rows, worst]),
            n_rows,
            effect_slices,
            required,
            lam_joint,
            rivals,
            rule,
            scan_sizes=scans,
        )
        if out is None:
            out = tuple(np.array(g) for g in got)
        for o, g in zip(out, got):
            o[:, j] = g[:, j]
    return out


def score_information(
    info: np.ndarray, effect_slices, required, lam_star, lookalike_slices=(), raw=None, n_rows=None, rule=None, step=None
) -> tuple:
    """(σθ (C,3), σθ θ-only (C,3), ρ (C,E), singular (C,), ρ joint (C,E), ρ look-alike (C,E,F),
    then η, P_name, canonical ρ, binding rival (each (C,E), None without ``raw``)) for
    information matrices (C, P, P) ordered [θ, required effects, look-alikes].

    A look-alike f is a catalogue effect the diagnosis also tests: ρ_e is the worst over f of
    ρ_e in the model θ + required effects + f (detectable with f floated). The naming scores
    (``naming.naming_scores``) need ``raw`` (C, P, P), the information with only the per-image
    errors marginalised, ``n_rows`` (C,) and the ``rule`` (``naming.NamingRule``). ``step``
    (``step_terms``): ``alignment_step`` is one more look-alike (the last column of ρ look-alike) and rival.
    """
    nb = 3 + sum(sl.stop - sl.start for sl in effect_slices)
    cov, singular, sig, sig_only, lam_joint, rho_joint = _base_scores(info[..., :nb, :nb], effect_slices, required, lam_star)
    rho_f = np.zeros(rho_joint.shape + (len(lookalike_slices),))
    for k, sl in enumerate(lookalike_slices):
        cov_f = _covariance_with(cov, info[..., :nb, sl], info[..., sl, sl])
        rho_f[..., k] = _rho(cov_f, effect_slices, required, lam_star)
    if step is not None:
        rho_s = _step_rho(cov, step, nb, rho_joint, effect_slices, required, lam_star)
        rho_f = np.concatenate([rho_f, rho_s[..., None]], axis=-1)
    rho = np.maximum(rho_joint, rho_f.max(axis=-1)) if rho_f.shape[-1] else rho_joint
    naming = (None, None, None, None)
    if raw is not None:
        naming = naming_with_step(
            info, raw, n_rows, effect_slices, required, lam_joint, list(effect_slices) + list(lookalike_slices), rule, step
        )
    rho, rho_joint, rho_f = (np.where(r > NOT_SEPARABLE_RATIO, np.inf, r) for r in (rho, rho_joint, rho_f))
    return (sig, sig_only, rho, singular, rho_joint, rho_f) + tuple(naming)


def _sum_blocks(padded, ii):
    """Σ_k padded[ii[:, k]] (C, P, P), pass by pass (no (C, n_max, P, P) temporary)."""
    out = padded[ii[:, 0]].copy()
    for k in range(1, ii.shape[1]):
        out += padded[ii[:, k]]
    return out


def bound_scores(blocks, idx, effect_slices, required, lam_star, chunk: int = 4096, option_rows=None, rule=None):
    """The cheap part of the scores of every candidate (option indices ``idx`` (C, n_max), −1 = none),
    from the base information [θ, required effects] only: σθ (C, 3) with the required effects floated,
    σθ (C, 3) with none, ρ joint (C, E), singular (C,) — equal to ``score_information``'s — and a lower
    bound (C, E) of the requirement ratio: with the naming rule η ≥ t_det / ``LOWER_BOUND_SLACK``
    (``naming.detection_only_size``: naming needs detection), without it ρ ≥ ρ joint.

    ``search.run_search`` scores in full (look-alikes, naming) only the candidates these bounds do
    not rule out of the Pareto front and the choice."""
    nb = 3 + sum(sl.stop - sl.start for sl in effect_slices)
    O = blocks.shape[0]
    padded = np.concatenate([blocks[:, :nb, :nb], np.zeros((1, nb, nb))])
    npad = None if option_rows is None else np.concatenate([np.asarray(option_rows, float), [0.0]])
    idx = np.where(idx < 0, O, idx)
    naming = rule is not None and npad is not None and bool(effect_slices)
    if naming:
        from boresight.studies.discrepancy.naming_power import LOWER_BOUND_SLACK, detection_only_size

        # the detection threshold λ* depends on the candidate only through its row count (BIC):
        # computed once per distinct count over all candidates, then t_det = √(λ*/λ)
        rows_u, inv = np.unique(npad[idx].sum(axis=1), return_inverse=True)
        t_unit = [detection_only_size(np.ones(rows_u.size), rows_u, sl.stop - sl.start, rule)[0] for sl in effect_slices]
    out = []
    for a in range(0, idx.shape[0], chunk):
        ii = idx[a : a + chunk]
        cov, singular, sig, sig_only, lam_joint, rho_joint = _base_scores(
            _sum_blocks(padded, ii), effect_slices, required, lam_star
        )
        lower = rho_joint
        if naming:
            lower = np.stack(
                [
                    np.sqrt(t[inv[a : a + chunk]] ** 2 / np.maximum(lam_joint[:, j], 1e-300)) / LOWER_BOUND_SLACK
                    for j, t in enumerate(t_unit)
                ],
                axis=-1,
            )
        out.append((sig, sig_only, rho_joint, singular, lower))
    return tuple(np.concatenate([o[k] for o in out]) for k in range(5))


def score_candidates(
    blocks: np.ndarray,
    idx: np.ndarray,
    option_cost: np.ndarray,
    effect_slices,
    required,
    lam_star,
    lookalike_slices=(),
    chunk: int = 20000,
    raw_blocks=None,
    option_rows=None,
    rule=None,
    step: bool = False,
) -> Scores:
    """Score candidates given as option indices ``idx`` (C, n_max), −1 = no pass.

    ``blocks`` (O, P, P) per-option information; the campaign's is the sum of its passes'.
    ``raw_blocks`` (O, P, P) and ``option_rows`` (O,) (optional, with ``rule``): the per-option
    information without the shared nuisances and the number of residuals, for the naming scores.
    ``step``: score ``alignment_step`` as a look-alike and rival too (``step_terms``; the columns of ``idx`` in flight order).
    """
    O, P, _ = blocks.shape
    padded = np.concatenate([blocks, np.zeros((1, P, P))])
    cpad = np.concatenate([option_cost, [0.0]])
    if raw_blocks is not None:
        rpad = np.concatenate([raw_blocks, np.zeros((1, P, P))])
        npad = np.concatenate([np.asarray(option_rows, float), [0.0]])
    idx0 = np.asarray(idx)
    idx = np.where(idx < 0, O, idx)
    parts = []
    for a in range(0, idx.shape[0], chunk):
        ii = idx[a : a + chunk]
        info = _sum_blocks(padded, ii)
        kw: dict = {}
        if raw_blocks is not None:
            kw = dict(raw=_sum_blocks(rpad, ii), n_rows=npad[ii].sum(axis=1), rule=rule)
        if step:
            kw["step"] = step_terms(blocks, idx0[a : a + chunk], raw_blocks)
        parts.append(score_information(info, effect_slices, required, lam_star, lookalike_slices, **kw))
    cat = [None if parts[0][k] is None else np.concatenate([p[k] for p in parts]) for k in range(10)]
    return Scores(
        sigma_theta_arcsec=cat[0],
        sigma_theta_only_arcsec=cat[1],
        detect_ratio=cat[2],
        cost=cpad[idx].sum(axis=1),
        singular=cat[3],
        detect_ratio_joint=cat[4],
        lookalike_ratio=cat[5],
        name_ratio=cat[6],
        name_probability=cat[7],
        canonical_rho=cat[8],
        binding_rival=cat[9],
    )
