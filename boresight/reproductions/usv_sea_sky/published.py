"""The USV sea-sky paper's published numbers — defined here and nowhere else.

Source: the USV sea-sky line paper (``docs/references.md``), section 6 and Figs. 8-9, on its own
Table 1 (the 120 measured frames packaged as ``boresight/data/usv_sea_sky_line.csv``). Only
this package's report and the commands (``boresight pointing sea-sky``) import these — never
the library proper (``tests/project/test_layering.py``); a test (``tests/reproductions/test_kiev2012.py``) checks that no
other module restates them.
"""

from __future__ import annotations

__all__ = ["PAPER_SPECIAL_POINTS_DEG", "PAPER_COARSE_DEG", "PAPER_FINE_DEG"]

#: USV sea-sky section 6 / Fig. 8: zero crossing q1' = 70.28 deg and peak |h2'| = 1.076 deg.
PAPER_SPECIAL_POINTS_DEG = (70.28, 1.076)
#: USV sea-sky section 6: coarse (alpha, beta) from the special points, eq 23.
PAPER_COARSE_DEG = (1.0133, 0.3632)
#: USV sea-sky section 6 / Fig. 9a: (alpha, beta) from the two-stage grid search, eq 24.
PAPER_FINE_DEG = (0.9533, 0.3732)
