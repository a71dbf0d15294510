"""Convention doctor: catch the frame / sign slips users make before they turn into a 180° θ.

A misalignment estimator fits a *small* rotation θ. Fed a file with a convention slip — a
mirrored detector axis, quaternions in the wrong order (either way) or conjugated, a transposed mount or ``cgi``,
Earth-fixed GNSS positions declared inertial — it returns 10⁴–10⁶″ (or 180°) with residuals
that look fine, or stops at a misleading "behind the camera". The doctor tests the few slips
that occur in practice, on the images of run 0 (up to ``max_images`` spread evenly over them).

For every hypothesis H (the declared conventions and each slip undone) it forms the nominal
camera-frame lines of sight (Kiev 2012 eq 3 with θ = 0)

    e_nom = C_SK,nominal A(q) (C_GI P − r) / |·|,      e_meas = [x, y, −F] / |·|

and fits ONE rotation R of any size between them (Wahba's problem, SVD solution — the large-angle
version of θ: R = exp(−Φ(θ))), then projects R e_nom back to the focal plane (eq 3) and takes the
RMS residual ρ_H (m). A landmark that R puts behind the camera counts as a residual of F.

DECISION (the decision rule; ``docs/tutorial-flight-data.md`` repeats it):

* a slip is reported when the best alternative fits **100× better** than the declared conventions,
  ρ_declared > 100 ρ_alt, and ρ_declared > 1 nm (so two noise-free, equivalent hypotheses — e.g.
  mirroring x when every landmark has x = 0 — never trigger on round-off);
* or when the declared conventions need a rotation larger than ``max_rotation_deg`` (default 1°,
  thousands of times the misalignments this tool estimates) while an alternative needs less and
  fits no worse than 2× the declared RMS (a mirrored axis on a symmetric landmark pattern is fit by
  θz = 180° with small residuals: this catches it);
* a declared fit needing more than ``max_rotation_deg`` that no slip explains is reported too
  (``LargeRotationError``): θ is estimated by linearisation about 0 and cannot be trusted there.

* with no slip found, the images are compared one by one with their expected noise after a
  robust fit (``K_INCONCLUSIVE``): an image more than 10× its noise makes the result
  "inconclusive" (``ConventionReport.disagreeing``; ``boresight check`` exits 4 naming the images), since
  a slip in one image (x/y swapped, a conjugated quaternion) fits no global hypothesis.

The quaternion order is tested both ways on the written quaternions (``_quat_variants``):
``quaternion_scalar_first`` (scalar-first data taken as scalar-last: the file holds ``np.roll(q, 1)``)
and ``quaternion_read_as_scalar_first`` (scalar-last data read as scalar-first upstream and written out:
``np.roll(q, -1)``, which no hypothesis explained before — "large rotation", 66° on the flight example),
each also for a star tracker → inertial source that the reader conjugated after reordering; once the
declared conventions fail, the order and the direction wrong at once too (``_double_quat_variants``). The slips of
an ingest's own inputs (landmark order or unit, orbit frame, time systems, and the attitude file's
quaternion order, tested by re-reading the file so that the reader's own conversions apply) are
hypotheses of ``observations/flight/culprit.py``, judged by this doctor.

With correct conventions ρ_declared is the noise level and no alternative can fit 100× better
than the noise; ``tests/observations/test_doctor.py`` runs 200 noisy seeds with no alarm and records the
smallest margin ρ_declared / ρ_alt seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from boresight.errors import ConventionError, InconclusiveError, LargeRotationError
from orbits.errors import BoresightError
from orbits.rotations import dcm_from_quat

__all__ = [
    "ConventionError",
    "LargeRotationError",
    "InconclusiveError",
    "ConventionReport",
    "diagnose_conventions",
    "check",
    "convention_error",
    "SLIPS",
]

#: the slips tested, name -> message head
SLIPS = {
    "x_mirrored": "your image x axis looks mirrored",
    "y_mirrored": "your image y axis looks mirrored",
    "quaternion_scalar_first": "your quaternions look scalar-first (q1 is the scalar; the file wants scalar-last q4)",
    "quaternion_read_as_scalar_first": (
        "your quaternions look scalar-last but read as scalar-first upstream (q1 taken for the scalar and moved to q4; "
        "declare the source scalar-last — --quaternion-order scalar_last, QUATERNION_TYPE = LAST, scipy's from_quat "
        "without scalar_first=True — and write the file again)"
    ),
    "quaternion_scalar_first_conjugated": (
        "your quaternions look scalar-first and conjugated: two slips, the order (q1 is the scalar; the file wants "
        "scalar-last q4) and the direction (star tracker → inertial against inertial → star tracker); declare both "
        "right and write the file again"
    ),
    "quaternion_read_as_scalar_first_conjugated": (
        "your quaternions look scalar-last but read as scalar-first upstream, and conjugated: two slips, the order "
        "(q1 taken for the scalar and moved to q4) and the direction (star tracker → inertial against inertial → star "
        "tracker); declare both right and write the file again"
    ),
    "quaternion_conjugated": "your quaternions look conjugated (star tracker → inertial given; the file wants inertial → star tracker)",
    "mount_transposed": "your C_SK_nominal looks transposed (camera → star tracker given; the file wants star tracker → camera)",
    "cgi_transposed": "your cgi columns look transposed (C_IG given; the file wants Earth-fixed → inertial C_GI)",
    "gnss_itrs": "your GNSS positions look Earth-fixed (ITRS) although the file declares them inertial (GCRS)",
}

RATIO = 100.0
FLOOR_M = 1e-9
MAX_ROTATION_DEG = 1.0


@dataclass(frozen=True)
class ConventionReport:
    """What the convention doctor found (``boresight.check``, ``diagnose_conventions``).

    ``table()`` prints it as ``boresight check`` does.

    Attributes
    ----------
    rms_m : dict
        Per hypothesis (``"declared"`` and each slip of ``SLIPS`` tried: ``mount_transposed`` only for a mount
        that is not its own transpose, the two ``…_conjugated`` order slips only when the declared conventions
        fail), the RMS focal-plane residual (m) after fitting a rotation (a quaternion slip: its best variant).
    rotation_deg : dict
        Per hypothesis, the angle of the fitted rotation (deg).
    images : numpy.ndarray
        The indices of the images tested.
    verdict : str or None
        The slip found (a key of ``SLIPS``), ``"large_rotation"``, or None.
    message : str
        The finding in words.
    disagreeing : numpy.ndarray or None
        With no verdict: the images whose declared fit is far above the noise (``inconclusive``).
    """

    rms_m: dict
    rotation_deg: dict
    images: np.ndarray
    verdict: str | None  # slip name, "large_rotation", or None
    message: str
    #: with no verdict: the images whose declared fit is far above the noise (``inconclusive``)
    disagreeing: np.ndarray | None = None

    @property
    def passed(self) -> bool:
        """True when the declared conventions are confirmed: no slip and no image far above the
        noise. The one test ``boresight check`` and ``boresight ingest`` apply, so a file ingest
        writes (exit 0) is one ``check`` passes."""
        return self.verdict is None and self.disagreeing is None

    def table(self) -> str:
        width = max(len(k) for k in self.rms_m)  # the first column: the longest hypothesis name tried
        lines = [f"{'hypothesis':<{width + 1}}rms residual   rotation needed"]
        for k in self.rms_m:
            lines.append(f"{k:<{width}} {_fmt_m(self.rms_m[k]):>12}   {self.rotation_deg[k]:10.4g} deg")
        return "\n".join(lines)


def _fmt_m(v: float) -> str:
    for unit, s in (("m", 1.0), ("mm", 1e-3), ("µm", 1e-6), ("nm", 1e-9)):
        if abs(v) >= s:
            return f"{v / s:.3g} {unit}"
    return f"{v:.2g} m"


_CONJUGATE = np.array([-1.0, -1.0, -1.0, 1.0])

#: what a quaternion slip's second variant adds to its message: the source was star tracker → inertial, so the
#: reader conjugated the quaternions after putting them in the wrong order (``_quat_variants``)
BODY_TO_INERTIAL = " (a star tracker → inertial source, conjugated by the reader after the reordering)"


def _quat_variants(q):
    """The quaternion slips undone: name -> [(variant, q_undone)], ``q`` (..., 4) scalar last.

    With P the reordering ``np.roll(·, 1)`` (scalar-last → scalar-first) and C the conjugation, a reader that takes
    a source of order o as order o′ and direction d as d′ writes C^d′ P^±1 C^d q (P when scalar-first data are read
    as scalar-last, P⁻¹ = ``np.roll(·, -1)`` when scalar-last data are read as scalar-first). Undone here, each
    order slip in its two variants: an inertial → star-tracker source (``""``: P^∓1 undoes it) and a star tracker
    → inertial source declared so, conjugated by the reader after the reordering (``"body_to_inertial"``: C P^∓1 C
    undoes C P^±1 C). The variants are one slip with one fix (declare the order right), and the doctor must try
    all four: undoing P (P⁻¹) on a file C P⁻¹ C q leaves the true attitude turned by a fixed 180°, A(P⁻¹ C P⁻¹ C q) =
    R₁₈₀ A(q) for every q, which the fitted rotation absorbs (and C P C on a file P q likewise). Such a file is fit
    as well by the wrong slip, 180° away: the smallest rotation tells them apart (``diagnose_conventions``), and
    without the variant the doctor named ``quaternion_scalar_first`` for C P⁻¹ C q. The order and the direction both
    wrong (C P^±1, P^±1 C) are ``_double_quat_variants``, tried only when the declared conventions fail
    (``tests/observations/test_doctor_quaternion.py`` holds all of it on the three shipped example kinds).
    """

    def roll(a, k):
        return np.roll(a, k, axis=-1)

    return {
        "quaternion_scalar_first": [("", roll(q, -1)), ("body_to_inertial", roll(q * _CONJUGATE, -1) * _CONJUGATE)],
        "quaternion_read_as_scalar_first": [("", roll(q, 1)), ("body_to_inertial", roll(q * _CONJUGATE, 1) * _CONJUGATE)],
        "quaternion_conjugated": [("", q * _CONJUGATE)],
    }


def _double_quat_variants(q):
    """The two slips at once, the order and the direction, undone: name -> [(variant, q_undone)] (``_quat_variants``'
    notation). A file C^d′ P^±1 C^d q with d ≠ d′: the reader conjugated (C P^±1, ``"reader"``) or the source was
    conjugated (P^±1 C, ``"source"``); C P and P⁻¹ C are 180° apart as C P⁻¹ C and P are.

    DECISION: tried only when the declared conventions fail (``diagnose_conventions``). Without them such a file is
    "large rotation" (C P 118°, P C 109°, C P⁻¹ 109°, P⁻¹ C 116° on the flight example), honest but naming nothing; with them it is
    named, at ~1 ms a fit, and a passing file's table keeps its rows (two slips at once are rare; four more rows on
    every clean table would bury the common ones).
    """

    def roll(a, k):
        return np.roll(a, k, axis=-1)

    return {
        "quaternion_scalar_first_conjugated": [("reader", roll(q * _CONJUGATE, -1)), ("source", roll(q, -1) * _CONJUGATE)],
        "quaternion_read_as_scalar_first_conjugated": [("reader", roll(q * _CONJUGATE, 1)), ("source", roll(q, 1) * _CONJUGATE)],
    }


def _directions(xy, q, r, C_GI, L, C_SK, F, ii, tt, U=None):
    """Nominal (eq 3, θ = 0) and measured unit lines of sight of the rows, each (K, 3): row k is
    target ``tt[k]`` (of ``L``) in image ``ii[k]`` (of ``q``, ``r``, ``C_GI``) — gathers, no
    images × targets array. ``U`` (K, 3): a star row's apparent direction (NaN on landmark rows;
    ``ObservationSet.star_directions_i``), used instead of its position (a star has none)."""
    d = np.einsum("kij,kj->ki", C_GI[ii], L[tt]) - r[ii]
    if U is not None:
        d = np.where(np.isfinite(U[:, :1]), U, d)
    e_nom = np.einsum("ij,kjl,kl->ki", C_SK, dcm_from_quat(q)[ii], d)
    e_nom = e_nom / np.linalg.norm(e_nom, axis=-1, keepdims=True)
    s = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -F)], axis=-1)
    e_meas = s / np.linalg.norm(s, axis=-1, keepdims=True)
    return e_nom, e_meas


def _wahba(a, b, w=None):
    """The rotation R (any size) minimising Σ w |b − R a|² (SVD solution)."""
    H = (a if w is None else a * w[:, None]).T @ b  # Σ a bᵀ; R = V diag(1,1,det) Uᵀ maps a to b
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    return Vt.T @ D @ U.T


def _residuals(a, xy, R, F):
    """Focal-plane residual norms (m) of the directions ``a`` rotated by R against ``xy``; a
    landmark that R puts behind the camera (or a non-finite projection) counts as F."""
    p = a @ R.T
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        xy_p = -F * p[:, :2] / p[:, 2:3]
        res = np.linalg.norm(xy_p - xy, axis=-1)
    res = np.where(p[:, 2] < 0, res, F)
    return np.where(np.isfinite(res), res, F)


def _fit(xy, q, r, C_GI, L, C_SK, F, ii, tt, U=None, return_rotation=False):
    """Best rotation R between nominal and measured directions of the rows; (rms m, angle deg)."""
    a, b = _directions(xy, q, r, C_GI, L, C_SK, F, ii, tt, U)
    R = _wahba(a, b)
    res = _residuals(a, xy, R, F)
    angle = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    if return_rotation:
        return float(np.sqrt(np.mean(res**2))), float(angle), R
    return float(np.sqrt(np.mean(res**2))), float(angle)


#: DECISION: an image "disagrees" with the declared conventions when its RMS residual under the
#: robust fit exceeds K_INCONCLUSIVE times its expected noise (the file's noise model, or — with
#: no noise model or an all-zero one — the residuals' own robust scale). For Gaussian noise an
#: image RMS of 10 σ has probability < e⁻⁶⁹ even for one landmark (a Rayleigh tail), so no clean
#: file trips it; one image with x/y swapped or its quaternion conjugated is 10³–10⁶ σ.
K_INCONCLUSIVE = 10.0


#: the per-image covariances (``gls.structure.image_covariance_rows``: each image's 2m_n × 2m_n block
#: on its own rows) are built for images of equal m_n, at most this many bytes of blocks at a time
COVARIANCE_GROUP_BYTES = 2**20


def _expected_sigma(obs, run: int):
    """Expected RMS focal-plane residual (m) per image from the file's noise model, (N,), or
    None (no noise model, an all-zero one, or a geometry the error Jacobians cannot handle).

    The diagonal of each image's residual covariance on its own rows, 2m_n × 2m_n
    (``core/gls/structure.image_covariance_rows``, images of equal m_n together, in pieces of
    ``COVARIANCE_GROUP_BYTES``), never 2T × 2T of the campaign's (2 572 single-use targets once
    asked for 47 GiB here)."""
    from boresight.core.disturbances import DisturbanceModel
    from boresight.core.gls.structure import image_covariance_rows, images_by_row_count

    try:
        model = DisturbanceModel.from_observations(obs)
        if model is None:
            return None
        one = obs.run(run)
        start = one.row_start
        var = np.zeros(one.n_observations)
        for m, ims in images_by_row_count(one):
            step = max(1, COVARIANCE_GROUP_BYTES // (8 * (2 * m) ** 2)) if m else ims.size
            for i in range(0, ims.size if m else 0, step):
                part = ims[i : i + step]
                with np.errstate(all="ignore"):
                    cov = image_covariance_rows(one.images(part), np.zeros((1, 3)), model)[0]  # (u, 2m, 2m)
                rows = (start[part][:, None] + np.arange(m)).ravel()
                var[rows] = np.einsum("nii->ni", cov).reshape(-1, 2).sum(axis=1)
        sums = np.bincount(one.image_index, weights=var, minlength=obs.n_images)
        sigma = np.sqrt(sums / np.maximum(obs.rows_per_image, 1))
    except (BoresightError, ValueError, FloatingPointError):
        return None
    if not np.all(np.isfinite(sigma)) or not np.any(sigma > FLOOR_M):
        return None
    return sigma


def _disagreeing_images(obs, run, idx, C_SK, F):
    """Images of ``run`` (all of them) whose declared-convention residual is far above the noise:
    (message, image indices) or None. The rotation is fitted robustly (iteratively reweighted
    Wahba on the doctor's images), so one bad image does not drag the others' residuals up."""
    ii, tt, xy_all = obs.image_index, obs.target_index, obs.xy_m[run]
    U = None if getattr(obs, "stars", None) is None else obs.star_directions_i(ii, tt)
    e_nom, e_meas = _directions(xy_all, obs.q_is[run], obs.r_sc_i_m[run], obs.C_GI, obs.landmark_g_m[run], C_SK, F, ii, tt, U)
    sub = np.zeros(obs.n_images, bool)
    sub[idx] = True
    fit_sel = sub[ii]
    a, b, xy_fit = e_nom[fit_sel], e_meas[fit_sel], xy_all[fit_sel]
    w = np.ones(len(a))
    for _ in range(8):  # Cauchy weights about the median residual: converges to the majority's fit
        R = _wahba(a, b, w)
        res = _residuals(a, xy_fit, R, F)
        c = max(3 * float(np.median(res)), FLOOR_M)
        w = 1.0 / (1.0 + (res / c) ** 2)
    res = _residuals(e_nom, xy_all, R, F)  # (K,) per row
    angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))
    k = int(np.argmax(res))
    worst = f"image {int(ii[k])} landmark {str(obs.landmark_ids[tt[k]])!r} {_fmt_m(res[k])}"
    count = np.maximum(obs.rows_per_image, 1)
    rms = np.sqrt(np.bincount(ii, weights=res**2, minlength=obs.n_images) / count)
    sigma = _expected_sigma(obs, run)
    if sigma is not None:
        ref, what = np.maximum(sigma, FLOOR_M), "the file's noise model"
    else:
        # a 2-D Gaussian residual's norm has median 1.1774 σ
        ref = np.full(rms.shape, max(float(np.median(res)) / 1.1774, FLOOR_M))
        what = "the residuals' own robust scale (no noise model)"
    bad = rms > K_INCONCLUSIVE * ref
    if not np.any(bad):
        return None, angle, worst
    images = np.nonzero(bad)[0]
    top = images[np.argsort(-(rms / ref)[images])][:5]  # not ``worst``: that names the largest row, returned below
    shown = ", ".join(f"image {int(n)} {_fmt_m(rms[n])} ({rms[n] / ref[n]:.3g}×)" for n in top)
    more = f" and {len(images) - len(top)} more" if len(images) > len(top) else ""
    msg = (
        f"inconclusive: {len(images)} of {obs.n_images} image(s) of run {run} disagree with the declared conventions, "
        f"their RMS residual more than {K_INCONCLUSIVE:g}× {what} ({ref[top[0]]:.3g} m): {shown}{more}; "
        "a convention slip in those images only, a damaged row, or an unmodelled effect (boresight diagnose)"
    )
    return (msg, images), angle, worst


def _smallest_rotation(fits):
    """Of ``{name: (rms m, angle deg)}``, the one needing the smallest rotation among those fitting within 2× the best
    RMS (with a floor of ``FLOOR_M``)."""
    best_rms = min(r for r, _ in fits.values())
    return min((k for k, (r, _) in fits.items() if r <= 2 * max(best_rms, FLOOR_M)), key=lambda k: fits[k][1])


def _head(slip, chosen):
    """The message head of ``slip`` (``SLIPS``), with its variant's note when the variant is not the plain one."""
    return SLIPS[slip] + (BODY_TO_INERTIAL if chosen.get(slip) == "body_to_inertial" else "")


def _fit_hypotheses(base, ratio, max_rotation_deg):
    """Each hypothesis fitted on the doctor's rows (``base``: ``_fit``'s inputs as declared): (rms m, angle deg,
    variant) per name — a row is its variant needing the smallest rotation among the best-fitting ones. The double
    quaternion slips (``_double_quat_variants``) are tried only when the declared conventions fail."""
    xy, q, r, C_GI, C_SK = base["xy"], base["q"], base["r"], base["C_GI"], base["C_SK"]
    # each hypothesis: its variants (name -> the fit's inputs); one, "", but for the quaternion slips (_quat_variants)
    hyps: dict[str, dict[str, dict]] = {"declared": {"": base}}
    hyps["x_mirrored"] = {"": dict(base, xy=xy * [-1.0, 1.0])}
    hyps["y_mirrored"] = {"": dict(base, xy=xy * [1.0, -1.0])}
    for k, vs in _quat_variants(q).items():
        hyps[k] = {v: dict(base, q=qv) for v, qv in vs}
    # DECISION: a symmetric mount (e.g. the identity) is its own transpose — the slip is not testable.
    if not np.allclose(C_SK, C_SK.T, atol=1e-12):
        hyps["mount_transposed"] = {"": dict(base, C_SK=C_SK.T)}
    hyps["cgi_transposed"] = {"": dict(base, C_GI=np.swapaxes(C_GI, -1, -2))}
    hyps["gnss_itrs"] = {"": dict(base, r=np.einsum("nij,nj->ni", C_GI, r))}
    rms, ang, chosen = {}, {}, {}

    def fit(k, variants):
        fits = {v: _fit(**h) for v, h in variants.items()}
        chosen[k] = _smallest_rotation(fits)
        rms[k], ang[k] = fits[chosen[k]]

    for k, variants in hyps.items():
        fit(k, variants)
    best_rms = min(rms[k] for k in hyps if k != "declared")
    if (rms["declared"] > FLOOR_M and rms["declared"] > ratio * best_rms) or ang["declared"] > max_rotation_deg:
        for k, vs in _double_quat_variants(q).items():  # the declared conventions fail: two slips at once too
            fit(k, {v: dict(base, q=qv) for v, qv in vs})
    return rms, ang, chosen


def diagnose_conventions(
    obs, *, max_images: int = 12, ratio: float = RATIO, max_rotation_deg: float = MAX_ROTATION_DEG, run: int = 0
) -> ConventionReport:
    """Fit the declared conventions and each slip of ``SLIPS``; return the ``ConventionReport`` (no raise)."""
    from boresight.errors import OBSERVATION_SET, InputTypeError
    from boresight.observations.model import ObservationSet

    if not isinstance(obs, ObservationSet):
        raise InputTypeError.expected("check", "obs", OBSERVATION_SET, obs)
    n = obs.n_images
    idx = np.unique(np.linspace(0, n - 1, min(n, max_images)).round().astype(int))
    rows = np.concatenate([np.arange(obs.row_start[i], obs.row_start[i + 1]) for i in idx]).astype(np.int64)
    local = np.full(n, -1, np.int64)
    local[idx] = np.arange(idx.size)
    xy = obs.xy_m[run, rows]
    q = obs.q_is[run, idx]
    r = obs.r_sc_i_m[run, idx]
    C_GI = obs.C_GI[idx]
    L = obs.landmark_g_m[run]
    C_SK = np.asarray(obs.C_SK_nominal, float)
    F = float(obs.focal_length_m)
    U = None if getattr(obs, "stars", None) is None else obs.star_directions_i(obs.image_index[rows], obs.target_index[rows])
    base = dict(xy=xy, q=q, r=r, C_GI=C_GI, L=L, C_SK=C_SK, F=F, ii=local[obs.image_index[rows]], tt=obs.target_index[rows], U=U)
    rms, ang, chosen = _fit_hypotheses(base, ratio, max_rotation_deg)
    alts = [k for k in rms if k != "declared"]
    # DECISION: slips can be equivalent up to a rotation (y mirrored = x mirrored + 180° about z; a quaternion
    # slip's variant and the other order slip, _quat_variants); among the alternatives that fit within 2× the best
    # one, name the one needing the smallest rotation — θ is small, its 180° twin is not.
    best = _smallest_rotation({k: (rms[k], ang[k]) for k in alts})
    d = rms["declared"]
    where = f"{len(idx)} image(s) of run {run}"
    if d > FLOOR_M and d > ratio * rms[best]:
        msg = (
            f"{_head(best, chosen)}: residuals {_fmt_m(d)} as declared, {_fmt_m(rms[best])} with it undone "
            f"({where}; rotation needed {ang['declared']:.3g}° as declared, {ang[best]:.3g}° with it undone)"
        )
        return ConventionReport(rms, ang, idx, best, msg)
    far, robust_deg, worst = _disagreeing_images(obs, run, idx, C_SK, F)
    if far is not None and robust_deg <= max_rotation_deg:
        # most images fit a small rotation; a few pull the least-squares fit away: name them
        return ConventionReport(rms, ang, idx, None, far[0], disagreeing=far[1])
    if ang["declared"] > max_rotation_deg:
        small = [k for k in alts if ang[k] <= max_rotation_deg and rms[k] <= 2 * max(d, FLOOR_M)]
        if small:
            k = min(small, key=lambda k: ang[k])
            msg = (
                f"{_head(k, chosen)}: the declared conventions need a {ang['declared']:.4g}° rotation between camera and star tracker "
                f"(residuals {_fmt_m(d)}); undoing the slip needs {ang[k]:.3g}° (residuals {_fmt_m(rms[k])}; {where})"
            )
            return ConventionReport(rms, ang, idx, k, msg)
        msg = (
            f"the declared conventions need a {ang['declared']:.4g}° rotation between camera and star tracker (residuals {_fmt_m(d)}; {where}); "
            f"θ is estimated as a small rotation (< {max_rotation_deg:g}°) and no tested slip explains it — check C_SK_nominal, "
            f"the detector axes and the quaternion convention; largest residual after a robust fit: {worst}"
        )
        return ConventionReport(rms, ang, idx, "large_rotation", msg)
    if far is not None:
        return ConventionReport(rms, ang, idx, None, far[0], disagreeing=far[1])
    # DECISION: the conventions are declared once per file, so the slip hypotheses are fitted on
    # one run; a damaged row can be in any run, so the per-image test covers every run (~20 ms a
    # run), and the first run with images far above the noise is named.
    for r in range(obs.runs):
        if r == run:
            continue
        far_r, deg_r, _ = _disagreeing_images(obs, r, idx, C_SK, F)
        if far_r is not None and deg_r <= max_rotation_deg:
            return ConventionReport(rms, ang, idx, None, far_r[0], disagreeing=far_r[1])
    runs = f"; the images of all {obs.runs} runs checked" if obs.runs > 1 else ""
    return ConventionReport(
        rms, ang, idx, None, f"conventions look right: residuals {_fmt_m(d)}, rotation {ang['declared']:.3g}° ({where}{runs})"
    )


#: what follows the doctor's finding in the error (``convention_error(hint=…)``)
HINT = "boresight check FILE shows the table; --no-check skips this test"


def convention_error(dg: ConventionReport, source: str = "", hint: str | None = HINT) -> "ConventionError":
    """The error for a ``ConventionReport`` with a verdict: ``"{source}: {message} ({hint})"`` — the one
    wording every command uses (``LargeRotationError`` when no slip explains a large rotation)."""
    prefix = f"{source}: " if source else ""
    cls = LargeRotationError if dg.verdict == "large_rotation" else ConventionError
    if dg.verdict is None and dg.disagreeing is not None:
        cls = InconclusiveError
    return cls(prefix + dg.message + (f" ({hint})" if hint else ""), slip=dg.verdict, report=dg)


def check(obs, source: str = "", hint: str | None = HINT, **kw) -> ConventionReport:
    """The convention doctor: ``diagnose_conventions`` that raises on a finding.

    Parameters
    ----------
    obs : ObservationSet
        The observations to test (run 0 unless ``run=`` is given).
    source : str
        The file name put in front of the message (``"{source}: …"``); empty for none.
    hint : str or None
        What follows the finding in the message (default: how to see the table, how to skip).
    **kw
        ``max_images``, ``ratio``, ``max_rotation_deg``, ``run``: as ``diagnose_conventions``.

    Returns
    -------
    ConventionReport
        The RMS residual and rotation angle of every hypothesis (``report.table()``), when the
        declared conventions fit.

    Raises
    ------
    ConventionError
        A common slip (``SLIPS``) fits ``ratio`` (100) times better than the declared conventions;
        ``exc.slip`` names it. ``LargeRotationError`` (a subclass) when no slip explains a rotation
        beyond ``max_rotation_deg``; ``InconclusiveError`` when some images disagree with the noise.
    InputTypeError
        ``obs`` is not an ``ObservationSet``.
    """
    dg = diagnose_conventions(obs, **kw)
    if dg.verdict is None:
        return dg
    raise convention_error(dg, source, hint)


def read_checked(path, check: bool = True, **kw):
    """Read an observation file and run the convention doctor on it (``check=False`` skips it).

    A file the reader refuses for its geometry (a landmark behind the camera or outside the field
    — what most slips produce) is re-read without those two tests so the doctor can say which
    convention is wrong; if no slip explains it the reader's own error is raised.
    """
    from boresight.errors import ObservationFileError
    from boresight.observations.ecsv import read_ecsv

    try:
        obs = read_ecsv(path)
    except ObservationFileError as exc:
        text = str(exc)
        if not check or ("behind the camera" not in text and "outside the field of view" not in text):
            raise
        lenient = read_ecsv(path, geometry_checks=False)
        dg = diagnose_conventions(lenient, **kw)
        if dg.verdict not in (None, "large_rotation"):
            raise convention_error(dg, str(path), hint=f"the reader refused the file: {text}; {HINT}") from exc
        raise
    if check:  # the parameter hides the function ``check``: its two lines, spelled out
        dg = diagnose_conventions(obs, **kw)
        if dg.verdict is not None:
            raise convention_error(dg, str(path))
    return obs
