"""An independent, plain-numpy diagnosis of a landmark campaign: the yardstick of ``bench_diagnose``.

    python benchmarks/reference_diagnosis.py [--images N]     # prints what it named and θ
    python benchmarks/reference_diagnosis.py --file FILE.ecsv  # the same on an observation file

The same questions ``boresight.diagnose`` asks, written the direct way an analyst would write them
with numpy and nothing of boresight's statistics: per image, the observed rows are whitened by the
Cholesky factor of the image's covariance (pixel noise and per-image star-tracker/GNSS errors);
the shared errors (per-pass star-tracker/GNSS, catalogue) are dense nuisance columns with a prior
row each, eliminated by one QR factorisation per linearisation point; then a Gauss–Newton GLS fit
of θ (and of the effects named so far), the χ² and structure-probe LR tests of the residuals, the
LR statistic of every catalogue candidate, and naming rounds (best candidate named when p ≤ α/K
and its BIC improves; refit; repeat). The physics — the image-plane model, its Jacobians, the
error Jacobians, the candidates' columns and the probe patterns — is taken from boresight, so both
sides compute the same numbers; only the statistics engine differs.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from orbits.rotations import ARCSEC  # noqa: E402


class Whitened:
    """Whitening and nuisance elimination at one θ (dense nuisance columns, one row per observation)."""

    def __init__(self, obs, model, theta):
        from boresight.core.disturbances import error_jacobians

        self.obs = obs
        self.img, self.lmk = np.asarray(obs.image_index), np.asarray(obs.target_index)
        J = {k: v[0] for k, v in error_jacobians(obs, theta, rows=(self.img, self.lmk)).items()}  # (K, 2, 3)
        st_var = np.asarray(model.sigma_star_tracker_rad, float) ** 2
        per_img = lambda m: m in ("per_image", "both")  # noqa: E731
        per_pass = lambda m: m in ("per_pass", "both")  # noqa: E731
        passes = np.unique(obs.pass_index)
        seen = np.unique(self.lmk)
        where = np.full(obs.n_targets, -1)
        where[seen] = np.arange(seen.size)
        n_u = (
            (3 * passes.size if per_pass(model.star_tracker_mode) else 0)
            + (3 * passes.size if per_pass(model.gnss_mode) else 0)
            + (3 * seen.size if model.sigma_catalogue_m > 0 else 0)
        )
        start = np.searchsorted(self.img, np.arange(obs.n_images + 1))  # image n's rows: start[n]:start[n + 1]
        self.Linv, self.rows, self.obs_rows = [], [], []
        U = np.zeros((2 * self.img.size, n_u))
        r0 = 0
        for n in range(obs.n_images):
            ks = np.arange(start[n], start[n + 1])
            self.obs_rows.append(ks)
            if ks.size == 0:
                self.Linv.append(None)
                self.rows.append(slice(r0, r0))
                continue
            A = J["star_tracker"][ks].reshape(-1, 3)
            B = J["gnss"][ks].reshape(-1, 3)
            D = model.sigma_pixel_m**2 * np.eye(2 * ks.size)
            if per_img(model.star_tracker_mode):
                D += (A * st_var) @ A.T
            if per_img(model.gnss_mode):
                D += model.sigma_gnss_m**2 * B @ B.T
            Li = np.linalg.inv(np.linalg.cholesky(D))
            rows = slice(r0, r0 + 2 * ks.size)
            c = 0
            p = int(np.searchsorted(passes, obs.pass_index[n]))
            if per_pass(model.star_tracker_mode):
                U[rows, c + 3 * p : c + 3 * p + 3] = Li @ (A * np.sqrt(st_var))
                c += 3 * passes.size
            if per_pass(model.gnss_mode):
                U[rows, c + 3 * p : c + 3 * p + 3] = Li @ (B * model.sigma_gnss_m)
                c += 3 * passes.size
            if model.sigma_catalogue_m > 0:
                Cc = J["catalogue"][ks] * model.sigma_catalogue_m  # (m, 2, 3)
                for i, m in enumerate(self.lmk[ks]):
                    blk = np.zeros((2 * ks.size, 3))
                    blk[2 * i : 2 * i + 2] = Cc[i]
                    U[rows, c + 3 * where[m] : c + 3 * where[m] + 3] = Li @ blk
            self.Linv.append(Li)
            self.rows.append(rows)
            r0 += 2 * ks.size
        self.n_data = r0
        # the nuisances with their prior rows [U; E], eliminated by one QR
        self.Q, _ = np.linalg.qr(np.vstack([U, np.eye(n_u)]))

    def rows_of(self, cols):
        """(K, 2, k) → whitened, nuisance-eliminated rows (n_data + n_u, k)."""
        k = cols.shape[-1]
        W = np.zeros((self.Q.shape[0], k))
        for n, Li in enumerate(self.Linv):
            if Li is not None:
                W[self.rows[n]] = Li @ cols[self.obs_rows[n]].reshape(-1, k)
        return W - self.Q @ (self.Q.T @ W)


def _on_rows(obs, a, row_ndim):
    """A candidate's array on the rows (K, 2[, k]) of run 0."""
    a = np.asarray(a, float)
    if a.ndim != row_ndim:
        raise ValueError(f"reference: a candidate's columns must be one row per observation, got {a.shape}")
    return a[0]


def _columns(obs, theta, named, cands):
    from boresight.core.measurement import linearize_rows

    G, q = linearize_rows(obs, theta, (obs.image_index, obs.target_index), obs.xy_m)
    G, q = G[0], q[0]
    blocks = [G]
    for c, p in named:
        cs = c.columns(obs, theta, p)
        q = q - _on_rows(obs, cs.offset, 3)
        blocks.append(_on_rows(obs, cs.jacobian, 4) * _scales(c, cs))
    return np.concatenate(blocks, axis=-1), q


class _AtBoundary:
    """A scanned candidate with its boundary fixed (``columns(obs, θ, p)`` at ``at``)."""

    def __init__(self, candidate, at):
        self.candidate, self.at = candidate, at
        self.name, self.n_params, self.scales, self.extra = candidate.name, candidate.n_params, candidate.scales, {}

    def columns(self, obs, theta, params):
        return self.candidate.columns(obs, theta, params, at=self.at)


def _scales(c, cs):
    s = c.scales if c.scales is not None else cs.scales
    return np.ones(cs.jacobian.shape[-1]) if s is None else np.asarray(s, float)


def fit(obs, model, theta, named, tol=1e-6 * ARCSEC):
    """Gauss–Newton GLS of θ and the named effects (whitened once per state)."""
    wh = Whitened(obs, model, theta)
    named = [(c, np.asarray(p, float)) for c, p in named]
    for _ in range(20):
        X, q = _columns(obs, theta, named, [])
        Xw = wh.rows_of(X)
        zw = wh.rows_of(q[..., None])[:, 0]
        b, *_ = np.linalg.lstsq(Xw, zw, rcond=None)
        theta = theta + b[:3]
        i = 3
        out = []
        for c, p in named:
            k = p.size
            out.append((c, p + b[i : i + k] * _scales(c, c.columns(obs, theta, None))))
            i += k
        named = out
        if np.max(np.abs(b[:3])) < tol:
            break
    X, q = _columns(obs, theta, named, [])
    Xw, zw = wh.rows_of(X), wh.rows_of(q[..., None])[:, 0]
    Qx, _ = np.linalg.qr(Xw)
    r = zw - Qx @ (Qx.T @ zw)
    return theta, named, wh, Qx, r, float(r @ r), wh.n_data - Xw.shape[1]


def lr(wh, Qx, r, cols):
    """Likelihood-ratio Δχ² and rank of adding the columns (K, 2, k) to the fitted model."""
    C = wh.rows_of(cols)
    C = C - Qx @ (Qx.T @ C)
    u, s, _ = np.linalg.svd(C, full_matrices=False)
    keep = s > 1e-8 * max(s.max(), 1e-300)
    g = u[:, keep].T @ r
    return float(g @ g), int(keep.sum())


def reference_diagnosis(obs, model, alpha=0.01, max_steps=4):
    from scipy import stats

    from boresight.studies.discrepancy.campaign import CampaignProblem
    from boresight.studies.discrepancy.candidates import catalogue_candidates

    cands = catalogue_candidates(None)
    probes = CampaignProblem(obs, model, []).probes_rows
    theta = np.zeros(3)
    named, pool, log = [], list(cands), []
    while True:
        theta, named, wh, Qx, r, chi2, dof = fit(obs, model, theta, named)
        tests = {"chi2": float(stats.chi2.sf(chi2, dof))}
        for name, P in probes.items():
            d, k = lr(wh, Qx, r, P)
            tests[name] = float(stats.chi2.sf(d, k)) if k else 1.0
        rows = []
        for c in pool:
            cs = c.columns(obs, theta, None)
            if cs.status != "ok":
                continue
            J, sc = _on_rows(obs, cs.jacobian, 4), _scales(c, cs)
            if not c.extra.get("scan"):
                d, k = lr(wh, Qx, r, J * sc)
                if k:
                    rows.append((float(stats.chi2.sf(d, k)), d, k, c))
                continue
            # a scanned effect (alignment_step): one LR test per boundary, Bonferroni over the scan;
            # the best boundary is then fitted as a fixed-boundary effect
            from boresight.studies.discrepancy.candidates import scan_boundaries

            ats, k0 = scan_boundaries(obs), sc.size
            best = None
            for b, at in enumerate(ats):
                d, k = lr(wh, Qx, r, J[..., b * k0 : (b + 1) * k0] * sc)
                p = min(1.0, float(stats.chi2.sf(d, k)) * ats.size) if k else 1.0
                if k and (best is None or p < best[0]):
                    best = (p, d, k, _AtBoundary(c, float(at)))
            if best is not None:
                rows.append(best)
        log.append((chi2 / dof, tests))
        rows.sort(key=lambda t: t[0])
        if not rows or len(named) >= max_steps:
            break
        p, d, k, c = rows[0]
        if not (p <= alpha / len(rows) and d > k * np.log(wh.n_data)):
            break
        named.append((c, np.zeros(c.n_params)))
        pool.remove(getattr(c, "candidate", c))
    return theta, [c.name for c, _ in named], log


def main(argv=None):
    from bench_diagnose import setup

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=None, help="a campaign of this many images (bench_diagnose.setup)")
    ap.add_argument("--file", help="an observation file (ECSV, with its noise model) instead: bench_estimate's yardstick")
    a = ap.parse_args(argv)
    if a.file:
        from boresight.core.disturbances import DisturbanceModel
        from boresight.observations.model import ObservationSet

        obs = ObservationSet.read(a.file)
        obs, model = obs.run(0) if obs.runs > 1 else obs, DisturbanceModel.from_observations(obs)
    else:
        obs, model = setup(a.images)
    theta, names, log = reference_diagnosis(obs, model)
    print(
        f"reference: named {names}; θ = {np.round(theta / ARCSEC, 3).tolist()} arcsec; χ²/dof {log[0][0]:.3f} → {log[-1][0]:.3f}"
    )


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    main()
