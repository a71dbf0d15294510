"""A landmark campaign (``ObservationSet`` + ``DisturbanceModel``) as a whitened linear problem.

This adapter turns Algorithm 3's image-plane residuals (``boresight.core.algorithms.image_plane``)
into the :class:`~boresight.studies.discrepancy.linear.GramProblem` the diagnosis works on, through
the one campaign GLS (``boresight.core.gls.campaign``):

* the columns of θ, the named effects (at their current values), every candidate (at parameter
  0) and every structure probe, and the residual q = measured − predicted(θ) − Σ offset_e(p_e),
  one row per observation (R = 1, K rows, 2 components: ``docs/architecture.md``, "The row model"),
  go through the one GLS on rows (``boresight.core.gls.rows``), which eliminates the per-image,
  per-pass and catalogue errors of the noise model exactly; its reduced normal equations are the
  Gram matrix;
* per-row residuals and leverages for the residual tests come from the same factors.

Everything is per row or per image: the probes bin rows by image radius and position angle (per
row), by time in pass, argument of latitude, pass, campaign time and attitude law (per image,
gathered to its rows); no array has an images × targets axis pair, so memory and CPU grow with the
observations (and the columns the probes need: the ``pass`` probe has 3 per pass).

It also computes the regressors the residual tests and the plots use: image radius and
position angle of each observation, time in pass, argument of latitude (from the orbit
plane of each pass — from the positions, so no velocity is needed), pass and attitude law
(nadir vs pointed, from the spread of the camera's off-nadir angle over the pass).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any, Callable

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.campaign import fit_rows
from boresight.core.gls.rows import RowFit, RowStructure, row_group_grams, row_reduced_rows, row_residuals
from boresight.core.measurement import linearize_rows
from boresight.errors import InputValueError
from boresight.studies.discrepancy.candidates import Candidate, columns_for
from boresight.studies.discrepancy.linear import BlockGram, GramProblem
from orbits.rotations import ARCSEC

__all__ = ["CampaignProblem", "CampaignLinearization"]

#: the compact GLS of a campaign whose passes share no target runs on chunks of groups of about this many rows
#: (``CampaignProblem._group_grams``, and the residual rows)
# DECISION: 4 096 — a chunk's GLS holds ~20 kB a row (its whitened compact columns, per-target arrays): one
# linearisation of every column of the single-use campaign ×30 traced 307 MiB at 16 384 rows a chunk, 111 MiB at
# 4 096, 81 MiB at 2 048, in 1.06–1.59, 0.83–0.95 and 0.85 s CPU, the residual rows of θ 0.33, 0.35 and 0.39 s (/tmp
# script, loaded machine, 2026-11-28): smaller chunks are no dearer down to ~2 000 rows, and the memory is a chunk's
GROUP_CHUNK_ROWS = 4_096
#: above this many rows the full columns' GLS (the Gauss–Newton steps of θ and the named effects: no per-pass column)
#: runs on the same chunks of groups as the compact one
# DECISION: 65 536 — the whole campaign's GLS holds ~1 kB a row and was the process's peak at 131 000 observations
# (``docs/benchmarks.md``, "### ``diagnose``"); its sum over chunks is exact but in another order, and the
# ill-conditioned joint fits of a diagnosis turn that round-off into ~3e-10 relative on the named estimates and
# 2e-9 on a p-value (the single-use campaign ×10, 13 100 rows, chunked); below the bound the one GLS is kept, and the
# smaller campaigns' answers are the same to the last digits
FULL_GLS_MAX_ROWS = 65_536


@dataclass(frozen=True)
class CampaignLinearization:
    lin: GramProblem
    candidates: dict  # name -> Columns of lin (k), scaled units
    status: dict  # name -> "ok" | "needs velocity" | reason
    scales: dict  # name -> (k,) scale of the columns (parameter units per column unit)
    probes: dict  # name -> Columns of lin (k)
    #: () -> (G, q, the fitted columns) at the linearisation's θ and named values (``CampaignProblem._design``), rebuilt
    #: when asked: a state keeps no K-sized array of its own (``CampaignProblem.linearize``)
    design: Callable[[], tuple]

    @property
    def residual_xy_m(self) -> np.ndarray:
        """(K, 2) image-plane residual of the current model, one row per observation."""
        return np.asarray(self.design()[1])

    @property
    def G(self) -> np.ndarray:
        """(K, 2, 3) image-plane Jacobian of θ (m/rad)."""
        return np.asarray(self.design()[0])


@dataclass(frozen=True)
class PassColumns:
    """Columns each non-zero on the rows of some passes only, with one pattern there: the full column
    (b, i) is Σ_p ``expand``[p, b] · ``values``[:, :, i] on the rows of pass p (compact passes, the
    order of ``np.unique(pass_index)``), the columns in the order (b, i), b major. ``values`` (K, 2, w);
    ``expand`` (P, B). The ``pass`` probe is G with ``expand`` = E_P (3 columns per pass), ``image scale by
    pass`` one radial column per pass, a scanned ``alignment_step`` its step columns after each boundary
    (``expand``[p, b] = 1 for the passes after boundary b). ``CampaignProblem._gram`` keeps them in this
    form: its GLS carries w columns for them, not w·B."""

    values: np.ndarray
    expand: np.ndarray

    @property
    def k(self) -> int:
        return int(self.expand.shape[1] * self.values.shape[-1])

    def dense(self, row_pass: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
        """The full columns (K, 2, B·w), or only the columns ``use`` of them, one row per observation."""
        w = self.values.shape[-1]
        use = np.arange(self.k) if use is None else np.asarray(use, np.int64)
        b, i = np.divmod(use, w)
        return self.values[..., i] * self.expand[row_pass][:, None, b]


def _columns_of(parts: list, row_pass: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
    """The columns ``use`` (all by default) of ``parts`` (arrays (K, 2, k) or ``PassColumns``, side by side), (K, 2, ·)."""
    out, start = [], 0
    for P in parts:
        k = P.k if isinstance(P, PassColumns) else P.shape[-1]
        sel = np.arange(k) if use is None else np.asarray(use, np.int64)[(use >= start) & (use < start + k)] - start
        if sel.size:
            out.append(P.dense(row_pass, sel) if isinstance(P, PassColumns) else P[..., sel])
        start += k
    K = row_pass.size
    return np.concatenate(out, axis=-1) if out else np.zeros((K, 2, 0))


class CampaignProblem:
    """See the module docstring. ``obs`` must have one run (flight data); ``run`` picks one."""

    kind = "campaign"
    base_labels = ("theta_x", "theta_y", "theta_z")
    theta_unit = "arcsec"
    theta_to_display = 1.0 / ARCSEC

    def __init__(self, obs, model: DisturbanceModel, candidates: list[Candidate], run: int = 0):
        from boresight.errors import BoresightError, InputTypeError

        if obs.runs > 1:
            obs = obs.run(run)
        if not isinstance(model, DisturbanceModel):
            raise InputTypeError.expected("diagnose", "model", "a boresight.DisturbanceModel or None", model)
        from boresight.core.gls.structure import has_pixel_noise

        if not has_pixel_noise(obs, model):
            raise BoresightError(
                "diagnose: the noise model needs a pixel σ > 0 on every row: sigma_pixel_m > 0 (from the file's noise "
                "metadata or --sigma-pixel-m), or each row's own σ (sigma_x, sigma_y)"
            )
        self.obs = obs
        self.model = model
        self.candidates = {c.name: c for c in candidates}
        #: the chosen value of each scanned candidate's boundary (``naming.best_block``), by name
        self.scan_choice: dict = {}
        self.structure = RowStructure.of(obs)
        self.img, self.lmk = self.structure.image_index, self.structure.target_index  # (K,) canonical order
        self.n_obs = self.img.size
        if self.n_obs < 3:
            raise BoresightError(f"diagnose: {self.n_obs} landmark observation(s); at least 3 are needed")
        self.regressors = self._regressors()
        #: name → the probe's columns, (K, 2, k) or ``PassColumns`` (per-pass probes)
        self.probes = self._probe_columns()
        self.n_images = obs.n_images
        self.row_pass = self.structure.row_pass
        self._groups = _pass_groups(self.structure)

    @property
    def probes_rows(self) -> dict:
        """name → the probe's columns (K, 2, k), every column one row per observation."""
        return {n: _columns_of([P], self.row_pass) for n, P in self.probes.items()}

    def with_model(self, model: DisturbanceModel, obs: Any = None) -> "CampaignProblem":
        """The same campaign and candidates under another noise model (and ``obs``, the same rows with their own
        pixel σ rescaled: ``VarianceComponents.scaled_rows``; None: the problem's)."""
        return CampaignProblem(self.obs if obs is None else obs, model, list(self.candidates.values()))

    # ------------------------------------------------------------------ geometry
    def _on_rows(self, a, row_ndim: int) -> np.ndarray:
        """A candidate's array, checked to be on the rows: (R, K, 2[, k]) (``candidates.ColumnSet``)."""
        a = np.asarray(a, float)
        if a.ndim != row_ndim or a.shape[1] != self.n_obs:
            raise InputValueError(
                f"diagnose: a candidate's columns must be one row per observation, (R, {self.n_obs}, 2[, k]); got {a.shape}"
            )
        return a

    def _regressors(self) -> dict:
        obs = self.obs
        xy = np.asarray(obs.xy_m, float)[0]  # (K, 2), the rows' measured points
        radius = np.hypot(xy[:, 0], xy[:, 1])
        pa = np.arctan2(xy[:, 1], xy[:, 0])
        t = obs.t_s
        passes = obs.pass_index
        t_in = np.empty_like(t)
        u_lat = np.full(t.shape, np.nan)
        law = np.empty(t.shape, dtype=object)
        r = obs.r_sc_i_m[0]
        C_IK = obs.nominal_camera_attitude()[0]
        bore_i = np.einsum("nji,j->ni", C_IK, [0.0, 0.0, -1.0])
        off_nadir = np.degrees(
            np.arccos(np.clip(np.einsum("ni,ni->n", bore_i, -r / np.linalg.norm(r, axis=-1, keepdims=True)), -1, 1))
        )
        for p in np.unique(passes):
            sel = passes == p
            tt = t[sel]
            t_in[sel] = tt - 0.5 * (tt.min() + tt.max())
            rp = r[sel]
            h = np.cross(rp[0], rp[-1]) if sel.sum() > 1 else np.zeros(3)
            if np.linalg.norm(h) > 0:
                h = h / np.linalg.norm(h)
                node = np.cross([0.0, 0.0, 1.0], h)
                node = node / (np.linalg.norm(node) or 1.0)
                u_lat[sel] = np.arctan2(np.einsum("ni,i->n", np.cross(node, rp), h), rp @ node)
            spread = np.ptp(off_nadir[sel])
            law[sel] = "nadir" if spread < 0.5 and off_nadir[sel].max() < 2.0 else "pointed"
        return {
            "x_m": xy[:, 0],
            "y_m": xy[:, 1],
            "radius_m": radius,
            "position_angle_rad": pa,
            "image": self.img,
            "t_in_pass_s": t_in,
            "arg_latitude_rad": u_lat,
            "pass": passes,
            "attitude_law": law,
            "off_nadir_deg": off_nadir,
            "t_s": t,
        }

    def _probe_columns(self) -> dict:
        """Generic image-plane patterns for the residual tests, (K, 2, k) each, one row per observation.

        Field patterns (radial/tangential displacements as functions of image radius and position
        angle, per row) and common-rotation patterns (θ-like rotations varying with time in pass,
        argument of latitude, pass, campaign time and attitude law: a per-image value gathered to the
        image's rows). They carry no physics: the tests ask whether the residuals hold *any* such
        structure beyond the noise model.
        """
        obs = self.obs
        reg = self.regressors
        img = self.img
        out: dict = {}
        xy = np.column_stack([reg["x_m"], reg["y_m"]])  # (K, 2)
        rad = reg["radius_m"]
        rmax = rad.max() or 1.0
        with np.errstate(invalid="ignore", divide="ignore"):
            rhat = np.where(rad[:, None] > 0, xy / rad[:, None], 0.0)
        that = np.stack([-rhat[:, 1], rhat[:, 0]], axis=-1)
        phi = reg["position_angle_rad"]
        rn = rad / rmax
        # image radius: radial displacement ∝ r within each radius quartile
        edges = np.quantile(rad, [0, 0.25, 0.5, 0.75, 1.0])
        cols = []
        for b in range(4):
            inb = (rad >= edges[b]) & ((rad < edges[b + 1]) if b < 3 else (rad <= edges[b + 1]))
            cols.append(rhat * (rn * inb)[:, None])
        out["image radius"] = np.stack(cols, axis=-1)
        cols = []
        for k in (1, 2, 3):
            for f in (np.cos, np.sin):
                w = (rn * f(k * phi))[:, None]
                cols += [rhat * w, that * w]
        out["position angle"] = np.stack(cols, axis=-1)
        # rotations: G0 at θ = 0 (its shape, not its value, matters for a probe)
        G = linearize_rows(obs, np.zeros(3), (self.img, self.lmk), obs.xy_m)[0][0]  # (K, 2, 3)

        def per_image(v):  # a per-image value on its rows, broadcast against (K, 2, 3)
            return np.asarray(v)[img][:, None, None]

        img_t = reg["t_in_pass_s"]
        tau = np.zeros(obs.n_images)
        for p in np.unique(obs.pass_index):
            sel = obs.pass_index == p
            half = np.abs(img_t[sel]).max()
            tau[sel] = img_t[sel] / half if half > 0 else 0.0
        out["time in pass"] = np.concatenate([G * per_image(tau), G * per_image(tau**2 - 1 / 3)], axis=-1)
        u = reg["arg_latitude_rad"]
        if np.all(np.isfinite(u)):
            out["argument of latitude"] = np.concatenate([G * per_image(np.sin(u)), G * per_image(np.cos(u))], axis=-1)
        passes = np.unique(obs.pass_index)
        if passes.size > 1:
            out["pass"] = PassColumns(G, np.eye(passes.size))  # a rotation per pass: G on its rows
            # a rotation linear in campaign time (an alignment drift over days): the "pass" probe
            # contains it when the passes are short, but spends 3 dof per pass
            from orbits.effects import campaign_time_s

            tc = campaign_time_s(obs.t_s)
            if np.abs(tc).max() > 0:
                out["campaign time"] = G * per_image(tc / np.abs(tc).max())
            out["image scale by pass"] = PassColumns((rhat * rn[:, None])[..., None], np.eye(passes.size))
        laws = np.unique(reg["attitude_law"].astype(str))
        if laws.size > 1:
            lw = reg["attitude_law"].astype(str)[img]
            out["attitude law"] = np.concatenate([G * (lw == L)[:, None, None] for L in laws], axis=-1)
        return out

    # ------------------------------------------------------------------ linearisation
    def linearize(self, theta_rad, named: dict, candidate_names=(), probes: bool = False) -> CampaignLinearization:
        """The whitened problem at θ and the named effects' parameter values.

        ``named``: name → (k,) parameter values in the candidate's units (fitted jointly with θ).
        ``candidate_names``: candidates whose columns (at parameter 0) to whiten for testing.
        """
        obs = self.obs
        theta = np.array(theta_rad, float).reshape(3)
        # DECISION: the fitted columns and q are rebuilt from θ, the named values and the scan choices (copied here:
        # the caller's dict changes under Gauss–Newton) when a state's residual rows, G or q are asked for, not kept:
        # every state of a diagnosis holds its linearisation, and these K × (3 + named) arrays were most of the live
        # memory at 131 000 observations (``docs/benchmarks.md``, "### ``diagnose``"); a rebuild is the same arithmetic,
        # so the same numbers
        design = partial(self._design, theta, {k: np.array(v, float) for k, v in named.items()}, dict(self.scan_choice))
        G, q, blocks = design()
        cand_slices, status, scales = {}, {}, {}
        cand_blocks = []
        col = 0
        sets = columns_for(
            obs, theta, [self.candidates[n] for n in candidate_names if n not in self.scan_choice and not self._scans(n)]
        )
        for name in candidate_names:
            c = self.candidates[name]
            if self._scans(name):
                J, status[name], scales[name] = self._scan_columns(c, theta)
            else:
                cs = sets[name] if name in sets else self._columns(c, theta, None)
                status[name] = cs.status
                sc = self.column_scales(c, cs)
                scales[name] = sc
                J = self._on_rows(cs.jacobian, 4)[0] * sc  # (K, 2, k)
                if cs.status != "ok":
                    J = np.zeros_like(J)
            cand_blocks.append(J)
            k = J.k if isinstance(J, PassColumns) else J.shape[-1]
            cand_slices[name] = slice(col, col + k)
            col += k
        probe_slices = {}
        probe_blocks = []
        if probes:
            pc = 0
            for name, P in self.probes.items():
                probe_blocks.append(P)
                k = P.k if isinstance(P, PassColumns) else P.shape[-1]
                probe_slices[name] = slice(pc, pc + k)
                pc += k
        n_fitted = sum(b.shape[-1] for b in blocks)
        lin = self._gram(theta, blocks + cand_blocks + probe_blocks, q, n_fitted, transient=len(cand_blocks), design=design)
        nf = n_fitted
        cands = {name: lin.columns(nf + sl.start, nf + sl.stop) for name, sl in cand_slices.items()}
        prb = {name: lin.columns(nf + col + sl.start, nf + col + sl.stop) for name, sl in probe_slices.items()}
        return CampaignLinearization(lin, cands, status, scales, prb, design)

    def _scans(self, name: str) -> bool:
        """True for a scanned candidate whose boundary is not chosen yet (its columns: every boundary's)."""
        return bool(self.candidates[name].extra.get("scan")) and name not in self.scan_choice

    def _scan_columns(self, c: Candidate, theta):
        """A scanned candidate's columns at every boundary (``candidates.scan_candidate``), with its status
        and scales: ``PassColumns`` of its columns on every image (a boundary before the first) when each pass lies
        wholly on one side of each boundary (the columns at boundary b are those on the passes after it,
        exactly: the step's Jacobian is the θ-like one times H(t − t_b)), else the dense blocks side by side."""
        from boresight.studies.discrepancy.candidates import scan_boundaries

        ats = scan_boundaries(self.obs)
        if ats.size == 0:  # one pass: no gap to scan
            cs = c.columns(self.obs, theta, None)
            zero = np.zeros(self._on_rows(cs.jacobian, 4)[0].shape[:-1] + (c.n_params,))
            return zero, "needs two or more passes (its boundary is scanned between passes)", self.column_scales(c, cs)
        cs = c.columns(self.obs, theta, None, at=float(self.obs.t_s.min()) - 1.0)  # before every image
        sc = self.column_scales(c, cs)
        after = self.obs.t_s[:, None] > ats[None, :]  # (N, B)
        pimg = self.structure.pass_of_image
        expand = np.zeros((self.structure.n_passes, ats.size))
        expand[pimg] = after
        status = cs.status
        J: Any
        if np.array_equal(expand[pimg], after.astype(float)):
            J = PassColumns(self._on_rows(cs.jacobian, 4)[0] * sc, expand)
        else:  # a pass straddles a boundary: the blocks side by side
            cs = c.columns(self.obs, theta, None)
            status = cs.status
            J = self._on_rows(cs.jacobian, 4)[0] * np.tile(sc, ats.size)
        if status != "ok":
            J = np.zeros(J.values.shape[:-1] + (J.k,)) if isinstance(J, PassColumns) else np.zeros_like(J)
        return J, status, np.tile(sc, ats.size)

    def _design(self, theta, named: dict, scan_choice: dict | None = None):
        """Algorithm 3's Jacobian G (K, 2, 3) and residual q (K, 2) with the named effects' offsets
        removed, and the fitted columns (θ, named effects), one row per observation (a scanned effect at its
        boundary in ``scan_choice``, default the problem's).

        Algorithm 3's linearisation (``core.algorithms.image_plane.linearize``) is the measurement
        model's, ``measurement.linearize_rows`` on the rows."""
        obs = self.obs
        G, q = linearize_rows(obs, theta, (self.img, self.lmk), obs.xy_m)
        G, q = G[0], q[0]  # (K, 2, 3), (K, 2)
        blocks = [G]
        for name, p in named.items():
            c = self.candidates[name]
            cs = self._columns(c, theta, np.asarray(p, float), scan_choice)
            q = q - self._on_rows(cs.offset, 3)[0]
            blocks.append(self._on_rows(cs.jacobian, 4)[0] * self.column_scales(c, cs))
        return G, q, blocks

    def _columns(self, c: Candidate, theta, params, scan_choice: dict | None = None):
        """A candidate's columns; a scanned one at its chosen boundary (``scan_choice``, default the problem's) when
        one is chosen."""
        scan_choice = self.scan_choice if scan_choice is None else scan_choice
        if c.extra.get("scan") and c.name in scan_choice:
            return c.columns(self.obs, theta, params, at=scan_choice[c.name])
        return c.columns(self.obs, theta, params)

    def variance_components(self, theta_rad, named: dict, extra_pass_rotation_rad: float = 0.0):
        """The noise model's variance components re-estimated on the residuals of θ and the named
        effects (``boresight.core.variance_components``: REML through the one GLS on rows)."""
        from boresight.core.variance_components import variance_components

        theta = np.asarray(theta_rad, float).reshape(3)
        _, q, blocks = self._design(theta, named)
        cols = np.concatenate(blocks, axis=-1)
        return variance_components(
            self.obs, theta, cols[None], q[None], self.model, extra_pass_rotation_rad=extra_pass_rotation_rad
        )

    def fit(self, theta, cols, q) -> RowFit:
        """The one GLS on rows (``boresight.core.gls.campaign.fit_rows``) of the columns ``cols`` (K, 2, p)
        and residuals ``q`` (K, 2) m under the problem's noise model (image-plane residuals)."""
        return fit_rows(self.obs, theta, cols[None], q[None], self.model)

    def _gram(self, theta, parts: list, q, n_fitted, transient: int = 0, design: Callable | None = None) -> GramProblem:
        """The problem in reduced form through the one GLS on rows (``boresight.core.gls.rows``).

        One GLS accumulation over all the columns ``parts`` ((K, 2, k) arrays and ``PassColumns``, side
        by side: θ, named effects, candidates, probes) and the residual q eliminates the per-image,
        per-pass and catalogue errors of the noise model; its reduced normal equations are the Gram
        matrix every fit, test and withdrawal of the diagnosis works on. Per-row residuals and
        leverages for the residual tests come from the same factors (``row_residuals``,
        ``row_reduced_rows``), in the rows' order.
        DECISION: the reduced form replaces a whitened dense regression with a column per shared
        error (~765 catalogue and per-pass columns on a 6-pass campaign, factorised for every
        fit); ``tests/studies/test_discrepancy_engine.py`` checks the base fit equal to ``estimate``'s GLS.

        Per-pass columns (``PassColumns``) stay compact when the passes fall into groups that share no
        target (``_pass_groups``; every pass its own group on a campaign of single-use ground-control
        points): the GLS then carries each such part's w columns once per place of a pass in its group
        (w·S for groups of at most S passes) instead of w per pass — the per-pass columns of different
        groups are the same columns of Y restricted to each group's rows —, its reduced block summed
        group by group (``rows.row_group_grams``: exact, the joint information is block-diagonal over
        the groups, on chunks of groups: ``_group_grams``) and held by its blocks over the full columns
        (``_assemble``'s map, ``linear.BlockGram``: never the (p + 1)² matrix, p ≈ 4 300 at 600 passes).
        DECISION: the GLS on rows, whose work and memory go as K × its columns², carries ≈ 70 columns however
        many passes there are (``docs/benchmarks.md``).
        Where the groups are few and large (a campaign whose passes revisit the same sites: one group)
        the compact form is no narrower, and the full columns go through the GLS as they did.
        ``design`` (() -> (G, q, the fitted parts), ``linearize``): the rows rebuild the fitted parts and q from it
        instead of keeping them.
        """
        row_pass = self.row_pass
        n_groups, group_of_pass, slot_of_pass, smax = self._groups
        pcs = [P for P in parts if isinstance(P, PassColumns)]
        widths = [P.k if isinstance(P, PassColumns) else P.shape[-1] for P in parts]
        p = int(sum(widths))
        compact = bool(pcs) and smax * sum(P.values.shape[-1] for P in pcs) < sum(P.k for P in pcs)
        gram: Any
        raw: Any
        chunks = self._group_chunks() if compact or self.n_obs > FULL_GLS_MAX_ROWS else []
        if not compact and len(chunks) <= 1:
            cols = _columns_of(parts, row_pass)
            fit = self.fit(theta, cols, q)
            ne = fit.normal_equations
            gram = np.empty((p + 1, p + 1))
            gram[:p, :p] = ne.data_information[0]
            gram[:p, p] = gram[p, :p] = ne.vector[0]
            gram[p, p] = ne.weighted_sum_squares[0]
            raw = fit.image_gram[0][:p, :p]
        elif not compact:
            # the full columns' GLS on the chunks of groups (``FULL_GLS_MAX_ROWS``): the groups share no nuisance, so
            # the reduced normal equations are the sum of the chunks' (exact, summed in another order)
            cols = _columns_of(parts, row_pass)
            gram, raw, n_residuals = np.zeros((p + 1, p + 1)), np.zeros((p, p)), 0
            for _, at, images in chunks:
                f_c = fit_rows(self._chunk_obs(images), theta, cols[at][None], q[at][None], self.model)
                ne_c = f_c.normal_equations
                gram[:p, :p] += ne_c.data_information[0]
                gram[:p, p] += ne_c.vector[0]
                gram[p, p] += ne_c.weighted_sum_squares[0]
                raw += f_c.image_gram[0][:p, :p]
                n_residuals += int(ne_c.n_residuals[0])
            gram[p, :p] = gram[:p, p]
            raw = 0.5 * (raw + raw.T)
            fit = None
        else:
            red, img, n_residuals = self._group_grams(theta, parts, q, slot_of_pass[row_pass], smax)
            M = self._assemble(parts, widths, n_groups, group_of_pass, slot_of_pass, smax)
            gram = _block_gram(M, red, _shared_atoms(parts, smax))
            raw = _block_gram(M, img, _shared_atoms(parts, smax), size=p)
            fit = None  # the rows below need a GLS of the used columns; the linearisation keeps no K × p array

        # DECISION: the rows below read the fitted columns only (a state's base fit: θ and the named effects); the
        # ``transient`` parts after the fitted ones (the candidates' columns, new arrays at every linearisation, K × ~45)
        # are not kept alive by them — every state of a diagnosis holds its problem, and they were most of its memory
        # (the probes are the problem's own arrays, shared)
        n_fit_parts = int(np.searchsorted(np.cumsum([0] + widths), n_fitted))
        drop = range(n_fit_parts, n_fit_parts + transient)
        rebuilt = range(n_fit_parts if design is not None else 0)
        kept = [_placeholder(P, self.n_obs) if i in drop or i in rebuilt else P for i, P in enumerate(parts)]
        lo, hi = n_fitted, n_fitted + sum(widths[i] for i in drop)
        if design is not None:
            q = None  # rebuilt with the fitted parts

        def rows(x, cov, use):
            # DECISION: the rows depend only on the columns with a coefficient or a variance (the fitted
            # model's): the residuals e = q̃ − Σ_j x_j z_j − (MAP nuisances, linear in the same terms), the
            # leverage h = h_ν + z̃ᵀ cov z̃ with each z̃_j a function of its own column. They are computed
            # on a GLS of those columns alone — equal, and linear in K instead of K·p² with the probes'
            # columns (3 per pass) in the fit
            x, cov = np.asarray(x, float), np.asarray(cov, float)
            keep = (x[use] != 0) | (np.diag(cov) != 0)
            use, cov = np.asarray(use)[keep], cov[np.ix_(keep, keep)]
            if np.any((use >= lo) & (use < hi)):
                # internal: `use` comes from this problem's own fitted model, which never holds the transient candidates
                raise ValueError(f"rows: columns {lo}..{hi - 1} (the candidates') are not kept for the residual rows")
            xs, cs = x[use][None], cov[None]
            if use.size == p and fit is not None:
                return _rows_of(fit, xs, cs)
            q_now, parts_now = q, kept
            if design is not None:
                _, q_now, fitted = design()
                parts_now = list(fitted) + kept[n_fit_parts:]
            cols = _columns_of(parts_now, row_pass, use)
            # DECISION: the GLS of the used columns runs on the chunks of groups of ``_group_grams`` (one chunk: the
            # whole campaign, as before, when the passes share targets or the campaign is small): the groups share no
            # nuisance, so a chunk's MAP nuisances, residuals and reduced rows are its groups' own — exact, given x
            # and its covariance — and its whitened columns and per-target arrays are a chunk's, not K's
            out = [np.empty(2 * self.n_obs) for _ in range(3)]
            for _, at, images in self._group_chunks():
                sub = fit_rows(self._chunk_obs(images), theta, cols[at][None], q_now[at][None], self.model)
                for o, r in zip(out, _rows_of(sub, xs, cs)):
                    o.reshape(-1, 2)[at] = r.reshape(-1, 2)
            return tuple(out)

        if fit is not None:
            n_residuals = int(fit.normal_equations.n_residuals[0])
            raw = 0.5 * (raw + raw.T)
        return GramProblem(gram, raw, n_residuals, n_fitted, rows)

    def _group_grams(self, theta, parts: list, q, slot_row: np.ndarray, smax: int) -> tuple[np.ndarray, np.ndarray, int]:
        """Each group's reduced block and ``image_gram`` of the compact columns (``rows.row_group_grams``), (G, m + 1,
        m + 1) twice, and the number of residuals: the GLS run on consecutive groups of passes holding at most
        ``GROUP_CHUNK_ROWS`` rows at a time (one GLS when the campaign is smaller).

        DECISION: the groups share no nuisance, so a chunk's GLS gives its groups' blocks exactly
        (``row_group_grams``' docstring) and the whole GLS is never needed: its K × m whitened columns and their
        copies (m ≈ 75 compact columns: ~160 MB each at 131 000 observations) are a chunk's, and the memory of the
        diagnosis stops growing with the passes beyond its per-row columns."""
        n_groups, group_of_pass, _, _ = self._groups
        group_img = group_of_pass[self.structure.pass_of_image]
        ny = 1 + sum(smax * P.values.shape[-1] if isinstance(P, PassColumns) else P.shape[-1] for P in parts)
        red, img = np.zeros((n_groups, ny, ny)), np.zeros((n_groups, ny, ny))
        n_residuals = 0
        for groups, rows, images in self._group_chunks():
            whole = images is None
            obs = self._chunk_obs(images)
            Xc = []
            for P in parts:
                if isinstance(P, PassColumns):
                    Xc += [P.values[rows] * (slot_row[rows] == s_)[:, None, None] for s_ in range(smax)]
                else:
                    Xc.append(P[rows])
            fit = fit_rows(obs, theta, np.concatenate(Xc, axis=-1)[None], q[rows][None], self.model)
            local = np.searchsorted(groups, group_img if whole else group_img[np.isin(group_img, groups)])
            r, i = row_group_grams(fit, local, groups.size)
            red[groups], img[groups] = r[0], i[0]
            n_residuals += int(fit.normal_equations.n_residuals[0])
        return red, img, n_residuals

    def _group_chunks(self) -> list:
        """Consecutive groups of passes (``_pass_groups``) in chunks of at most ``GROUP_CHUNK_ROWS`` rows (a group
        larger than that alone): (the chunk's groups, its rows — ``slice(None)`` for one chunk —, its images — None for
        one chunk —) each, in order."""
        n_groups, group_of_pass, _, _ = self._groups
        group_img = group_of_pass[self.structure.pass_of_image]
        g_row = group_img[self.img]
        counts = np.bincount(g_row, minlength=n_groups)
        chunk = np.zeros(n_groups, np.int64)
        rows_in = 0
        for g in range(n_groups):  # consecutive groups until a chunk holds GROUP_CHUNK_ROWS rows
            if rows_in and rows_in + counts[g] > GROUP_CHUNK_ROWS:
                chunk[g:] += 1
                rows_in = 0
            rows_in += counts[g]
        if chunk[-1] == 0:
            return [(np.arange(n_groups), slice(None), None)]
        out = []
        for c in range(int(chunk[-1]) + 1):
            groups = np.flatnonzero(chunk == c)
            out.append((groups, np.flatnonzero(np.isin(g_row, groups)), np.flatnonzero(np.isin(group_img, groups))))
        return out

    def _chunk_obs(self, images: np.ndarray | None):
        """The observations of a chunk's ``images`` (None: the whole campaign) with the chunk's own targets only: the GLS
        sizes its per-target arrays by the target table, which ``images`` keeps whole."""
        return self.obs if images is None else self.obs.images(images).observed_targets()

    @staticmethod
    def _assemble(parts, widths, n_groups, group_of_pass, slot_of_pass, smax):
        """The map M (sparse, (G·(m + 1), p + 1)) from each group's compact columns (and q) to the full
        columns (and q): the full reduced block is Σ_g M_gᵀ Gc_g M_g. A compact column of an array part
        is its full column; the column (s, i) of a ``PassColumns`` part, in group g, is the pass π at
        place s of g, and enters the full column (b, i) with weight ``expand``[π, b]."""
        import scipy.sparse as sps

        P = group_of_pass.size
        pass_at = np.full((n_groups, smax), -1)
        pass_at[group_of_pass, slot_of_pass] = np.arange(P)
        mq = 1 + sum(smax * part.values.shape[-1] if isinstance(part, PassColumns) else k for part, k in zip(parts, widths))
        goff = np.arange(n_groups)[:, None] * mq
        R_, C_, V_ = [], [], []
        m = start = 0
        for part, k in zip(parts, widths):
            if not isinstance(part, PassColumns):
                R_.append((goff + m + np.arange(k)).ravel())
                C_.append(np.tile(start + np.arange(k), n_groups))
                V_.append(np.ones(n_groups * k))
                m += k
            else:
                w = part.values.shape[-1]
                g, s_, b, i = np.meshgrid(
                    np.arange(n_groups), np.arange(smax), np.arange(part.expand.shape[1]), np.arange(w), indexing="ij"
                )
                pi = pass_at[g, s_]
                wt = np.where(pi >= 0, part.expand[np.maximum(pi, 0), b], 0.0)
                keep = wt != 0
                R_.append((g * mq + m + s_ * w + i)[keep])
                C_.append((start + b * w + i)[keep])
                V_.append(wt[keep])
                m += w * smax
            start += k
        R_.append(goff.ravel() + m)
        C_.append(np.full(n_groups, start))
        V_.append(np.ones(n_groups))
        return sps.csr_matrix((np.concatenate(V_), (np.concatenate(R_), np.concatenate(C_))), shape=(n_groups * mq, start + 1))

    @staticmethod
    def column_scales(c: Candidate, cs) -> np.ndarray:
        """The scale of each of candidate ``c``'s parameters, by which its columns ``cs`` (an ``EffectColumns``)
        are multiplied: the candidate's own ``scales``, else the columns' ``scales``, else ones."""
        if c.scales is not None:
            return np.asarray(c.scales, float)
        if cs.scales is not None:
            return np.asarray(cs.scales, float)
        return np.ones(cs.jacobian.shape[-1])

    # ------------------------------------------------------------------ displays
    def split_residuals(self, residual_xy_m: np.ndarray, G: np.ndarray):
        """Each image's common rotation ω_n (N, 3) arcsec and the field part (n_obs, 2) m.

        ω_n is the least-squares rotation of image n's residuals (Algorithm 3 Jacobian); the field
        part is what remains. Per-image star-tracker and GNSS errors live almost entirely in ω_n,
        so effects that distort the field become visible in the field part even when hidden
        under per-image errors ten times larger.
        """
        N = self.obs.n_images
        r = np.asarray(residual_xy_m, float)
        G = np.asarray(G, float)
        # per image the 3 × 3 normal equations of its rotation (all images at once)
        AtA = np.zeros((N, 3, 3))
        Atb = np.zeros((N, 3))
        np.add.at(AtA, self.img, np.einsum("oki,okj->oij", G, G))
        np.add.at(Atb, self.img, np.einsum("oki,ok->oi", G, r))
        count = np.bincount(self.img, minlength=N)
        w = np.einsum("nij,nj->ni", np.linalg.pinv(AtA, hermitian=True), Atb)
        w[count < 2] = 0.0
        omega = np.where((count >= 2)[:, None], w / ARCSEC, np.nan)
        field = r - np.einsum("oki,oi->ok", G, w[self.img])
        return omega, field

    def theta_truth_rad(self):
        t = self.obs.truth
        if t is not None and "theta_rad" in t:
            return np.asarray(t["theta_rad"], float).reshape(-1, 3)[0]
        return None


def _pass_groups(st: RowStructure) -> tuple[int, np.ndarray, np.ndarray, int]:
    """The passes in groups that share no target: (G, group of each pass (P,), its place in the group
    (P,), the largest group's size). Passes joined by a target seen in both (any noise model: a
    catalogue error would couple them) or by an attitude-sample table (one group) are one group."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    P, T = st.n_passes, st.n_targets
    if st.has_samples or P == 0:
        return 1, np.zeros(P, np.int64), np.arange(P), max(P, 1)
    graph = coo_matrix((np.ones(st.n_rows), (st.row_pass, P + st.target_index)), shape=(P + T, P + T))
    _, label = connected_components(graph, directed=False)
    _, group = np.unique(label[:P], return_inverse=True)
    group = group.reshape(-1).astype(np.int64)
    G = int(group.max()) + 1
    order = np.lexsort((np.arange(P), group))
    first = np.searchsorted(group[order], np.arange(G))
    slot = np.empty(P, np.int64)
    slot[order] = np.arange(P) - first[group[order]]
    return G, group, slot, int(np.bincount(group).max())


def _rows_of(fit: RowFit, xs: np.ndarray, cs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residual rows of ``fit`` at the coefficients ``xs`` (1, u) with covariance ``cs`` (1, u, u), flat (2K,)
    each: the pixel-level residuals in units of σ, their leverages and the per-image-whitened residuals."""
    e = row_residuals(fit, xs)[0]
    w = row_residuals(fit, xs, per_image_whitened=True)[0]
    h, _ = row_reduced_rows(fit, cs)  # leverage=True: h is an array
    return e.reshape(-1), np.asarray(h, float)[0].reshape(-1), w.reshape(-1)


def _placeholder(P, K: int) -> np.ndarray:
    """A part's shape with no memory (a zero-strided view): what the residual rows keep of a transient part."""
    k = P.k if isinstance(P, PassColumns) else P.shape[-1]
    return np.broadcast_to(np.zeros(1), (K, 2, k))


def _shared_atoms(parts: list, smax: int) -> np.ndarray:
    """The places of the shared columns among a group's compact columns (``CampaignProblem._gram``): every
    column of an array part and the residual q (last), not the per-pass slots of a ``PassColumns`` part."""
    out, m = [], 0
    for P in parts:
        if isinstance(P, PassColumns):
            m += smax * P.values.shape[-1]
        else:
            out.append(m + np.arange(P.shape[-1]))
            m += P.shape[-1]
    out.append(np.array([m]))
    return np.concatenate(out)


def _block_gram(M, blocks: np.ndarray, shared: np.ndarray, size: int | None = None) -> BlockGram:
    """Σ_g M_gᵀ B_g M_g for the groups' blocks ``blocks`` (G, m + 1, m + 1) and the map ``M`` (``_assemble``), as a
    :class:`~boresight.studies.discrepancy.linear.BlockGram`: the shared columns' blocks summed over the groups,
    their coupling to each group's per-pass slots, and those slots' own blocks (the per-pass columns of two groups
    are orthogonal). The shared rows of M are the same in every group (a shared column is its own full column)."""
    import scipy.sparse as sps

    G, mq, _ = blocks.shape
    local = np.setdiff1d(np.arange(mq), shared)
    M = sps.csr_matrix(M)
    Ms = M[shared]  # group 0's rows: every group's shared rows are these
    Ml = M[(np.arange(G)[:, None] * mq + local[None, :]).ravel()]
    return BlockGram(
        blocks[:, shared][:, :, shared].sum(axis=0),
        blocks[:, shared][:, :, local].transpose(1, 0, 2).reshape(shared.size, G * local.size),
        blocks[:, local][:, :, local],
        Ms,
        Ml,
        size,
    )
