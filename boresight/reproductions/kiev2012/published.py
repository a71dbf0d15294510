"""The Kiev 2012 seminar's published numbers — defined here and nowhere else.

Source: Lebedev & Tkachenko, Kiev 2012 seminar (``docs/references.md`` [Kiev2012]); the slide or
equation each table comes from is named with it. Only this package's reproduction modules
(``eq28``, ``algorithm1``, ``kalman_table``, ``report``) and the commands (``sensitivity``) import
these — never the library proper (``tests/project/test_layering.py``); a test (``tests/reproductions/test_kiev2012.py``) checks that no other
module restates them.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SEMINAR_EQ28",
    "SEMINAR_EQ28_UNITS",
    "SEMINAR_EQ28_SIGMA_ARCSEC",
    "SEMINAR_ALGORITHM1_TABLE",
    "SEMINAR_KALMAN_ROWS",
    "SEMINAR_IMAGE_COUNTS",
    "seminar_kalman_table",
]

#: Kiev 2012 eq 28 sensitivity table ∂σθi/∂σs: source → (x, y, z, norm), units ``SEMINAR_EQ28_UNITS``.
#: Sources in the seminar's symbols (``boresight.core.error_sources``): K pixel, R GNSS, P catalogue,
#: β1-β3 star tracker.
SEMINAR_EQ28 = {
    "K": (0.04e6, 0.04e6, 2.47e6, 2.47e6),
    "R": (0.30, 0.30, 0.0, 0.43),
    "P": (0.12, 0.12, 7.88, 7.88),
    "beta1": (0.49, 0.81, 0.33, 1.0),
    "beta2": (0.70, 0.14, 0.70, 1.0),
    "beta3": (0.53, 0.57, 0.64, 1.0),
}
#: units of the eq 28 rows
SEMINAR_EQ28_UNITS = {
    "K": "arcsec/m",
    "R": "arcsec/m",
    "P": "arcsec/m",
    "beta1": "arcsec/arcsec",
    "beta2": "arcsec/arcsec",
    "beta3": "arcsec/arcsec",
}
#: Kiev 2012 eq 28 result: σθx, σθy, σθz, total (arcsec)
SEMINAR_EQ28_SIGMA_ARCSEC = (6.09, 6.09, 8.36, 11.98)

#: Kiev 2012, Algorithm 1 result table (seed slide after eq 13): t (s) from the passage over the
#: site (interpretation), μ (arcsec) and δr (m) for landmark errors r_p = 0, 1 and 5 m (one
#: realisation each for r_p > 0). Keys ``mu_arcsec_rp{r}``, ``dr_m_rp{r}``.
SEMINAR_ALGORITHM1_TABLE = {
    "t_s": (5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0),
    "mu_arcsec_rp0": (20.5, 12.1, 6.9, 9.6, 13.7, 17.1, 19.7, 21.7, 23.3, 24.4),
    "dr_m_rp0": (131.7, 82.4, 41.0, 17.8, 7.6, 4.5, 4.8, 6.6, 9.0, 11.2),
    "mu_arcsec_rp1": (26.9, 12.6, 13.7, 20.8, 14.8, 22.7, 37.1, 21.9, 6.5, 38.1),
    "dr_m_rp1": (109.3, 92.8, 94.2, 64.8, 110.8, 22.6, 23.9, 11.6, 48.3, 18.7),
    "mu_arcsec_rp5": (36.0, 110.3, 114.8, 134.4, 129.0, 67.5, 171.1, 116.0, 72.4, 166.8),
    "dr_m_rp5": (44.0, 147.8, 140.8, 551.7, 149.7, 156.9, 78.7, 73.7, 219.0, 293.6),
}

#: Kiev 2012 eq 32 table (Kalman variant, initial uncertainty σ = 10″), arcsec: rows of
#: (images, σθx, σθy, σθz, max|θx|, max|θy|, max|θz|). The slide's last row ("refined
#: resolution") is not included.
SEMINAR_KALMAN_ROWS = (
    (1, 2.9, 3.2, 18.8, 8.4, 8.1, 78.3),
    (2, 2.2, 2.3, 13.3, 6.5, 5.9, 50.6),
    (4, 1.7, 1.9, 10.6, 5.3, 5.1, 36.1),
    (8, 3.8, 3.5, 7.5, 11.9, 11.5, 23.0),
    (12, 4.3, 4.2, 7.0, 11.9, 12.1, 23.9),
    (20, 4.6, 4.3, 6.4, 12.2, 12.8, 25.4),
)
#: the image counts of the eq 32 table's rows
SEMINAR_IMAGE_COUNTS = tuple(r[0] for r in SEMINAR_KALMAN_ROWS)


def seminar_kalman_table():
    """The seminar's published eq 32 table (``SEMINAR_KALMAN_ROWS``) as an astropy Table, arcsec.

    >>> t = seminar_kalman_table()
    >>> float(t["sigma_theta_x"][-1]), t["sigma_theta_x"].unit.to_string()
    (4.6, 'arcsec')
    """
    from astropy import units as u
    from astropy.table import Table

    a = np.array(SEMINAR_KALMAN_ROWS)
    t = Table()
    t["n_images"] = a[:, 0].astype(int)
    for i, name in enumerate(
        ["sigma_theta_x", "sigma_theta_y", "sigma_theta_z", "max_abs_theta_x", "max_abs_theta_y", "max_abs_theta_z"]
    ):
        t[name] = a[:, i + 1] * u.arcsec
    t.meta["reference"] = "Kiev 2012 eq 32 table (initial uncertainty σ = 10″)"
    return t
