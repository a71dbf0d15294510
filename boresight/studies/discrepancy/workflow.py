"""``boresight.diagnose``: find what the model misses, name it, add it, show the gap shrink.

The procedure (the statistics are derived in :mod:`.linear`; choices in ``docs/discrepancy.md``):

1. **Base fit** — GLS of θ under the noise model (Gauss–Newton to 1e-6″).
2. **Residual tests** (:mod:`.structure`) — χ²/dof, normalised residuals, whiteness, and
   structure probes against image radius, position angle, time in pass, argument of
   latitude, pass and attitude law; Holm at family-wise α.
3. **Identifiability, before naming** — for every candidate on *this* data: marginal σ, largest
   correlation with θ and with each other candidate, the smallest size the naming test would
   detect (level α/K — the Bonferroni level of step 4 — and power 80 %, non-central χ²), and a
   status: ``separable``, ``partially separable`` (tested on its separable directions),
   ``not_separable`` (every direction has canonical correlation > 0.995 with the base model,
   or it is undetectable anywhere in its physical range) with the θ shift it would cause at its
   typical size, or ``needs velocity``.
4. **Naming** — each separable candidate is added in turn; they are ranked by the p-value of
   the likelihood-ratio statistic Δχ² (χ² with the candidate's separable rank; BIC reported
   too). The best is named only if p ≤ α/K (Holm's first step over the K candidates still in
   play, family-wise α = 1 %) and its BIC improves; a fitted value outside the physical range
   (by more than 3σ) rejects the candidate instead. If another significant candidate explains
   the data about as well — ΔlogL < 2 between their single fits, or the winner adds nothing
   significant (p > α) once the other is in the model — the pair is ``ambiguous`` and neither
   is named. After a name, θ and the named effects are refitted jointly and the search repeats.
5. **Verdict** — if the residuals of the final model still fail a test, the structure is
   ``unexplained_structure`` and the field residuals are shown with Tang 2014's collocation.
6. **Variance components** — if the χ² test still fails, the scale of every error source of the
   noise model is estimated from the residuals (REML, ``boresight.core.variance_components``) and the
   diagnosis is redone once under it, re-deciding only the names already made
   (``_diagnose_problem``; ``variance_components`` in diagnosis.json).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from boresight.observations.merge import merge_observations  # re-exported: its home is the data model
from boresight.studies.discrepancy.naming import GENERIC_TESTS, identifiability, leftover, naming_rounds, withdraw
from boresight.studies.discrepancy.result import DIAGNOSIS_FORMAT, DIAGNOSIS_VERSION, Diagnosis
from boresight.studies.discrepancy.state import State, final_state, final_values
from boresight.studies.discrepancy.structure import collocation_view, residual_tests
from orbits.errors import BoresightError
from orbits.rotations import ARCSEC

__all__ = ["Diagnosis", "diagnose", "diagnose_problem", "merge_observations", "DIAGNOSIS_FORMAT", "DIAGNOSIS_VERSION"]


def diagnose_problem(
    problem, *, alpha: float = 0.01, power: float = 0.8, max_steps: int = 4, candidates=None, progress=None
) -> Diagnosis:
    """Run the five steps of the module docstring on a problem (``CampaignProblem`` or another
    adapter with the same methods). ``progress``: optional callable given a short description
    of each stage as it starts (the CLI's heartbeat). BLAS runs single-threaded, as in the
    campaign GLS (its matrices are small; a threaded BLAS on shared cores only adds overhead)."""
    with _one_blas_thread():
        return _diagnose_problem(problem, alpha, power, max_steps, candidates, progress or (lambda msg: None))


def _one_blas_thread():
    from boresight.core.gls.campaign import single_threaded_blas

    return single_threaded_blas()


def _diagnose_problem(problem, alpha, power, max_steps, candidates, progress) -> Diagnosis:
    """Step 6: the noise model's scales re-estimated when the data reject it.

    DECISION: when, after naming, the χ² test still fails, the noise model understates the scatter —
    a σ that is wrong (every source 1.5× the declared), or an error no catalogue effect describes (an
    attitude jitter of tens of seconds). The scale of every error source of the model (pixel, star
    tracker per image and per pass, GNSS, catalogue) is then estimated from the residuals of the
    final model by REML (``boresight.core.variance_components``), with a per-pass rotation added when
    the ``pass`` probe fails and the model has none, and the whole diagnosis (names, withdrawals, θ
    and its σ) is redone once under the estimated model (``variance_components`` in diagnosis.json).
    The rediagnosis re-decides only the names of the first (at the same level α/K): a name that
    appears only under the re-scaled model is a projection of the within-pass shape of a correlated
    error carried as white noise (a time tag at p ≈ 1e-3 with θ 3–4σ off in 5 of 40 seeds of an attitude jitter).
    This replaced an earlier step, moment estimates of an extra rotation per image and per pass — a rotation
    is the wrong shape for a pixel σ that is too small (σθ was never inflated: ratio 1.000 over 10
    seeds of 1.5× noise), and for heavy tails (a 29.5″ rotation per image for Student-t pixel
    noise, σθ 5× θ's scatter).
    DECISION: heavy tails are a question of the loss, not of a rotation: least squares is kept, and
    its σθ comes from the estimated variances (honest for any error distribution of finite
    variance: it is the scatter of the least-squares θ); the terminal and the JSON say so and that
    a robust loss (``boresight estimate --loss huber``) would be the more efficient estimator.
    No silent fallback: when the estimate fails (a singular fit, no convergence) the terminal and
    the JSON say so, and θ's σ is the first diagnosis' inflated by √(χ²/dof) (the Birge ratio: all
    sources scaled alike), so it reflects the failure.
    """
    d = _diagnose_once(problem, alpha, power, max_steps, candidates, progress)
    final = d.details["final_tests"]
    if not (
        d.unexplained_structure
        and hasattr(problem, "variance_components")
        and any(t.rejected and t.name == "chi2" for t in final)
    ):
        return d
    from dataclasses import replace

    st = d.details["final_state"]
    chi2 = next(t for t in final if t.name == "chi2")
    before = {
        "chi2_dof_before": float(chi2.statistic / chi2.dof),
        "named_before": list(d.named),
        "theta_before_arcsec": list(d.theta_arcsec),
        "theta_sigma_before_arcsec": list(d.theta_sigma_arcsec),
    }
    progress("estimating the noise model's variance components (REML)")
    st_sigma = float(np.max(problem.model.sigma_star_tracker_rad))
    try:
        # a per-pass rotation is sized only when the pass probe asks for one (else it adds noise to σθ)
        pass_fails = any(t.rejected and t.name == "pass" for t in final)
        extra = (st_sigma or ARCSEC) if pass_fails else 0.0
        vc = problem.variance_components(st.theta, st.named, extra_pass_rotation_rad=extra)
        failure = None if vc.converged else f"the REML iteration did not converge in {vc.iterations} iterations"
        if failure is None and any(c.unit == "arcsec" and not c.estimate < 3600.0 for c in vc.components):
            failure = "a star-tracker scale exceeds 1° (outside the small-angle model)"
    except (BoresightError, np.linalg.LinAlgError) as err:
        vc, failure = None, f"the estimate failed ({err})"
    if failure is not None:
        birge = float(np.sqrt(max(1.0, chi2.statistic / chi2.dof)))
        entry = {
            "failed": failure,
            "sigma_inflation": birge,
            "note": f"θ's σ inflated by √(χ²/dof) = {birge:.3g} (every source scaled alike) since the sources could not be sized",
            **before,
        }
        if vc is not None:
            entry.update(vc.as_json())
        return replace(d, variance_components=entry, theta_sigma_arcsec=[float(v) * birge for v in d.theta_sigma_arcsec])
    progress("rediagnosis under the estimated noise model")
    rescaled = problem.with_model(vc.model, vc.scaled_rows(problem.obs))  # rows with their own σ scale with σK
    d2 = _diagnose_once(rescaled, alpha, power, max_steps, candidates, progress, nameable=set(d.named))
    entry = {**vc.as_json(), "failed": None, **before}
    entry["loss"] = "least squares"
    entry["loss_reason"] = (
        "the residuals are heavy-tailed (excess kurtosis "
        + ", ".join(f"{k} {v:.2g}" for k, v in vc.kurtosis.items())
        + "): a question of the loss, not of an extra rotation; least squares is kept and θ's σ comes from the estimated "
        "variances (honest for any error distribution of finite variance); a robust loss (boresight estimate --loss huber) "
        "would give a more efficient θ"
        if vc.heavy_tailed
        else "the residuals are consistent with Gaussian tails: least squares under the estimated variances"
    )
    d2.details["before_variance_components"] = d
    d2.details["variance_components"] = vc
    return replace(d2, variance_components=entry)


def _diagnose_once(problem, alpha, power, max_steps, candidates, progress, nameable=None) -> Diagnosis:
    names = list(problem.candidates) if candidates is None else list(candidates)
    progress("base fit")
    st = State(problem, np.asarray(getattr(problem, "base_start", np.zeros(3)), float), {}, names)
    base_state = st
    tests0 = residual_tests(st.base, st.cl.probes, alpha)
    progress(f"identifiability of {len(names)} candidate(s)")
    ident, not_sep, _ = identifiability(st, names, alpha, power)
    status = {e["effect"]: e["status"] for e in ident}
    pool = [n for n in names if status[n] in ("separable", "partially separable")]
    K = max(1, len(pool))
    if nameable is not None:  # the rediagnosis under the estimated scatter re-decides only these (K unchanged)
        pool = [n for n in pool if n in nameable]
    withdrawn: list[Any] = []
    withdrawal_tests: list[Any] = []
    before_withdrawal = None  # the final state of the first naming, if a withdrawal followed it
    # DECISION: a ``withdrawn`` or ``untestable`` name is dropped and the naming redone without
    # it. An untestable name is not floated: floating it pulled θ 3–9σ off in 35 of 40 seeds of
    # an attitude jitter the noise model does not carry (the name was the noise's projection), and
    # the cases where dropping it hurt (a drift named with a spurious time tag) are decided before that by the
    # parsimony leg of ``withdraw``; a θ that moves > 3σ from the fit before the withdrawals
    # while residual tests still fail is printed (CAUTION). Every round removes at least one name
    # from the pool, so the loop ends, and it ends only on a round whose names were all kept or
    # on a model with nothing left failing.
    while True:
        progress("naming")
        out_of_pool = {w["effect"] for w in withdrawn}
        rec = naming_rounds(problem, base_state, [n for n in pool if n not in out_of_pool], alpha, max_steps)
        states = rec["states"]
        state_tests = [tests0 if s is base_state else residual_tests(s.base, s.cl.probes, alpha) for s in states]
        # the model θ is quoted from (an ambiguous or not-decisive group floated): its residuals
        # decide whether structure is unexplained, and the withdrawal tests run against it
        st, tests1 = final_state(problem, rec, states[-1], state_tests[-1], alpha)
        unexplained = any(t.rejected for t in tests1)
        left = _left_beyond_floated(rec, st, tests0, alpha)
        unexplained = unexplained or bool(left)
        if not unexplained or not rec["named"]:
            break
        progress(f"withdrawal tests of {', '.join(rec['named'])} against the unexplained structure")
        w = withdraw(problem, rec["named"], st, tests1, alpha, K)
        withdrawal_tests += w
        w = [x for x in w if x["verdict"] != "kept"]
        if not w:
            break
        withdrawn += w
        before_withdrawal = before_withdrawal or st
    shift = None
    if before_withdrawal is not None and unexplained:
        # the model after the withdrawals against the one before: a θ that moved by many σ while
        # the residuals still fail depends on what the unexplained structure is — said, not hidden
        z = (st.theta_arcsec() - before_withdrawal.theta_arcsec()) / st.theta_sigma_arcsec()
        shift = {
            "theta_before_arcsec": [float(v) for v in before_withdrawal.theta_arcsec()],
            "named_before": list(before_withdrawal.named),
            "shift_sigma": [float(v) for v in z],
        }
    for n in rec["not_decisive"]:
        # "more data would name it" only when the data say so: it took the structure the base fit showed
        n["explains_structure"] = not left
        if left:
            n["structure_left"] = left
    colloc = None
    if unexplained and hasattr(problem, "split_residuals"):
        _, field_xy = problem.split_residuals(st.cl.residual_xy_m, st.cl.G)
        reg = problem.regressors
        colloc = collocation_view(reg["x_m"], reg["y_m"], field_xy)
    details = {
        "base_tests": tests0,
        "final_tests": tests1,
        "state_tests": state_tests,
        "rounds": rec["rounds"],
        "rejected": rec["rejected"],
        "withdrawn": withdrawn,
        "withdrawal_tests": withdrawal_tests,
        "states": states,
        "base_state": base_state,
        "collocation": colloc,
        "alpha": alpha,
        "power": power,
        "problem": problem,
        "converged": all(s.converged for s in states),
        "ambiguous_detail": rec["ambiguous"],
        "final_state": st,
        "theta_shift_after_withdrawal": shift,
        "structure_left_by_floated": left,
    }
    return Diagnosis(
        format=DIAGNOSIS_FORMAT,
        version=DIAGNOSIS_VERSION,
        named=rec["named"],
        steps=rec["steps"],
        named_final=final_values(problem, st, rec["named"]),
        withdrawn=[dict(w) for w in withdrawn],
        ambiguous=[{"effects": a["effects"], "would_split": a["would_split"]} for a in rec["ambiguous"]],
        not_decisive=rec["not_decisive"],
        not_separable=not_sep,
        unexplained_structure=bool(unexplained),
        tails=_tails(st, tests1) if unexplained else None,
        identifiability=ident,
        theta_arcsec=[float(v) for v in st.theta_arcsec()],
        theta_sigma_arcsec=[float(v) for v in st.theta_sigma_arcsec()],
        details=details,
    )


def _load(observations):
    from boresight.errors import OBSERVATION_SET, InputTypeError, ObservationError
    from boresight.observations.model import ObservationSet

    items = observations if isinstance(observations, (list, tuple)) else [observations]
    if not items:
        raise ObservationError(
            "diagnose: no observations given (an empty list); pass an ObservationSet, a file's path or a list of them"
        )
    for o in items:
        if not isinstance(o, (ObservationSet, str, os.PathLike)):
            raise InputTypeError.expected("diagnose", "observations", f"{OBSERVATION_SET}, a file's path or a list of them", o)
    sets = [o if isinstance(o, ObservationSet) else ObservationSet.read(o) for o in items]
    return merge_observations(sets)


def _default_model(obs):
    from boresight.core.disturbances import DisturbanceModel
    from boresight.errors import NoiseModelError

    f = getattr(DisturbanceModel, "from_observations", None)
    model = f(obs) if f is not None else None
    if model is None:
        raise NoiseModelError(
            "diagnose: the observation file carries no noise model (metadata 'noise', format 1.1); "
            "give one (model=DisturbanceModel(...), or --sigma-pixel-m, --sigma-star-tracker-arcsec, --sigma-gnss-m, --sigma-catalogue-m)"
        )
    return model


def diagnose(
    observations,
    model=None,
    *,
    effects=None,
    candidates=None,
    alpha: float = 0.01,
    power: float = 0.8,
    max_steps: int = 4,
    run: int = 0,
    progress=None,
) -> Diagnosis:
    """Find what the model misses: base fit, residual tests, identifiability, naming (module docstring).

    Parameters
    ----------
    observations : an ``ObservationSet``, a path to an observation file, or a list of either
        (merged into one campaign: images concatenated, pass indices distinct per input).
    model : ``DisturbanceModel``; default the file's noise model (format 1.1 metadata ``noise``).
    effects : catalogue effect names to consider (default: all of ``boresight.core.effect_model.effect_names()``).
    candidates : alternatively, explicit :class:`~boresight.studies.discrepancy.candidates.Candidate` objects.
    alpha : family-wise level of the naming and of the residual tests (default 1 %).
    power : power at which the minimum detectable sizes are quoted (default 80 %).
    max_steps : at most this many effects are named.
    run : which run of a multi-run ``ObservationSet`` to diagnose.
    progress : optional callable given a short description of each stage as it starts.

    Returns
    -------
    Diagnosis
        the verdicts and their evidence (``as_json()`` is ``diagnosis.json``).

    Raises
    ------
    InputTypeError
        ``observations`` is not an ``ObservationSet``, a path or a list of them; ``model`` is not a
        ``DisturbanceModel``; ``candidates`` is not a list of ``Candidate``.
    InputValueError
        ``alpha`` or ``power`` is not a number in (0, 1); ``run`` is not one of the observations' runs.
    ObservationError
        An empty list, or inputs that cannot be merged into one campaign (``merge_observations``); an
        observation file that cannot be read raises the reader's ``ObservationFileError`` (a subclass).
    NoiseModelError
        The observations carry no noise model and ``model`` is not given.
    UnknownEffectError
        A name in ``effects`` is not in the effects catalogue.
    """
    from boresight.errors import InputTypeError, InputValueError
    from boresight.studies.discrepancy.campaign import CampaignProblem
    from boresight.studies.discrepancy.candidates import Candidate, catalogue_candidates

    if not all(isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) and 0 < v < 1 for v in (alpha, power)):
        raise InputValueError(f"diagnose: alpha and power must be numbers in (0, 1), got {alpha!r}, {power!r}")
    obs = _load(observations)
    if isinstance(run, bool) or not isinstance(run, (int, np.integer)) or not 0 <= run < obs.runs:
        raise InputValueError(f"diagnose: run must be an integer in 0..{obs.runs - 1} (the observations' runs), got {run!r}")
    if obs.runs > 1:
        obs = obs.run(run)
    if model is None:
        model = _default_model(obs)
    if candidates is None:
        candidates = [] if effects is not None and len(effects) == 0 else catalogue_candidates(effects)
    elif not (isinstance(candidates, (list, tuple)) and all(isinstance(c, Candidate) for c in candidates)):
        raise InputTypeError.expected(
            "diagnose", "candidates", "a list of Candidate (catalogue_candidates(names); effect names go to effects=)", candidates
        )
    problem = CampaignProblem(obs, model, list(candidates))
    return diagnose_problem(problem, alpha=alpha, power=power, max_steps=max_steps, progress=progress)


def _left_beyond_floated(rec, st, tests0, alpha) -> str:
    """The structure a floated, not-decisive group leaves (as text; empty when none): each probe
    that failed at the base fit re-tested beyond the floated model at level α — its LR statistic
    on the probe columns independent of the model.

    DECISION: floating a candidate that is significant but not decisive must not hide
    structure it does not explain. The final residual tests judge the family with Holm at
    family-wise α, so a ``pass`` probe left at p = 0.005 by a floated ``thermal`` passes them
    although thermal was not the cause (an 8″ alignment step after pass 2 of 6: thermal "not
    decisive" and "nothing unexplained" in 4 of 10 seeds). The probes that failed before anything
    was fitted are the structure the group is credited with, so each is asked, at α itself,
    whether the group took it; one that is still significant sets ``unexplained_structure``, and
    "more data would name it" is not said."""
    from scipy import stats

    if not rec["not_decisive"] or rec["ambiguous"]:
        return ""
    failing = [t.name for t in tests0 if t.rejected and t.name not in GENERIC_TESTS]
    out = []
    for name, x, k, _ in leftover(st, failing, alpha):
        p = float(stats.chi2.sf(x, k))
        if p <= alpha:
            out.append(f"{name}: Δχ² = {x:.1f} on {k} dof, p = {p:.2g}")
    return "; ".join(out)


def _tails(st, tests) -> dict | None:
    """The tails of the final model's normalised residuals r/√(1 − h) when the outlier test fails:
    excess kurtosis over the n residuals, heavy when above max(1, 4 √(24/n)) (Gaussian: 0 with standard
    error √(24/n)), and the loss kept, with why. None when the outlier test passes.

    DECISION: a heavy-tailed residual is a question of the loss, not of structure or of an
    extra rotation per image (Student-t noise once got a 29.5″ rotation per image and σθ 5× θ's
    scatter). Least squares is kept: its σθ is honest for any error distribution whose variance the
    noise model has (the χ² test, or the variance components when it fails); a robust loss
    (``boresight estimate --loss huber``) would be more efficient, and is named, not imposed."""
    from scipy import stats

    if not any(t.rejected and t.name == "normalised residuals" for t in tests):
        return None
    nd = st.cl.lin.n_data
    r = st.base.residual[:nd]
    t = r / np.sqrt(np.clip(1.0 - st.base.leverage(nd), 1e-12, None))
    k = float(stats.kurtosis(t))
    heavy = k > max(1.0, 4.0 * np.sqrt(24.0 / max(nd, 1)))
    return {
        "excess_kurtosis": k,
        "n": int(nd),
        "heavy": bool(heavy),
        "loss": "least squares",
        "reason": (
            "heavy tails are a question of the loss, not of structure or of an extra rotation: least squares is kept, its "
            "σθ honest for any error distribution of the noise model's variance; a robust loss (boresight estimate --loss "
            "huber) would be more efficient"
            if heavy
            else "the tails are Gaussian: the largest residual is an outlier of its own (see diagnosis.md)"
        ),
    }
