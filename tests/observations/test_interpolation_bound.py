"""The orbit interpolation error bound (interpolate.lagrange / hermite, printed by `boresight ingest`)
against a dynamical truth: a J2 propagation between the samples of sparse and dense ephemerides of
real-shaped orbits, written as OEMs and read back through `read_oem` (so the bound includes the
file's writing precision), at many random image times.

Pass criteria (issue 21): true error ≤ bound at ≥ 99 % of the image times, and bound ≤ 10 × true
error at ≥ 99 % of the accepted times (bound ≤ 0.05 m). The truth is a DOP853 integration with
rtol 3e-14; its own consistency between sample and image times is ~2e-8 m (measured: Lagrange 11 on
5 s samples of it reproduces it to 1.7e-8 m at most), so "true error ≤ bound" is tested as
≤ bound + 2e-8 m and the 10× ratio only where the true error exceeds 100× that (2e-6 m)."""

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from scipy.integrate import solve_ivp

from boresight.observations import flight as bio

MU, J2, RE = 3.986004418e14, 1.08262668e-3, 6378137.0
TRUTH_FLOOR_M = 2e-8
T0 = Time("2024-03-01T00:00:00", scale="utc")


def _f(t, y):
    r = y[:3]
    n = np.linalg.norm(r)
    k = 1.5 * J2 * MU * RE**2 / n**5
    zz = 5 * r[2] ** 2 / n**2
    return np.r_[y[3:], -MU * r / n**3 + k * np.array([r[0] * (zz - 1), r[1] * (zz - 1), r[2] * (zz - 3)])]


def _j2(alt_m, e, inc_deg, ts):
    a = RE + alt_m
    rp = a * (1 - e)
    v = np.sqrt(MU * (1 + e) / rp)
    inc = np.radians(inc_deg)
    y0 = np.array([rp, 0, 0, 0, v * np.cos(inc), v * np.sin(inc)])
    return solve_ivp(_f, (0, ts[-1]), y0, method="DOP853", rtol=3e-14, atol=1e-9, t_eval=ts).y.T


# (orbit, sample step s, INTERPOLATION, degree): sparse (60–300 s) and dense (10 s) ephemerides
CASES = [
    ("CBERS-like 778 km SSO", (778e3, 0.0012, 98.5), 60.0, "LAGRANGE", 7),
    ("CBERS-like 778 km SSO", (778e3, 0.0012, 98.5), 120.0, "LAGRANGE", 7),
    ("ISS-like 420 km", (420e3, 0.0005, 51.6), 60.0, "LAGRANGE", 5),
    ("ISS-like 420 km", (420e3, 0.0005, 51.6), 300.0, "HERMITE", 9),
    ("CBERS-like 778 km SSO", (778e3, 0.0012, 98.5), 10.0, "LAGRANGE", 7),
    ("ISS-like 420 km", (420e3, 0.0005, 51.6), 10.0, "HERMITE", 5),
]


@pytest.mark.parametrize("name, orbit, step, method, degree", CASES, ids=[f"{c[0][:4]}-{c[2]:g}s-{c[3][0]}{c[4]}" for c in CASES])
def test_bound_covers_the_j2_truth_and_is_not_loose(tmp_path, name, orbit, step, method, degree):
    rng = np.random.default_rng(21)
    nodes = np.arange(0.0, 5400.0 + step / 2, step)
    q = np.sort(rng.uniform(nodes[0], nodes[-1], 400))
    allt = np.union1d(nodes, q)
    Y = _j2(*orbit, allt)
    yn, yq = Y[np.searchsorted(allt, nodes)], Y[np.searchsorted(allt, q)]
    p = bio.write_oem(tmp_path / "o.oem", T0 + nodes * u.s, yn[:, :3], yn[:, 3:], interpolation=method, degree=degree)
    track = bio.read_oem(p)
    r, _, bound = track.at(T0 + q * u.s, max_error_m=np.inf)
    true = np.linalg.norm(r - yq[:, :3], axis=-1)
    covered = np.mean(true <= bound + TRUTH_FLOOR_M)
    assert covered >= 0.99, (name, step, covered)
    sel = (bound <= bio.orbit.MAX_POSITION_ERROR_M) & (true > 100 * TRUTH_FLOOR_M)
    if sel.any():
        assert np.mean(bound[sel] <= 10 * true[sel]) >= 0.99, (name, step, np.quantile(bound[sel] / true[sel], [0.5, 0.99]))
        # the figure docs/tutorial-flight-data.md quotes: the bound is 1.8–2.3 × the true error (measured 1.86–2.26)
        ratio = bound[sel] / true[sel]
        assert 1.8 <= ratio.min() and ratio.max() <= 2.3, (name, step, ratio.min(), ratio.max())
