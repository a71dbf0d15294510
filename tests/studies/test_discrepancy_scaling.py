"""``boresight.diagnose`` linear in observations on campaigns of single-use ground-control points: the
per-pass columns (the ``pass`` and ``image scale by pass`` probes, a scanned ``alignment_step``) kept
compact through the one GLS when the passes share no target (``CampaignProblem._gram``), equal to the
full columns' route, and the traced peak per observation flat when such a campaign grows ×10
(``docs/benchmarks.md``, "### ``diagnose``")."""

import numpy as np
import pytest
from builders import campaign_as_flown, single_use, tile, traced_peak

from boresight import diagnose
from boresight.studies.discrepancy import campaign as campaign_mod
from boresight.studies.discrepancy.campaign import CampaignProblem, PassColumns
from boresight.studies.discrepancy.candidates import catalogue_candidates


def rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.fixture(scope="module")
def small_single_use():
    """The as-flown campaign's first pass (20 images, 241 observations), every observation its own
    ground-control point, with its noise model."""
    flown, model = campaign_as_flown()
    one = flown.images(np.flatnonzero(flown.pass_index == flown.pass_index[0])).observed_targets()
    return single_use(one), model


def test_compact_per_pass_columns_equal_the_full_columns(small_single_use, monkeypatch):
    """Four passes of single-use targets (the one-pass campaign tiled ×4): every pass its own group, the
    per-pass probes and ``alignment_step``'s scan compact (7 columns in the GLS instead of 25); the Gram
    matrix, its per-row-whitened twin, the data count and the rows (residuals, leverage, innovations) of a
    fit that uses a per-pass probe column equal the full columns' route (one group: no compaction) to
    1e-9 relative."""
    obs, model = small_single_use
    obs = tile(obs, 4)
    prob = CampaignProblem(obs, model, catalogue_candidates(None))
    assert prob._groups[0] == 4 and prob._groups[3] == 1
    assert isinstance(prob.probes["pass"], PassColumns)
    names = list(prob.candidates)
    theta = np.full(3, 2e-5)
    cl = prob.linearize(theta, {}, names, probes=True)
    monkeypatch.setattr(
        campaign_mod, "_pass_groups", lambda st: (1, np.zeros(st.n_passes, np.int64), np.arange(st.n_passes), st.n_passes)
    )
    full = CampaignProblem(obs, model, catalogue_candidates(None))
    cf = full.linearize(theta, {}, names, probes=True)
    a, b = cl.lin, cf.lin
    assert a.p == b.p and a.n_data == b.n_data
    assert rel(a.gram, b.gram) < 1e-9 and rel(a.raw, b.raw) < 1e-9
    x = np.zeros(a.p)
    j = int(
        np.asarray(cl.probes["pass"].T.argmax(axis=0)).reshape(-1)[4]
    )  # the second pass's second probe column, with a coefficient
    x[[0, 1, 2, j]] = [1.0, -2.0, 0.5, 0.7]
    use = np.array([0, 1, 2, j])
    cov = np.diag([1e-3, 1e-3, 1e-3, 2e-3])
    for u, v in zip(a.rows(x, cov, use), b.rows(x, cov, use)):
        assert rel(u, v) < 1e-9


def test_compact_gls_by_chunks_of_passes_equals_one_gls(small_single_use, monkeypatch):
    """The compact GLS run on chunks of groups (``campaign.GROUP_CHUNK_ROWS``: here about 3 passes of 241 rows a
    chunk, 4 chunks for the ×10 tiling) gives the Gram, its per-row-whitened twin and the data count of the one
    GLS over every row to 1e-9 relative: the groups share no nuisance, so each chunk's GLS is its groups' own.
    So do the full columns' GLS of θ and a named effect (no per-pass column: a Gauss–Newton step's) and the residual
    rows (residuals, leverage, innovations) of a fit with a named effect and a per-pass probe column, rebuilt from θ
    and the named value and run on the same chunks."""
    obs, model = small_single_use
    obs = tile(obs, 10)
    theta = np.full(3, 2e-5)
    whole = CampaignProblem(obs, model, catalogue_candidates(None))
    names = list(whole.candidates)
    one = whole.linearize(theta, {}, names, probes=True).lin
    named = {"landmark_datum_shift": np.array([0.5, -0.3])}
    cl1 = whole.linearize(theta, named, [], probes=True)
    j = int(np.asarray(cl1.probes["pass"].T.argmax(axis=0)).reshape(-1)[4])  # the second pass's second probe column
    use = np.array([0, 1, 2, 3, 4, j])
    x = np.zeros(cl1.lin.p)
    x[use] = [1.0, -2.0, 0.5, 0.2, -0.1, 0.7]
    cov = np.diag([1e-3, 1e-3, 1e-3, 5e-4, 5e-4, 2e-3])
    rows_one = cl1.lin.rows(x, cov, use)
    base_one = whole.linearize(theta, named).lin
    monkeypatch.setattr(campaign_mod, "GROUP_CHUNK_ROWS", 730)
    monkeypatch.setattr(campaign_mod, "FULL_GLS_MAX_ROWS", 0)  # the full columns' GLS on the chunks too
    prob = CampaignProblem(obs, model, catalogue_candidates(None))
    calls = []
    fit_rows = campaign_mod.fit_rows
    monkeypatch.setattr(campaign_mod, "fit_rows", lambda o, *a, **k: calls.append(o.n_observations) or fit_rows(o, *a, **k))
    chunked = prob.linearize(theta, {}, names, probes=True).lin
    assert len(calls) == 4 and sum(calls) == obs.n_observations, calls
    assert chunked.p == one.p and chunked.n_data == one.n_data
    assert rel(chunked.gram, one.gram) < 1e-9 and rel(chunked.raw, one.raw) < 1e-9
    calls.clear()
    base = prob.linearize(theta, named).lin  # no per-pass column: the full columns' GLS, on the chunks too
    assert len(calls) == 4, calls
    assert base.n_data == base_one.n_data
    assert rel(base.gram, base_one.gram) < 1e-9 and rel(base.raw, base_one.raw) < 1e-9
    calls.clear()
    rows_chunked = prob.linearize(theta, named, [], probes=True).lin.rows(x, cov, use)
    assert len(calls) == 4 + 4, calls  # the linearisation's chunks, then the rows' own
    for u, v in zip(rows_chunked, rows_one):
        assert rel(u, v) < 1e-9


def test_diagnose_memory_is_flat_per_observation(small_single_use):
    """The one-pass single-use campaign (20 images, 241 observations) and the same tiled ×10 (10 passes,
    2 410 observations): before the per-pass columns stayed compact the GLS carried 3 + 1 columns per pass
    and 3 per gap between passes, so its K × p blocks grew as K × passes (≈ 60 columns at ×1, ≈ 127 at
    ×10), and S⁻¹ formed whole for the leverage as (images·6)². Measured 2026-11-27 (this tree): 13.3 kB
    per observation at ×1, 12.4 kB at ×10; the code before (47d1edb) 14.6 → 28.2 kB, ×1.93: this test
    fails there. Bound: ×10 / ×1 ≤ 1.5 and under 40 kB per observation."""
    one, model = small_single_use
    ten = tile(one, 10)
    diagnose(one, model)  # imports and caches outside the measurement
    per = [traced_peak(lambda o=o: diagnose(o, model)) / o.n_observations for o in (one, ten)]
    assert per[1] <= 1.5 * per[0], (per, "bytes per observation: diagnose's memory grows faster than its rows")
    assert per[1] < 40e3, per


def test_structured_probe_tests_equal_the_dense_route(monkeypatch):
    """The per-pass probes tested through their block structure (``linear.lr_test``: Haynsworth's count of the
    directions the base absorbs, subspace iteration for them, Woodbury solves on the rest — no k × k
    eigen-decomposition) give ``extend``'s rank and Δχ² to 1e-9 (relative, or of one unit of χ² for a Δχ² below
    one), on the as-flown campaign's single-use twin tiled ×2 (12 passes: the ``pass`` probe 36 columns in 12
    blocks, 3 of them absorbed by θ; ``image scale by pass`` 12 blocks of one) and on every other probe (one
    block: the same algebra). Measured on the ×10 campaign of ``docs/benchmarks.md``: 2e-14 relative for the
    180-column ``pass`` probe. The whole residual battery equals the dense route's with the structured route
    taken for every probe."""
    from boresight.studies.discrepancy import linear
    from boresight.studies.discrepancy.state import State
    from boresight.studies.discrepancy.structure import residual_tests

    flown, model = campaign_as_flown()
    prob = CampaignProblem(tile(single_use(flown), 2), model, catalogue_candidates(None))
    st = State(prob, np.zeros(3), {}, list(prob.candidates))
    checked = 0
    for name, P in st.cl.probes.items():
        ext = linear.extend(st.base, P)
        got = linear._structured_lr(st.base, P, linear.SEPARABILITY_RHO)
        assert got is not None, name
        assert got[0] == ext.rank, (name, got, ext.rank)
        assert abs(got[1] - ext.delta_chi2) <= 1e-9 * max(abs(ext.delta_chi2), 1.0), (name, got, ext.delta_chi2)
        checked += name in ("pass", "image scale by pass")
    assert checked == 2
    assert linear.extend(st.base, st.cl.probes["pass"]).rank == st.cl.probes["pass"].k - 3
    dense = residual_tests(st.base, st.cl.probes, 0.01)
    monkeypatch.setattr(linear, "STRUCTURED_MIN_COLUMNS", 0)
    structured = residual_tests(st.base, st.cl.probes, 0.01)
    assert [t.name for t in structured] == [t.name for t in dense]
    for a, b in zip(structured, dense):
        assert a.dof == b.dof and a.rejected == b.rejected
        assert abs(a.statistic - b.statistic) <= 1e-9 * max(abs(b.statistic), 1.0), (a, b)
