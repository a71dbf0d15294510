"""``boresight.estimate`` on the row model: no images × targets array anywhere in the estimate path,
and a tiled campaign gives the single one's θ with σ / √K (docs/architecture.md, "The row model")."""

import numpy as np
import pytest
from builders import campaign_as_flown, single_use, tile, traced_peak

from boresight import estimate


@pytest.fixture(scope="module")
def single_use_sets():
    """The as-flown campaign's observations, each its own ground-control point (120 images, 1 310
    targets), and the same tiled ×10 (1 200 images, 13 100 targets): row sets, with the noise model."""
    flown, model = campaign_as_flown()
    one = single_use(flown)
    return one, tile(one, 10), model


CASES = [
    dict(algorithm="image_plane", weighting="gls"),
    dict(algorithm="ground_plane", weighting="diagonal"),
    dict(algorithm="unit_vector", weighting="gls", loss="huber"),
    dict(algorithm="image_plane", weighting="unit", effects=["focal_scale"]),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: "-".join(str(v) if isinstance(v, str) else v[0] for v in c.values()))
def test_estimate_memory_is_flat_per_observation(single_use_sets, case):
    """Tiling a single-use campaign ×10 (10× images AND 10× targets) multiplies an images × targets
    array by 100, i.e. its share per observation by 10; on rows the estimate's traced peak per
    observation stays flat. Measured 2026-11-27, the four cases: 1.6 to 2.1 kB per observation at
    ×1 and at ×10, ×10 / ×1 = 0.98 to 0.99 (the images × landmarks path it replaces held 400 B per
    image × landmark cell: 5.9 GiB at ×10, refused by the memory budget). Bound: ×10 / ×1 ≤ 1.5, and under 10 kB per
    observation."""
    one, ten, model = single_use_sets
    run = lambda obs: estimate(obs, model=model, **case)  # noqa: E731
    run(one)  # imports and caches outside the measurement
    per = [traced_peak(lambda o=o: run(o)) / o.n_observations for o in (one, ten)]
    assert per[1] <= 1.5 * per[0], (per, "bytes per observation: an images × targets array is back in estimate")
    assert per[1] < 10e3, per


def test_a_tiled_campaign_gives_the_same_theta_and_sigma_over_root_k(single_use_sets):
    """K copies of a campaign (new images, passes and targets; the same values) are K independent
        repetitions of the same data: the GLS normal equations are K × the single ones, so θ̂ is the
        same and σ is σ₁/√K. Only round-off differs (sums over 10× the rows, another elimination order
        of the reduced system): measured 2026-11-27 1.4e-12 of σ for θ, 1e-15 relative for σ√K, 1.2e-12
    of the largest residual for the residuals.
        Tolerance 1e-9 (of σ for θ, relative for σ): a wrong weighting of the copies (e.g. a shared
        nuisance across them) moves σ by O(1)."""
    one, ten, model = single_use_sets
    e1 = estimate(one, model=model, weighting="gls")
    e10 = estimate(ten, model=model, weighting="gls")
    s1 = e1.sigma.to_value("arcsec")
    assert np.max(np.abs(e10.theta.to_value("arcsec") - e1.theta.to_value("arcsec")) / s1) < 1e-9
    assert np.max(np.abs(e10.sigma.to_value("arcsec") * np.sqrt(10) / s1 - 1)) < 1e-9
    assert e10.residuals.shape == (ten.n_observations, 2)
    assert np.max(np.abs(e10.residuals - np.tile(e1.residuals, (10, 1)))) < 1e-9 * np.max(np.abs(e1.residuals))
