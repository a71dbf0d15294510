"""The small campaigns of the GLS tests and their references, shared by ``tests/core/test_campaign_gls.py``,
``tests/core/test_row_gls.py`` and ``tests/core/test_attitude_samples.py``: a few passes of campaign-6pass
on the images × landmarks grid (``small_campaign``), the error modes every comparison runs over
(``MODES``), the full-Σ GLS reference (``full_gls``) and the relative difference the 1e-9 figures are
measured in (``rel``); and the one linearised case of the dense-GLS comparisons (``linearised_campaign``,
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
