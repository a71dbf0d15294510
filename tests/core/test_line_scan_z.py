"""The largest normalised residuals of a pushbroom fit (``LineScanFit.z``, ``Estimate.whitened_residual_norm`` /
``largest_residuals``): the frame fits' statistic — each detection's residual over its pixel σ once the fit's MAP
tracker-sample, per-pass and catalogue errors given x are removed (``gls.rows.row_residuals``) — on lines.

Tolerances: noise-free, the residuals are at the inverse location's floor (1e-8 line, measured ~1e-7 px), so z over a
1 px σ is below 1e-5 with a factor ≥ 100 to spare. The oracle whitens the same residuals with the dense covariance of
all rows (pixel + nuisances); it differs from the fit's z only by the last Gauss–Newton step (below 1e-4 σ: z moves by
less than 1e-4 of its σ-scale, an absolute 1e-3 covers it tenfold) and by round-off.
"""

import numpy as np
import pytest

from boresight.core.disturbances import DisturbanceModel
from boresight.core.line_scan import LineScanUnknowns, estimate_line_scan, line_scan_rows, pixel_jacobian
from boresight.observations.strip import strip_observations
from orbits.pushbroom import LineScanParameters
from orbits.strip import GcpLayout, StripConfig, TrackerNoise, simulate_strip, strip_geometry, zy3_like_sensor

ARCSEC = np.pi / 180 / 3600
TRUTH = LineScanParameters(theta_rad=np.array([20.0, -35.0, 50.0]) * ARCSEC)
NOISE = {"pixel": {"sigma_m": 0.3 * 7e-6}, "star_tracker": {"sigma_arcsec": [0.3] * 3, "error_mode": "per_image"}}


@pytest.fixture(scope="module")
def geometry():
    return strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=20.0, tracker_mount_rotvec_deg=(10.0, -5.0, 3.0)))


def _model(tracker_arcsec=0.3):
    return DisturbanceModel(
        sigma_pixel_m=0.3 * 7e-6,
        sigma_star_tracker_rad=(tracker_arcsec * ARCSEC,) * 3,
        star_tracker_mode="per_image",
        sigma_gnss_m=5.0,
        gnss_mode="per_pass",
        sigma_catalogue_m=1.0,
    )


def test_noise_free_z_is_at_the_floor(geometry):
    """A noise-free strip: every z below 1e-5 (the least-squares fit and a robust one), through ``estimate`` too (under
    a noise model, as the frame fits, the list is printed: it shows 0.00)."""
    from boresight import estimate

    sim = simulate_strip(geometry, TRUTH, np.random.default_rng(2), GcpLayout(n_gcps=80))
    obs = strip_observations(sim)
    for loss in (None, "huber"):
        fit = estimate_line_scan(obs, LineScanUnknowns(), DisturbanceModel(sigma_pixel_m=7e-6), loss=loss)
        assert fit.z is not None and fit.z.shape == (obs.n_observations,)
        assert np.max(fit.z) < 1e-5, (loss, np.max(fit.z))
    est = estimate(strip_observations(sim, {"pixel": {"sigma_m": 7e-6}}))
    assert np.max(est.whitened_residual_norm) < 1e-5
    assert est.largest_residuals[0][2] < 1e-5 and " 0.00, " in est.largest_residuals_text()


def test_a_detection_moved_20_lines_tops_the_list(geometry):
    """One detection moved by 20 lines (~67 σ at 0.3 px) in a strip with 0.3 px noise and a 0.3″ tracker: the least-
    squares estimate's largest z is that row (z > 20: the fit absorbs part of it; measured 59.5), named by its measured
    line in the text, more than 5 times the next (measured 6.5: a neighbour sharing its tracker samples, whose MAP error
    the outlier pulls); under the Huber loss it is the top again and every other z is below 5 (a 2-D normal: P(z > 5)
    = 4e-6 per row; measured 3.5). The clean strip's top z is below 5 too."""
    from boresight import estimate

    sim = simulate_strip(geometry, TRUTH, np.random.default_rng(3), GcpLayout(n_gcps=150), TrackerNoise(0.3), sigma_pixel=0.3)
    top_clean = estimate(strip_observations(sim, NOISE)).largest_residuals[0][2]
    assert top_clean < 5
    d = 17
    sim.line_measured[d] += 20.0
    dirty = strip_observations(sim, NOISE)
    est = estimate(dirty)
    lines = np.asarray(dirty.line_scan.line)[dirty.image_index]
    row = int(np.flatnonzero(np.abs(lines - sim.line_measured[d]) < 1e-9)[0])
    k, label, z = est.largest_residuals[0]
    assert k == row and z > 20 and f"line {sim.line_measured[d]:.1f}" in label
    assert z > 5 * est.largest_residuals[1][2]
    assert est.largest_residuals_text().startswith(label)
    assert f"largest z     {label}" in est.summary()
    robust = estimate(dirty, loss="huber")
    assert robust.largest_residuals[0][0] == row and robust.largest_residuals[1][2] < 5


def test_z_agrees_with_dense_whitening(geometry):
    """Test oracle (a second route on purpose, not the library's): the rows at the fit's x, whitened by each row's
    pixel covariance (``line_scan_rows``), are whitened again by the dense covariance of all rows, I + D Dᵀ with D every
    nuisance column (tracker samples: each row's per-image column times its two interpolation weights; the per-pass
    GNSS; each target's catalogue), and e = (I + D Dᵀ)⁻¹ q̃ is the residual with the MAP nuisances removed
    (q̃ − D ν̂, ν̂ = Dᵀ (I + D Dᵀ)⁻¹ q̃), so z_k = |e_k|. The fit's z (the sparse elimination, ``row_residuals``) must
    agree to 1e-3 absolute on a small strip (60 points), with a 2″ tracker so the nuisances matter (z changes by
    more than 0.1 when they are not removed)."""
    sim = simulate_strip(geometry, TRUTH, np.random.default_rng(5), GcpLayout(n_gcps=60), TrackerNoise(2.0), sigma_pixel=0.3)
    obs = strip_observations(sim)
    model = _model(2.0)
    unknowns = LineScanUnknowns()
    fit = estimate_line_scan(obs, unknowns, model)
    J = pixel_jacobian(obs, np.zeros(3), unknowns)  # the fit's pixel covariance: at its first iterate (its DECISION)
    st, cols = line_scan_rows(obs, fit.x, unknowns, model, pixel_jac=J)
    K = obs.n_observations
    q = cols.q[0].reshape(2 * K)
    A, B, C = cols.A[0], cols.B[0], cols.C[0]
    na, nb, nc = A.shape[-1], B.shape[-1], C.shape[-1]
    assert na and nb and nc
    S, P, T = st.n_samples, int(st.row_pass.max()) + 1, st.n_targets
    D = np.zeros((K, 2, S * na + P * nb + T * nc))
    for k in range(K):
        for s, w in zip(st.sample_index[k], st.sample_weight[k], strict=True):
            D[k, :, s * na : (s + 1) * na] += w * A[k]
        p = st.row_pass[k]
        D[k, :, S * na + p * nb : S * na + (p + 1) * nb] = B[k]
        t = st.target_index[k]
        D[k, :, S * na + P * nb + t * nc : S * na + P * nb + (t + 1) * nc] = C[k]
    D = D.reshape(2 * K, -1)
    e = np.linalg.solve(np.eye(2 * K) + D @ D.T, q).reshape(K, 2)
    z_oracle = np.linalg.norm(e, axis=-1)
    assert np.max(np.abs(fit.z - z_oracle)) < 1e-3, np.max(np.abs(fit.z - z_oracle))
    assert np.max(np.abs(np.linalg.norm(cols.q[0], axis=-1) - z_oracle)) > 0.1  # the nuisances are removed
