"""The measurement model and the error Jacobians on rows (issue 27) against their dense layout.

The library takes rows only (a grid's values are the row values scattered: ``tests/oracles.py:on_grid``),
so the check that matters is against an independent dense computation: the old per-image formulas, written here once more as the oracle
(an images × landmarks evaluation with the boresight put where nothing is observed), to 1e-13
relative (round-off of a different summation order).
"""

import numpy as np
from builders import campaign_6pass_doc, simulate_with_model
from oracles import dense_grid, on_grid

import orbits
from boresight.core.disturbances import error_jacobians
from boresight.core.gls.structure import error_columns
from boresight.core.measurement import (
    linearize,
    linearize_rows,
    predict,
    predicted_camera_vectors,
    projection_jacobian,
    residuals,
)
from orbits.camera import project
from orbits.rotations import misalignment_dcm, right_jacobian, skew


def _obs():
    obs, model = simulate_with_model(orbits.scenario_from_dict(campaign_6pass_doc(3, 4)), 3, 2)
    obs = dense_grid(obs)  # the oracle is the images × landmarks grid (tests/oracles.py)
    assert (~obs.mask).any()
    return obs, model


def rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def test_linearize_rows_equal_the_dense_images_by_landmarks_formula():
    obs, _ = _obs()
    th = np.array([[2e-4, -1e-4, 3e-4], [0.0, 1e-5, -2e-5]])
    C = misalignment_dcm(th)[:, None] @ obs.nominal_camera_attitude()
    s = np.einsum("rnij,rnmj->rnmi", C, obs.landmarks_i_m() - obs.r_sc_i_m[:, :, None, :])
    s = np.where(obs.mask[None, :, :, None], s, [0.0, 0.0, -1.0])
    q_ref = np.where(obs.mask[None, :, :, None], obs.xy_m - project(s, obs.focal_length_m), 0.0)
    G_ref = projection_jacobian(s, obs.focal_length_m) @ skew(s) @ right_jacobian(th)[:, None, None]
    img, tgt = np.nonzero(obs.mask)
    rows = obs.to_rows()
    Gr, qr = linearize_rows(rows, th, (img, tgt), obs.xy_m[:, img, tgt])
    assert Gr.shape == (2, img.size, 2, 3) and qr.shape == (2, img.size, 2)
    assert rel(Gr, G_ref[:, img, tgt]) < 1e-13 and rel(qr, q_ref[:, img, tgt]) < 1e-13
    G, q = linearize(rows, th)
    assert rel(G, G_ref[:, img, tgt]) < 1e-13 and rel(q, q_ref[:, img, tgt]) < 1e-13
    assert rel(on_grid(residuals, obs, th), q_ref) < 1e-13
    xy_ref = np.where(obs.mask[None, :, :, None], project(s, obs.focal_length_m), 0.0)
    assert rel(on_grid(predict, obs, th), xy_ref) < 1e-13
    assert rel(predicted_camera_vectors(rows, th, (img, tgt)), predicted_camera_vectors(rows, th)) < 1e-13


def test_error_jacobians_and_columns_on_rows():
    obs, model = _obs()
    th = np.full((2, 3), 5e-5)
    img, tgt = np.nonzero(obs.mask)
    rows = obs.to_rows()
    J = error_jacobians(rows, th, rows=(img, tgt))
    Jd = on_grid(error_jacobians, obs, th)
    # the oracle: −P(C_SK e_k × s), P C_IK, −P C_IK C_GI per image × landmark
    M = misalignment_dcm(th)
    C_IK = M[:, None] @ obs.nominal_camera_attitude()
    C_SK = M @ obs.C_SK_nominal
    s = np.einsum("rnij,rnmj->rnmi", C_IK, obs.landmarks_i_m() - obs.r_sc_i_m[:, :, None, :])
    P = projection_jacobian(s, obs.focal_length_m)
    st = np.stack([-np.einsum("rnmij,rnmj->rnmi", P, np.cross(C_SK[:, None, None, :, k], s)) for k in range(3)], -1)
    ref = {"star_tracker": st, "gnss": P @ C_IK[:, :, None], "catalogue": -(P @ C_IK[:, :, None]) @ obs.C_GI[None, :, None]}
    for k, v in ref.items():
        assert J[k].shape == (2, img.size, 2, 3)
        assert rel(J[k], v[:, img, tgt]) < 1e-13, k
        assert rel(Jd[k][:, img, tgt], v[:, img, tgt]) < 1e-13 and np.all(Jd[k][:, ~obs.mask] == 0)
    L = np.broadcast_to(np.array([[1.0, 0.2], [0.0, 0.9]]), (2, img.size, 2, 2))
    for Zr, Zd in zip(error_columns(rows, th, model, L, rows=(img, tgt)), on_grid(error_columns, obs, th, model)):
        if Zd is not None:
            assert rel(Zr, L @ Zd[:, img, tgt]) < 1e-13
