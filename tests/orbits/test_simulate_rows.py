"""The simulator on rows (issue 27): ``orbits.observe``/``draw_errors`` hold no images × targets
array — memory linear in observations when targets differ from image to image — and the pixel
noise keeps the stream every seed gave before the row model (``orbits.measurements``, "Pixel-noise
draw order")."""

import gc
import tracemalloc

import numpy as np
import pytest
from tiled_simulation import simulate_arrays, tile_arrays

import orbits
from orbits import measurements
from orbits.measurements import draw_errors, observe
from orbits.sensors import PixelNoise

CAMPAIGN = "scenarios/campaign-6pass.toml"


@pytest.fixture(scope="module")
def arrays():
    return orbits.campaign_arrays(orbits.load_scenario(CAMPAIGN))


def _peak_per_observation(a, runs, rows=True):
    gc.collect()
    tracemalloc.start()
    try:
        m = simulate_arrays(a, runs, rows)
        return tracemalloc.get_traced_memory()[1] / m.n_observations
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("single_use", [True, False], ids=["single-use targets", "pass landmarks, rows found"])
def test_simulator_memory_is_flat_per_observation(arrays, single_use):
    """Tiling campaign-6pass ×10 (10× images and 10× targets, 1 320 → 13 200 observations)
    multiplies an images × targets array by 100, its share per observation by 10; the simulator on
    rows keeps its traced peak per observation flat. Single-use ground-control points (a target
    per row, the rows given) and the scenario's pass landmarks (the rows found by
    ``visible_rows``, pass by pass, ×1 in the grid's draw order) alike. Measured 2026-11-27 (3 runs):
    575 → 570 B per observation (single-use), 478 → 456 (pass landmarks); the old simulator's
    (R, N, M) grid on the pass-landmark campaign: 4.3 → 42 kB (×9.7). Bound: 1.5."""
    a1 = tile_arrays(arrays, 1, single_use)
    a10 = tile_arrays(arrays, 10, single_use)
    simulate_arrays(a1, 1, rows=single_use)  # imports outside the measurement
    per = [_peak_per_observation(a, 3, rows=single_use) for a in (a1, a10)]
    assert per[1] <= 1.5 * per[0], (per, "bytes per observation: an images × targets array is back")
    assert per[1] < 5e3, per  # and small: < 5 kB per observation of 3 runs


def test_found_rows_are_the_old_mask(arrays):
    """``visible_rows`` (pass by pass, in pieces) finds exactly the cells of the old mask: own pass
    and inside the field at the nominal attitude, in canonical order."""
    sc = orbits.load_scenario(CAMPAIGN)
    C_IE, r, CG, lm = arrays["C_IE"], arrays["r_sc_i_m"], arrays["C_GI"], arrays["landmarks_g_m"]
    s_nom = np.einsum("nij,nmj->nmi", C_IE, np.einsum("nij,mj->nmi", CG, lm) - r[:, None])
    mask = (arrays["landmark_pass"][None] == arrays["pass_index"][:, None]) & sc.camera.visible(s_nom)
    img, tgt = arrays["rows"]
    np.testing.assert_array_equal(np.stack(np.nonzero(mask)), np.stack([img, tgt]))


def test_grid_stream_is_the_old_draw_in_pieces(arrays, monkeypatch):
    """The pixel noise of an incomplete campaign in the grid's order equals the old (R, N, M, 2)
    draw at the rows' cells, whole runs at a time and, with pieces smaller than a run's grid,
    image by image; the rows' order draws K pairs per run."""
    img, tgt = arrays["rows"]
    n, m = arrays["t_s"].size, arrays["landmarks_g_m"].shape[0]

    def noise(**kw):
        e = draw_errors(np.random.default_rng(5), 4, arrays["pass_index"], m, pixel=PixelNoise(3e-6), **kw)
        return e["pixel_noise_m"]

    old = noise(rows=None).reshape(4, n, m, 2)[:, img, tgt]  # every cell drawn: the old grid
    np.testing.assert_array_equal(noise(rows=(img, tgt)), old)
    monkeypatch.setattr(measurements, "_MIN_PIECE", 1000)  # 8 K = 10 560 normals: a few images a piece
    np.testing.assert_array_equal(noise(rows=(img, tgt)), old)
    by_row = noise(rows=(img, tgt), grid_stream=False)
    assert by_row.shape == old.shape and not np.array_equal(by_row, old)


def test_a_complete_set_draws_the_same_stream_either_way():
    """Every target in every image: the rows are the grid, one draw, the same numbers in both orders."""
    a = orbits.campaign_arrays(orbits.load_scenario("scenarios/kiev2012-algorithm1.toml"))
    img, tgt = a["rows"]
    assert img.size == a["t_s"].size * a["landmarks_g_m"].shape[0]
    draws = [
        draw_errors(np.random.default_rng(2), 3, a["pass_index"], 4, rows=a["rows"], grid_stream=g, pixel=PixelNoise(1e-6))
        for g in (True, False)
    ]
    np.testing.assert_array_equal(draws[0]["pixel_noise_m"], draws[1]["pixel_noise_m"])
    grid = draw_errors(np.random.default_rng(2), 3, a["pass_index"], 4, pixel=PixelNoise(1e-6))["pixel_noise_m"]
    np.testing.assert_array_equal(draws[0]["pixel_noise_m"], grid)


def test_pixel_noise_of_the_wrong_rows_is_refused(arrays):
    e = draw_errors(np.random.default_rng(0), 1, arrays["pass_index"], arrays["landmarks_g_m"].shape[0])  # every cell
    with pytest.raises(ValueError, match=r"pixel_noise_m has shape \(1, 15360, 2\), the 1320 rows need"):
        observe(e, **arrays)
