"""The diagnosis on real data: the USV sea-sky scan (``boresight.pointing``) as a diagnosis problem.

The base model is the installation error (α, β) of USV sea-sky eq 12 **without** the hull
attitude (pitch P = roll R = 0): h'(q) = asin(v₀ᵀ S_α S_β u₀(q)). The candidates are what a
demanding analyst would suspect of a ship-borne electro-optical device:

* ``hull_attitude`` — the paper's eq 12 hull pitch and roll terms, with a gain k (1 = eq 12);
* ``pitch_coupling`` / ``roll_coupling`` — pitch or roll alone (a gain on one axis: an attitude
  sensor scale error, or the mount responding to one axis only);
* ``elevation_offset`` — a constant elevation error (horizon dip from the sensor height,
  refraction, an encoder zero);
* ``azimuth_eccentricity`` — a second harmonic of azimuth (bearing/encoder eccentricity or an
  elliptical ring).

The noise model is not known for these data: σ is the robust scatter (1.4826 MAD) of the base
fit's residuals, inflated by √(n/n_eff) for their serial correlation along the scan (Geyer's
effective sample size, ``boresight.stats.residuals``), after dropping the frames with
|robust z| > 3.5 (sea-surge blocked lines). So χ²/dof of the base model is ≈ n_eff/n by
construction and the χ² test says nothing; the likelihood-ratio tests of the candidates are
approximate (a correlated-noise GLS would need the noise's correlation model, which the paper
does not give). ``theta_arcsec`` of the diagnosis holds (α, β).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from boresight.stats.residuals import effective_sample_size, robust_sigma, robust_z
from boresight.studies.discrepancy.candidates import Candidate
from boresight.studies.discrepancy.linear import Linearization, gram_problem
from orbits.rotations import ARCSEC

__all__ = ["SeaSkyProblem", "sea_sky_candidates", "diagnose_sea_sky"]


def _none(*_):  # the sea-sky model evaluates its candidates itself
    raise NotImplementedError


def _gain(name: str, cause: str, separated_by: str) -> Candidate:
    """A gain on the hull attitude's reach into the line of sight: dimensionless, typical 1, physical [-0.5, 1.5]."""
    return Candidate(
        name, ("gain",), ("1",), np.array([1.0]), np.array([[-0.5, 1.5]]), _none, cause=cause, separated_by=separated_by
    )


def sea_sky_candidates() -> list[Candidate]:
    c = [
        _gain(
            "hull_attitude",
            cause="the hull's pitch and roll tilt the device's base (USV sea-sky eq 12)",
            separated_by="frames with hull pitch and roll of both signs at every azimuth",
        ),
        _gain(
            "pitch_coupling",
            cause="only the pitch reaches the line of sight (or the roll sensor is wrong)",
            separated_by="frames where pitch and roll are not correlated",
        ),
        _gain(
            "roll_coupling",
            cause="only the roll reaches the line of sight (or the pitch sensor is wrong)",
            separated_by="frames where pitch and roll are not correlated",
        ),
    ]
    c.append(
        Candidate(
            "elevation_offset",
            ("offset_deg",),
            ("deg",),
            np.array([0.01]),
            np.array([[-1.0, 1.0]]),
            _none,
            cause="horizon dip from the sensor height, atmospheric refraction, an elevation encoder zero",
            separated_by="nothing in a sea-sky scan separates a constant from the mean of α, β over a full turn "
            "only if the scan is complete; a star or a surveyed target at known elevation does",
        )
    )
    c.append(
        Candidate(
            "azimuth_eccentricity",
            ("cos2_deg", "sin2_deg"),
            ("deg", "deg"),
            np.array([0.01, 0.01]),
            np.array([[-0.5, 0.5], [-0.5, 0.5]]),
            _none,
            cause="bearing or encoder eccentricity, an elliptical azimuth ring",
            separated_by="a complete, evenly sampled azimuth turn",
        )
    )
    return c


@dataclass(frozen=True)
class _Lin:
    lin: Linearization
    candidates: dict
    status: dict
    scales: dict
    probes: dict


class SeaSkyProblem:
    """``boresight.studies.discrepancy`` adapter for a ``SeaSkyScan`` (see the module docstring)."""

    kind = "sea_sky"
    n_base = 2
    base_labels = ("alpha", "beta")
    base_to_display = 1.0 / ARCSEC

    def __init__(self, scan, candidates=None, outlier_z: float = 3.5):
        from boresight.pointing.sea_sky_fit import fit_least_squares

        self.scan = scan
        cands = sea_sky_candidates() if candidates is None else list(candidates)
        self.candidates = {c.name: c for c in cands}
        base = fit_least_squares(scan, loss="huber", use_attitude=False)
        r = base.residuals_deg
        self.inlier = np.abs(robust_z(r)) <= outlier_z
        self.outlier_frames = scan.frame[~self.inlier]
        ri = r[self.inlier]
        self.n_eff = effective_sample_size(ri)
        self.sigma_deg = robust_sigma(ri) * np.sqrt(ri.size / self.n_eff)
        self.base_start = np.radians([base.alpha_deg, base.beta_deg])
        q = np.radians(scan.azimuth_deg[self.inlier])
        self.q = q
        self.P = np.radians(scan.pitch_deg[self.inlier])
        self.R = np.radians(scan.roll_deg[self.inlier])
        self.h = scan.h_meas_deg[self.inlier]
        order = np.linspace(-1, 1, q.size)
        self.probes_raw = {
            "azimuth harmonics": np.column_stack([f(k * q) for k in (1, 3, 4) for f in (np.cos, np.sin)]),
            "scan order": np.column_stack([order, order**2 - 1 / 3, order**3]),
        }

    @staticmethod
    def column_scales(c, cs=None):
        """The scale of each of candidate ``c``'s parameters (every sea-sky candidate states its own ``scales``;
        ``cs``, the columns, is taken for the campaign problem's signature)."""
        return np.asarray(c.scales, float)

    def _model_deg(self, ab_rad, named: dict):
        from boresight.pointing.sea_sky_fit import Geometry

        kp = kr = 0.0
        extra = np.zeros(self.q.size)
        for name, p in named.items():
            p = np.asarray(p, float)
            if name == "hull_attitude":
                kp, kr = kp + p[0], kr + p[0]
            elif name == "pitch_coupling":
                kp += p[0]
            elif name == "roll_coupling":
                kr += p[0]
            elif name == "elevation_offset":
                extra = extra + p[0]
            elif name == "azimuth_eccentricity":
                extra = extra + p[0] * np.cos(2 * self.q) + p[1] * np.sin(2 * self.q)
        g = Geometry(np.degrees(self.q), np.degrees(self.P) * kp, np.degrees(self.R) * kr)
        return g.elevation_deg(np.degrees(ab_rad[0]), np.degrees(ab_rad[1])) + extra

    def _jac(self, f, x, steps):
        cols = []
        for i, h in enumerate(steps):
            e = np.zeros_like(x)
            e[i] = h
            cols.append((f(x + e) - f(x - e)) / (2 * h))
        return np.column_stack(cols)

    def linearize(self, theta_rad, named: dict, candidate_names=(), probes: bool = False):
        ab = np.asarray(theta_rad, float).reshape(2)
        named = {k: np.asarray(v, float) for k, v in named.items()}
        h0 = self._model_deg(ab, named)
        s = self.sigma_deg
        z = (self.h - h0) / s
        cols = [self._jac(lambda x: self._model_deg(x, named), ab, [1e-7, 1e-7])]
        for name, p in named.items():
            sc = self.column_scales(self.candidates[name])

            def f(x, name=name):
                nn = dict(named)
                nn[name] = x
                return self._model_deg(ab, nn)

            cols.append(self._jac(f, p, 1e-3 * sc) * sc)
        X = np.column_stack(cols) / s
        cands, scales, status = {}, {}, {}
        for name in candidate_names:
            c = self.candidates[name]
            sc = self.column_scales(c)

            def f(x, name=name):
                nn = dict(named)
                nn[name] = x
                return self._model_deg(ab, nn)

            cands[name] = self._jac(f, np.zeros(c.n_params), 1e-3 * sc) * sc / s
            scales[name] = sc
            status[name] = "ok"
        prb = {k: v / s for k, v in self.probes_raw.items()} if probes else {}
        extra = list(cands.values()) + list(prb.values())
        lin, cols = gram_problem(
            Linearization(z=z, X=X, n_data=z.size, n_fitted=X.shape[1]), np.column_stack(extra) if extra else None
        )
        out, j = {}, 0
        for name, C in list(cands.items()) + list(prb.items()):
            out[name] = cols[:, j : j + C.shape[1]]
            j += C.shape[1]
        return _Lin(lin, {k: out[k] for k in cands}, status, scales, {k: out[k] for k in prb})


def diagnose_sea_sky(scan=None, *, alpha: float = 0.01, power: float = 0.8):
    """The diagnosis of the sea-sky scan (default: the paper's 120 frames) from the model without
    hull attitude; returns a ``Diagnosis`` whose ``theta_arcsec`` is (α, β) in arcsec and whose
    ``details`` add ``outlier_frames``, ``sigma_deg`` and ``n_eff``."""
    from boresight.pointing import load_sea_sky
    from boresight.studies.discrepancy.workflow import diagnose_problem

    problem = SeaSkyProblem(load_sea_sky() if scan is None else scan)
    d = diagnose_problem(problem, alpha=alpha, power=power)
    d.details.update(
        outlier_frames=problem.outlier_frames, sigma_deg=problem.sigma_deg, n_eff=problem.n_eff, n=int(problem.inlier.sum())
    )
    return d
