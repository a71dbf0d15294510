"""Convention doctor: catch the frame / sign slips users make before they turn into a 180° θ.

A misalignment estimator fits a *small* rotation θ. Fed a file with a convention slip — a
mirrored detector axis, scalar-first or conjugated quaternions, a transposed mount or ``cgi``,
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

With correct conventions ρ_declared is the noise level and no alternative can fit 100× better
than the noise; ``tests/test_doctor.py`` runs 200 noisy seeds with no alarm and records the
smallest margin ρ_declared / ρ_alt seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbits.errors import BoresightError
from orbits.rotations import dcm_from_quat

from boresight.errors import EXIT_CONVENTION

__all__ = ["ConventionError", "LargeRotationError", "Diagnosis", "diagnose_conventions", "check_conventions", "convention_error", "SLIPS"]

#: the slips tested, name -> message head
SLIPS = {
    "x_mirrored": "your image x axis looks mirrored",
    "y_mirrored": "your image y axis looks mirrored",
    "quaternion_scalar_first": "your quaternions look scalar-first (q1 is the scalar; the file wants scalar-last q4)",
    "quaternion_conjugated": "your quaternions look conjugated (star tracker → inertial given; the file wants inertial → star tracker)",
    "mount_transposed": "your C_SK_nominal looks transposed (camera → star tracker given; the file wants star tracker → camera)",
    "cgi_transposed": "your cgi columns look transposed (C_IG given; the file wants Earth-fixed → inertial C_GI)",
    "gnss_itrs": "your GNSS positions look Earth-fixed (ITRS) although the file declares them inertial (GCRS)",
}

RATIO = 100.0
FLOOR_M = 1e-9
MAX_ROTATION_DEG = 1.0


class ConventionError(BoresightError, ValueError):
    """The file's declared conventions fit the images far worse than a common slip does.

    ``slip`` is the name (a key of ``SLIPS``), ``diagnosis`` the full ``Diagnosis``. Every command
    that runs the doctor (``check``, ``estimate``, ``diagnose``, ``ingest``) lets it reach the CLI,
    which prints ``boresight COMMAND: ConventionError: …`` and exits with ``exit_code``.
    """

    #: the ``boresight`` command's exit status for a convention slip (``boresight.errors``)
    exit_code = EXIT_CONVENTION

    def __init__(self, message: str, *, slip: str | None = None, diagnosis=None):
        super().__init__(message)
        self.slip = slip
        self.diagnosis = diagnosis


class LargeRotationError(ConventionError):
    """The declared conventions need a rotation far beyond a small misalignment and no slip explains it."""


@dataclass(frozen=True)
class Diagnosis:
    """RMS focal-plane residual (m) and fitted rotation angle (deg) per hypothesis."""

    rms_m: dict
    rotation_deg: dict
    images: np.ndarray
    verdict: str | None  # slip name, "large_rotation", or None
    message: str

    def table(self) -> str:
        lines = ["hypothesis                  rms residual   rotation needed"]
        for k in self.rms_m:
            lines.append(f"{k:<27} {_fmt_m(self.rms_m[k]):>12}   {self.rotation_deg[k]:10.4g} deg")
        return "\n".join(lines)


def _fmt_m(v: float) -> str:
    for unit, s in (("m", 1.0), ("mm", 1e-3), ("µm", 1e-6), ("nm", 1e-9)):
        if abs(v) >= s:
            return f"{v / s:.3g} {unit}"
    return f"{v:.2g} m"


def _quat_variants(q):
    return {
        "quaternion_scalar_first": np.roll(q, -1, axis=-1),
        "quaternion_conjugated": q * np.array([-1.0, -1.0, -1.0, 1.0]),
    }


def _fit(xy, mask, q, r, C_GI, L, C_SK, F):
    """Best rotation R between nominal and measured directions; (rms m, angle deg)."""
    d = np.einsum("nij,mj->nmi", C_GI, L) - r[:, None, :]
    e_nom = np.einsum("ij,njk,nmk->nmi", C_SK, dcm_from_quat(q), d)
    e_nom = e_nom / np.linalg.norm(e_nom, axis=-1, keepdims=True)
    s = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -F)], axis=-1)
    e_meas = s / np.linalg.norm(s, axis=-1, keepdims=True)
    a, b = e_nom[mask], e_meas[mask]
    H = a.T @ b  # Σ a bᵀ; R = V diag(1,1,det) Uᵀ maps a to b
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    p = a @ R.T
    with np.errstate(divide="ignore", invalid="ignore"):
        xy_p = -F * p[:, :2] / p[:, 2:3]
    res = np.linalg.norm(xy_p - xy[mask], axis=-1)
    res = np.where(p[:, 2] < 0, res, F)
    res = np.where(np.isfinite(res), res, F)
    angle = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    return float(np.sqrt(np.mean(res**2))), float(angle)


def diagnose_conventions(obs, *, max_images: int = 12, ratio: float = RATIO, max_rotation_deg: float = MAX_ROTATION_DEG, run: int = 0) -> Diagnosis:
    """Fit the declared conventions and each slip of ``SLIPS``; return the ``Diagnosis`` (no raise)."""
    n = obs.n_images
    idx = np.unique(np.linspace(0, n - 1, min(n, max_images)).round().astype(int))
    xy = obs.xy_m[run, idx]
    mask = obs.mask[idx]
    q = obs.q_is[run, idx]
    r = obs.r_sc_i_m[run, idx]
    C_GI = obs.C_GI[idx]
    L = obs.landmark_g_m[run]
    C_SK = np.asarray(obs.C_SK_nominal, float)
    F = float(obs.focal_length_m)
    base = dict(xy=xy, mask=mask, q=q, r=r, C_GI=C_GI, L=L, C_SK=C_SK, F=F)
    hyps = {"declared": base}
    hyps["x_mirrored"] = dict(base, xy=xy * [-1.0, 1.0])
    hyps["y_mirrored"] = dict(base, xy=xy * [1.0, -1.0])
    for k, v in _quat_variants(q).items():
        hyps[k] = dict(base, q=v)
    # DECISION: a symmetric mount (e.g. the identity) is its own transpose — the slip is not testable.
    if not np.allclose(C_SK, C_SK.T, atol=1e-12):
        hyps["mount_transposed"] = dict(base, C_SK=C_SK.T)
    hyps["cgi_transposed"] = dict(base, C_GI=np.swapaxes(C_GI, -1, -2))
    hyps["gnss_itrs"] = dict(base, r=np.einsum("nij,nj->ni", C_GI, r))
    rms, ang = {}, {}
    for k, h in hyps.items():
        rms[k], ang[k] = _fit(**h)
    alts = [k for k in hyps if k != "declared"]
    # DECISION: slips can be equivalent up to a rotation (y mirrored = x mirrored + 180° about z);
    # among the alternatives that fit within 2× the best one, name the one needing the smallest rotation.
    best_rms = min(rms[k] for k in alts)
    best = min((k for k in alts if rms[k] <= 2 * max(best_rms, FLOOR_M)), key=lambda k: ang[k])
    d = rms["declared"]
    where = f"{len(idx)} image(s) of run {run}"
    if d > FLOOR_M and d > ratio * rms[best]:
        msg = f"{SLIPS[best]}: residuals {_fmt_m(rms[best])} instead of {_fmt_m(d)} ({where}; rotation needed {ang[best]:.3g}° instead of {ang['declared']:.3g}°)"
        return Diagnosis(rms, ang, idx, best, msg)
    if ang["declared"] > max_rotation_deg:
        small = [k for k in alts if ang[k] <= max_rotation_deg and rms[k] <= 2 * max(d, FLOOR_M)]
        if small:
            k = min(small, key=lambda k: ang[k])
            msg = (
                f"{SLIPS[k]}: the declared conventions need a {ang['declared']:.4g}° rotation between camera and star tracker "
                f"(residuals {_fmt_m(d)}); undoing the slip needs {ang[k]:.3g}° (residuals {_fmt_m(rms[k])}; {where})"
            )
            return Diagnosis(rms, ang, idx, k, msg)
        msg = (
            f"the declared conventions need a {ang['declared']:.4g}° rotation between camera and star tracker (residuals {_fmt_m(d)}; {where}); "
            f"θ is estimated as a small rotation (< {max_rotation_deg:g}°) and no tested slip explains it — check C_SK_nominal, "
            "the detector axes and the quaternion convention"
        )
        return Diagnosis(rms, ang, idx, "large_rotation", msg)
    return Diagnosis(rms, ang, idx, None, f"conventions look right: residuals {_fmt_m(d)}, rotation {ang['declared']:.3g}° ({where})")


#: what follows the doctor's finding in the error (``convention_error(hint=…)``)
HINT = "boresight check FILE shows the table; --no-check skips this test"


def convention_error(dg: Diagnosis, source: str = "", hint: str | None = HINT) -> "ConventionError":
    """The error for a ``Diagnosis`` with a verdict: ``"{source}: {message} ({hint})"`` — the one
    wording every command uses (``LargeRotationError`` when no slip explains a large rotation)."""
    prefix = f"{source}: " if source else ""
    cls = LargeRotationError if dg.verdict == "large_rotation" else ConventionError
    return cls(prefix + dg.message + (f" ({hint})" if hint else ""), slip=dg.verdict, diagnosis=dg)


def check_conventions(obs, source: str = "", hint: str | None = HINT, **kw) -> Diagnosis:
    """``diagnose_conventions`` that raises ``ConventionError`` (or ``LargeRotationError``) on a finding."""
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
    from boresight.observations.ecsv import read_ecsv
    from boresight.observations.model import ObservationFileError

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
    if check:
        check_conventions(obs, source=str(path), **kw)
    return obs
