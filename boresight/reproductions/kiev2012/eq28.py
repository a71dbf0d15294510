"""The seminar's eq 28 table beside ours: the sensitivity study's comparison plus the published column.

``boresight.studies.sensitivity`` knows nothing about the seminar; this module puts
``published.SEMINAR_EQ28`` next to a study's finite-difference, analytic and CRLB sensitivities,
for the ``sensitivity`` command and the reproduction report.
"""

from __future__ import annotations

from boresight.reproductions.kiev2012.published import SEMINAR_EQ28, SEMINAR_EQ28_UNITS

__all__ = ["eq28_comparison", "seminar_table"]


def eq28_comparison(study, algorithm: str = "image_plane"):
    """``study.comparison(algorithm)`` (FD ± SE, analytic, CRLB per source and axis) with the
    seminar's entry in ``seminar_{x,y,z}``."""
    t = study.comparison(algorithm)
    for i, a in enumerate("xyz"):
        t.add_column([SEMINAR_EQ28[s][i] for s in t["source"]], name=f"seminar_{a}", index=t.colnames.index(f"crlb_{a}") + 1)
    return t


def seminar_table():
    """The seminar's eq 28 sensitivity table as an astropy Table.

    >>> float(seminar_table()["coef_z"][0])
    2470000.0
    """
    from astropy.table import Table

    return Table(
        rows=[(s, *v, SEMINAR_EQ28_UNITS[s]) for s, v in SEMINAR_EQ28.items()],
        names=["source", "coef_x", "coef_y", "coef_z", "coef_norm", "unit"],
    )
