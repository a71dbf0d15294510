"""The Kiev 2012 eq 28 study compiled with numba: the yardstick of ``boresight sensitivity kiev2012-sensitivity``.

    python benchmarks/bench_eq28.py [--runs 45000] [--seed 1]      # the compiled study alone (prints σθ)
    python -m boresight sensitivity kiev2012-sensitivity --no-plots --quiet --out /tmp/eq28   # the study it is the yardstick of

The ratio is of whole processes, start-up included: time both commands from outside (user + system CPU
of the finished process, e.g. ``/usr/bin/time -f %U+%S``), in turn A B A B … over at least 5 pairs, and
quote the median of the pair ratios with its spread (docs/montecarlo.md's performance table).

The same study as boresight's (``boresight.studies.sensitivity.fd_sensitivities``): the one-image,
four-landmark Kiev case, 45 000 runs, each run's θ ~ N(0, 10′²) per axis and its errors drawn once
(star tracker β1-β3, catalogue P, GNSS R, pixel K), then the base case and each source doubled
(common random numbers, 7 cases), each estimated by Gauss-Newton with the three least-squares
algorithms (image plane, ground plane, unit vector; from θ0 = 0, ≥ 2 steps, until the step is below
1e-4″, ≤ 30). Geometry from ``orbits.campaign_arrays`` (as boresight's); draws from numpy (blocks of
1000 runs); simulation, estimation and the streamed sums in one numba-compiled loop (``cache=True``:
the compiled code is reused by later processes; run once to warm the cache before timing).

Prints σθ (x, y, z, arcsec) per algorithm for the base case and the image-plane a_is of each source:
they must agree with boresight's within sampling error (relative SE of σ ≈ 1/√(2n) = 0.33 % at
45 000 runs; the draws differ, so only statistically). numba (BSD-2-Clause) is optional: this file
is a benchmark, never imported by boresight.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from machine import machine_line  # benchmarks/machine.py

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

ARCSEC = np.pi / (180 * 3600)
TOL = 1e-4 * ARCSEC
SOURCES = ("beta1", "beta2", "beta3", "P", "R", "K")


def _geometry():
    import orbits

    sc = orbits.load_scenario(os.path.join(os.path.dirname(__file__), "..", "scenarios", "kiev2012-sensitivity.toml"))
    a = orbits.campaign_arrays(sc)
    C_ES = np.asarray(a["C_ES"], float)
    C_IS = C_ES @ np.asarray(a["C_IE"], float)[0]
    geo = dict(
        C_IS=np.ascontiguousarray(C_IS),
        C_SK=np.ascontiguousarray(C_ES.T),
        C_GI=np.ascontiguousarray(np.asarray(a["C_GI"], float)[0]),
        r=np.ascontiguousarray(np.asarray(a["r_sc_i_m"], float)[0]),
        lm=np.ascontiguousarray(np.asarray(a["landmarks_g_m"], float)),
        F=float(a["camera"].focal_length_m),
    )
    sig = dict(
        theta=sc.theta_sigma0_arcsec * ARCSEC,
        beta=np.asarray(sc.sigma_star_tracker_arcsec, float) * ARCSEC,
        R=float(sc.sigma_gnss_m),
        P=float(sc.sigma_catalogue_m),
        K=float(sc.sigma_pixel_m),
    )
    return geo, sig


try:  # numba is optional (a benchmark's yardstick, never a dependency of boresight)
    from numba import njit
except ImportError:  # pragma: no cover - depends on the environment
    njit = None


def _compile():
    if njit is None:
        raise ImportError("numba")
    return study_block


if njit is not None:

    @njit(cache=True, fastmath=False)
    def rodrigues(v, out):
        """exp(Φ(v)) into out (3, 3)."""
        p2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        if p2 < 1e-8:
            a, b = 1.0 - p2 / 6.0, 0.5 - p2 / 24.0
        else:
            p = np.sqrt(p2)
            a, b = np.sin(p) / p, (1.0 - np.cos(p)) / p2
        x, y, z = v[0], v[1], v[2]
        out[0, 0] = 1.0 + b * (x * x - p2)
        out[1, 1] = 1.0 + b * (y * y - p2)
        out[2, 2] = 1.0 + b * (z * z - p2)
        out[0, 1] = b * x * y - a * z
        out[1, 0] = b * x * y + a * z
        out[0, 2] = b * x * z + a * y
        out[2, 0] = b * x * z - a * y
        out[1, 2] = b * y * z - a * x
        out[2, 1] = b * y * z + a * x

    @njit(cache=True)
    def jr_coeffs(t):
        p2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2]
        if p2 < 1e-8:
            return 0.5 - p2 / 24.0, 1.0 / 6.0 - p2 / 120.0
        p = np.sqrt(p2)
        return (1.0 - np.cos(p)) / p2, (p - np.sin(p)) / (p2 * p)

    @njit(cache=True)
    def times_jr(g, t, out):
        """row g (3,) times J_r(t) = (1 − cφ²)E − bΦ(t) + c t tᵀ."""
        b, c = jr_coeffs(t)
        t0, t1, t2 = t[0], t[1], t[2]
        d = 1.0 - c * (t0 * t0 + t1 * t1 + t2 * t2)
        j00, j11, j22 = d + c * t0 * t0, d + c * t1 * t1, d + c * t2 * t2
        j01, j10 = c * t0 * t1 + b * t2, c * t0 * t1 - b * t2
        j02, j20 = c * t0 * t2 - b * t1, c * t0 * t2 + b * t1
        j12, j21 = c * t1 * t2 + b * t0, c * t1 * t2 - b * t0
        ga, gb, gc = g[0], g[1], g[2]
        out[0] = ga * j00 + gb * j10 + gc * j20
        out[1] = ga * j01 + gb * j11 + gc * j21
        out[2] = ga * j02 + gb * j12 + gc * j22

    @njit(cache=True)
    def solve3(B, y, out):
        """B⁻¹ y for symmetric 3 × 3 B by cofactors (no LAPACK call per step)."""
        c00 = B[1, 1] * B[2, 2] - B[1, 2] * B[1, 2]
        c01 = B[0, 2] * B[1, 2] - B[0, 1] * B[2, 2]
        c02 = B[0, 1] * B[1, 2] - B[0, 2] * B[1, 1]
        c11 = B[0, 0] * B[2, 2] - B[0, 2] * B[0, 2]
        c12 = B[0, 1] * B[0, 2] - B[0, 0] * B[1, 2]
        c22 = B[0, 0] * B[1, 1] - B[0, 1] * B[0, 1]
        det = B[0, 0] * c00 + B[0, 1] * c01 + B[0, 2] * c02
        out[0] = (c00 * y[0] + c01 * y[1] + c02 * y[2]) / det
        out[1] = (c01 * y[0] + c11 * y[1] + c12 * y[2]) / det
        out[2] = (c02 * y[0] + c12 * y[1] + c22 * y[2]) / det

    @njit(cache=True)
    def gauss_newton(alg, s0, sp, nk, Tk, F, M, theta):
        """θ̂ from 0 for algorithm alg (0 image plane, 1 ground plane, 2 unit vector)."""
        theta[:] = 0.0
        R = np.empty((3, 3))
        s = np.empty(3)
        g = np.empty(3)
        gj = np.empty(3)
        step = np.empty(3)
        B = np.empty((3, 3))
        y = np.empty(3)
        mt = np.empty(3)
        prev = np.inf
        for it in range(30):
            B[:] = 0.0
            y[:] = 0.0
            for i in range(3):
                mt[i] = -theta[i]
            for m in range(M):
                if alg == 0:
                    rodrigues(mt, R)  # exp(−Φ(θ)) s0
                    for i in range(3):
                        s[i] = R[i, 0] * s0[m, 0] + R[i, 1] * s0[m, 1] + R[i, 2] * s0[m, 2]
                    px, py = s[0] / s[2], s[1] / s[2]
                    res = (sp[m, 0] + F * px, sp[m, 1] + F * py)
                    rows = ((-F * px * py, F * (1.0 + px * px), -F * py), (-F * (1.0 + py * py), F * px * py, F * px))
                    for k in range(2):
                        g[0], g[1], g[2] = rows[k]
                        times_jr(g, theta, gj)
                        for i in range(3):
                            y[i] += gj[i] * res[k]
                            for j in range(3):
                                B[i, j] += gj[i] * gj[j]
                elif alg == 1:
                    rodrigues(theta, R)  # u = exp(Φ(θ)) s′
                    for i in range(3):
                        s[i] = R[i, 0] * sp[m, 0] + R[i, 1] * sp[m, 1] + R[i, 2] * sp[m, 2]
                    n0, n1, n2 = nk[m, 0], nk[m, 1], nk[m, 2]
                    nu = n0 * s[0] + n1 * s[1] + n2 * s[2]
                    lam = (n0 * s0[m, 0] + n1 * s0[m, 1] + n2 * s0[m, 2]) / nu
                    w0, w1, w2 = s0[m, 0] - lam * s[0], s0[m, 1] - lam * s[1], s0[m, 2] - lam * s[2]
                    cn0, cn1, cn2 = s[1] * n2 - s[2] * n1, s[2] * n0 - s[0] * n2, s[0] * n1 - s[1] * n0
                    for k in range(2):
                        tx, ty, tz = Tk[m, k, 0], Tk[m, k, 1], Tk[m, k, 2]
                        q = tx * w0 + ty * w1 + tz * w2
                        f = (tx * s[0] + ty * s[1] + tz * s[2]) / nu
                        g[0] = lam * ((s[1] * tz - s[2] * ty) - f * cn0)
                        g[1] = lam * ((s[2] * tx - s[0] * tz) - f * cn1)
                        g[2] = lam * ((s[0] * ty - s[1] * tx) - f * cn2)
                        times_jr(g, mt, gj)
                        for i in range(3):
                            y[i] += gj[i] * q
                            for j in range(3):
                                B[i, j] += gj[i] * gj[j]
                else:
                    rodrigues(mt, R)
                    n = np.sqrt(s0[m, 0] ** 2 + s0[m, 1] ** 2 + s0[m, 2] ** 2)
                    for i in range(3):
                        s[i] = (R[i, 0] * s0[m, 0] + R[i, 1] * s0[m, 1] + R[i, 2] * s0[m, 2]) / n
                    ne = np.sqrt(sp[m, 0] ** 2 + sp[m, 1] ** 2 + F * F)
                    e0, e1, e2 = sp[m, 0] / ne, sp[m, 1] / ne, -F / ne
                    a0, a1, a2 = 1.0 - s[0] * s[0], -s[0] * s[1], -s[0] * s[2]
                    na = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
                    t10, t11, t12 = a0 / na, a1 / na, a2 / na
                    t20, t21, t22 = s[1] * t12 - s[2] * t11, s[2] * t10 - s[0] * t12, s[0] * t11 - s[1] * t10
                    d0, d1, d2 = e0 - s[0], e1 - s[1], e2 - s[2]
                    for k in range(2):
                        if k == 0:
                            g[0], g[1], g[2] = -t20, -t21, -t22
                            q = t10 * d0 + t11 * d1 + t12 * d2
                        else:
                            g[0], g[1], g[2] = t10, t11, t12
                            q = t20 * d0 + t21 * d1 + t22 * d2
                        times_jr(g, theta, gj)
                        for i in range(3):
                            y[i] += gj[i] * q
                            for j in range(3):
                                B[i, j] += gj[i] * gj[j]
            solve3(B, y, step)
            theta += step
            sm = max(abs(step[0]), abs(step[1]), abs(step[2]))
            if it >= 1 and (sm <= TOL or (sm * sm <= TOL and sm <= 0.01 * prev)):
                break
            prev = sm

    @njit(cache=True)
    def matvec(A, v, out):
        for i in range(3):
            out[i] = A[i, 0] * v[0] + A[i, 1] * v[1] + A[i, 2] * v[2]

    @njit(cache=True)
    def study_block(th, dl, gn, ct, px, factors, C_IS, C_SK, C_GI, r, lm, F, sums):
        """Simulate and estimate every run of a block for every case; add errors (arcsec) and their
        squares to sums[case, alg, 0 | 1, axis]."""
        M = lm.shape[0]
        Rd = np.empty((3, 3))
        Rt = np.empty((3, 3))
        delta = np.empty(3)
        theta = np.empty(3)
        mth = np.empty(3)
        s0 = np.empty((M, 3))
        sp = np.empty((M, 2))
        sp3 = np.empty((M, 3))
        xy = np.empty((M, 2))
        nk = np.empty((M, 3))
        Tk = np.empty((M, 2, 3))
        li = np.empty((M, 3))
        st = np.empty(3)
        lg = np.empty(3)
        lgi = np.empty(3)
        d = np.empty(3)
        up = np.empty(3)
        east = np.empty(3)
        north = np.empty(3)
        rr = np.empty(3)
        CSKIS = C_SK @ C_IS
        for m in range(M):
            matvec(C_GI, lm[m], st)
            for i in range(3):
                li[m, i] = st[i] - r[i]
        for run in range(th.shape[0]):
            for i in range(3):
                mth[i] = -th[run, i]
            rodrigues(mth, Rt)
            Ctrue = Rt @ CSKIS
            for m in range(M):  # the true image points: θ only (the case scales the reported errors)
                matvec(Ctrue, li[m], st)
                xy[m, 0] = -F * st[0] / st[2]
                xy[m, 1] = -F * st[1] / st[2]
            for case in range(factors.shape[0]):
                f = factors[case]
                for i in range(3):
                    delta[i] = dl[run, i] * f[i]
                    rr[i] = r[i] + gn[run, i] * f[4]
                rodrigues(delta, Rd)
                Cnom = C_SK @ (Rd @ C_IS)
                CG = Cnom @ C_GI
                for m in range(M):
                    sp[m, 0] = xy[m, 0] + px[run, m, 0] * f[5]
                    sp[m, 1] = xy[m, 1] + px[run, m, 1] * f[5]
                    sp3[m, 0], sp3[m, 1], sp3[m, 2] = sp[m, 0], sp[m, 1], -F
                    for i in range(3):
                        lg[i] = lm[m, i] + ct[run, m, i] * f[3]
                    matvec(C_GI, lg, lgi)
                    for i in range(3):
                        d[i] = lgi[i] - rr[i]
                    matvec(Cnom, d, st)
                    s0[m, 0], s0[m, 1], s0[m, 2] = st[0], st[1], st[2]
                    nl = np.sqrt(lg[0] ** 2 + lg[1] ** 2 + lg[2] ** 2)
                    for i in range(3):
                        up[i] = lg[i] / nl
                    ne = np.sqrt(up[0] ** 2 + up[1] ** 2)
                    east[0], east[1], east[2] = -up[1] / ne, up[0] / ne, 0.0
                    north[0] = up[1] * east[2] - up[2] * east[1]
                    north[1] = up[2] * east[0] - up[0] * east[2]
                    north[2] = up[0] * east[1] - up[1] * east[0]
                    matvec(CG, up, st)
                    nk[m, 0], nk[m, 1], nk[m, 2] = st[0], st[1], st[2]
                    matvec(CG, east, st)
                    Tk[m, 0, 0], Tk[m, 0, 1], Tk[m, 0, 2] = st[0], st[1], st[2]
                    matvec(CG, north, st)
                    Tk[m, 1, 0], Tk[m, 1, 1], Tk[m, 1, 2] = st[0], st[1], st[2]
                for alg in range(3):
                    gauss_newton(alg, s0, sp3 if alg == 1 else sp, nk, Tk, F, M, theta)
                    for i in range(3):
                        e = (theta[i] - th[run, i]) / ARCSEC
                        sums[case, alg, 0, i] += e
                        sums[case, alg, 1, i] += e * e


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=45000)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    try:
        study_block = _compile()
    except ImportError:
        print(
            "numba is not installed: the compiled eq 28 study is skipped (the bench extra installs it: "
            'python -m pip install ".[bench]" in a checkout; numba is BSD-2-Clause)'
        )
        return 0
    geo, sig = _geometry()
    M = geo["lm"].shape[0]
    factors = np.ones((7, 6))  # columns: β1 β2 β3 P R K
    for k in range(6):
        factors[k + 1, k] = 2.0
    sums = np.zeros((7, 3, 2, 3))
    ss = np.random.SeedSequence(args.seed)
    for b, child in enumerate(ss.spawn(-(-args.runs // 1000))):
        n = min(1000, args.runs - 1000 * b)
        rng = np.random.default_rng(child)
        th = rng.normal(size=(n, 3)) * sig["theta"]
        dl = rng.normal(size=(n, 3)) * sig["beta"]
        gn = rng.normal(size=(n, 3)) * sig["R"]
        ct = rng.normal(size=(n, M, 3)) * sig["P"]
        px = rng.normal(size=(n, M, 2)) * sig["K"]
        study_block(th, dl, gn, ct, px, factors, geo["C_IS"], geo["C_SK"], geo["C_GI"], geo["r"], geo["lm"], geo["F"], sums)
    n = args.runs
    mean = sums[:, :, 0] / n
    var = (sums[:, :, 1] - n * mean**2) / (n - 1)
    sd = np.sqrt(var)
    for a, name in enumerate(("image_plane", "ground_plane", "unit_vector")):
        print(f"{name:<13} σθ = {sd[0, a, 0]:.3f} / {sd[0, a, 1]:.3f} / {sd[0, a, 2]:.3f} arcsec ({n} runs, numba)")
    sigmas = [sig["beta"][0] / ARCSEC, sig["beta"][1] / ARCSEC, sig["beta"][2] / ARCSEC, sig["P"], sig["R"], sig["K"]]
    for k, s in enumerate(SOURCES):
        coef = (
            np.sqrt(np.maximum(var[k + 1, 0] - var[0, 0], 0.0) / (sigmas[k] ** 2 * 3.0)) if sigmas[k] > 0 else np.full(3, np.nan)
        )
        print(f"a_is image_plane {s:<5} " + " / ".join(f"{c:.4g}" for c in coef))


if __name__ == "__main__":
    sys.exit(main())
