"""
Reproduce the Kiev 2012 seminar
===============================

The seminar's tables beside ours (``boresight docs reproduction``): Algorithm 1, the eq 28
sensitivity study and the Kalman table. The narrative's numbers use 45 000 runs per case; with
``BORESIGHT_GALLERY_SMALL`` (as on this page) the study runs 1 000 (the Kalman table 200), so its
σθ carry wider intervals.
"""

# %%
from _common import OUT, SMALL, run

sizes = ["--runs", "1000", "--kalman-runs", "200", "--workers", "1"] if SMALL else []
run("reproduce", "kiev2012", "--out", str(OUT / "report"), *sizes)
