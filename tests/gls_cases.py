"""The small campaigns of the GLS tests and their references, shared by ``tests/core/test_campaign_gls.py``,
``tests/core/test_row_gls.py`` and ``tests/core/test_attitude_samples.py``: a few passes of campaign-6pass
on the images × landmarks grid (``small_campaign``), the error modes every comparison runs over
(``MODES``), the full-Σ GLS reference (``full_gls``) and the relative difference the 1e-9 figures are
measured in (``rel``); random lines on an attitude-sample table (``sample_lines``) and their dense nuisance columns
(``sample_Z``: ``tests/core/test_attitude_samples.py``, ``tests/core/test_tracker_gauss_markov.py``); and the one linearised case of the dense-GLS comparisons (``linearised_campaign``,
over ``EACH_DENSE_MODE`` × ``EACH_LINEARISER``).
"""

import dataclasses

import numpy as np
import pytest
import scipy.linalg as sl
from builders import campaign_6pass_doc, simulate_with_model
from oracles import dense_grid, on_grid

import orbits
from boresight.core.algorithms import ground_plane, image_plane, unit_vector
from boresight.core.crlb import full_residual_covariance
from boresight.core.gls.rows import RowColumns, RowStructure


def small_campaign(n_pass=3, n_img=4, seed=0, shared=False, runs=1):
    """A few passes of campaign-6pass with fewer images (nadir passes mask landmarks)."""
    d = campaign_6pass_doc(n_pass, n_img)
    if shared:  # pass 1 revisits pass 0's site and landmark field (descending)
        d["passes"][1] = dict(d["passes"][0], direction="descending")
    obs, model = simulate_with_model(orbits.scenario_from_dict(d), seed, runs)
    obs = dense_grid(obs)  # these tests index the images × landmarks grid (tests/oracles.py)
    return (merge_landmarks(obs) if shared else obs), model


def merge_landmarks(obs):
    """Map pass 1's landmarks (P1Mj) onto pass 0's (P0Mj): the same physical landmarks."""
    ids = list(obs.landmark_ids)
    keep = [k for k, i in enumerate(ids) if not i.startswith("P1M")]
    xy = obs.xy_m.copy()
    mask = obs.mask.copy()
    for k, i in enumerate(ids):
        if i.startswith("P1M"):
            j = ids.index("P0M" + i[3:])
            rows = mask[:, k]
            xy[:, rows, j] = xy[:, rows, k]
            mask[rows, j] = True
    return dataclasses.replace(
        obs,
        landmark_ids=obs.landmark_ids[keep],
        landmark_g_m=obs.landmark_g_m[:, keep],
        xy_m=xy[:, :, keep],
        mask=mask[:, keep],
        truth=None,
    )


def full_gls(obs, theta, G, q, model):
    """GLS with the dense covariance of every residual of the run (image plane only): G (R, N, M, 2, n)
    and q on the grid, gathered at its rows (the order of ``crlb.full_residual_covariance``)."""
    obs = dense_grid(obs)
    img, tgt = np.nonzero(obs.mask)
    S = full_residual_covariance(obs.to_rows(), theta, model)
    out = []
    for r in range(obs.runs):
        Gg, qq = G[r][img, tgt].reshape(-1, G.shape[-1]), q[r][img, tgt].reshape(-1)
        cf = sl.cho_factor(S[r])
        info = Gg.T @ sl.cho_solve(cf, Gg)
        C = np.linalg.inv(info)
        out.append((C @ (Gg.T @ sl.cho_solve(cf, qq)), C))
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


MODES = [
    dict(),  # campaign-6pass: both modes, catalogue
    dict(star_tracker_mode="per_image", gnss_mode="per_image"),
    dict(star_tracker_mode="per_pass", gnss_mode="per_pass"),
    dict(star_tracker_mode="per_pass", gnss_mode="per_image", sigma_catalogue_m=0.0),
    dict(star_tracker_mode="both", gnss_mode="per_pass", sigma_catalogue_m=5.0),
    dict(sigma_star_tracker_rad=(0.0, 0.0, 0.0), sigma_gnss_m=0.0),  # pixel + catalogue only
    dict(sigma_star_tracker_rad=(0.0, 0.0, 0.0), sigma_gnss_m=0.0, sigma_catalogue_m=0.0),  # pixel only
]


#: the error modes of the dense-GLS comparisons (both, per image, mixed, catalogue)
EACH_DENSE_MODE = pytest.mark.parametrize(
    "kw", [MODES[0], MODES[1], MODES[3], MODES[5]], ids=["both", "per_image", "mixed", "catalogue"]
)
#: the three linearisers (the image plane's residuals are the pixels; the others' through their residual maps)
EACH_LINEARISER = pytest.mark.parametrize(
    "alg", [image_plane, ground_plane, unit_vector], ids=["image_plane", "ground_plane", "unit_vector"]
)


def linearised_campaign(alg, kw):
    """The dense-GLS comparisons' case: ``small_campaign(n_img=3, shared=True, seed=3)`` with the error mode
    ``kw``, linearised by ``alg`` at θ = 0 on its grid. Returns (obs, model, θ, G, q, L): L is the
    residual map, None for the image plane."""
    obs, model = small_campaign(n_img=3, shared=True, seed=3)
    model = dataclasses.replace(model, **kw)
    th = np.zeros((1, 3))
    G, q = on_grid(alg.linearize, obs, th)
    L = None if alg is image_plane else on_grid(alg.residual_map, obs, th)
    return obs, model, th, G, q, L


def sample_lines(seed=0, n_images=40, n_samples=9, n_targets=30, n=4, na=3, nb=2, runs=2):
    """Lines (images) along a strip with 1-3 rows each; targets seen once or by 2-3 lines; two samples per line."""
    rng = np.random.default_rng(seed)
    img, tgt = [], []
    for i in range(n_images):
        for t in sorted(rng.choice(n_targets, size=rng.integers(1, 4), replace=False)):
            img.append(i)
            tgt.append(t)
    img, tgt = np.array(img), np.array(tgt)
    f = np.linspace(0.0, n_samples - 1.0, n_images)
    k = np.minimum(np.floor(f).astype(int), n_samples - 2)
    frac = f - k
    st = RowStructure(
        img,
        tgt,
        np.arange(n_images) * 2 // n_images,
        n_targets,
        sample_index=np.stack([k, k + 1], axis=1),
        sample_weight=np.stack([1 - frac, frac], axis=1),
        n_samples=n_samples,
    )
    K = img.size
    cols = RowColumns(
        X=rng.normal(size=(runs, K, 2, n)),
        q=rng.normal(size=(runs, K, 2)),
        A=0.8 * rng.normal(size=(runs, K, 2, na)),
        B=0.3 * rng.normal(size=(runs, K, 2, nb)),
        C=0.6 * rng.normal(size=(runs, K, 2, 3)),
    )
    return st, cols


def sample_Z(st, cols, r, with_b=True, with_c=True):
    """The oracle's (2K, S·na + P·nb + T·3) nuisance columns of run r."""
    K = st.n_rows
    na, nb = cols.A.shape[-1], cols.B.shape[-1]
    S, P, T = st.n_samples, st.n_passes, st.n_targets
    Z = np.zeros((K, 2, S * na + P * nb + T * 3))
    for k in range(K):
        n = st.image_index[k]
        for i in range(2):
            s = st.sample_index[n, i]
            Z[k, :, s * na : (s + 1) * na] += st.sample_weight[n, i] * cols.A[r, k]
        if with_b:
            p = st.pass_of_image[n]
            Z[k, :, S * na + p * nb : S * na + (p + 1) * nb] = cols.B[r, k]
        if with_c:
            t = st.target_index[k]
            Z[k, :, S * na + P * nb + 3 * t : S * na + P * nb + 3 * t + 3] = cols.C[r, k]
    return Z.reshape(2 * K, -1)
