"""
A flight pass: from CCSDS files to θ ± σ
========================================

The flight tutorial's data set (``boresight docs tutorial-flight-data``): a CCSDS OEM orbit and AEM
attitude, a landmark list, pixel detections and a camera calibration are ingested into one
observation file, checked for convention slips, and estimated. ``estimate --out`` writes the
residual plots shown below.
"""

# %%
# Ingest the pass, as the tutorial's step 1 does: ``--example flight-pass`` takes the five files from
# the shipped data set (with your own files, name them instead: ``--oem orbit.oem --aem attitude.aem
# --landmarks landmarks.csv --detections detections.csv --camera camera.toml``). The noise model is
# given in the units the sensors are specified in; ``examples/flight-pass/README.md`` says where each
# σ comes from.
from _common import OUT, run

noise = ["--sigma-pixel-px", "0.3", "--sigma-star-tracker-arcsec", "4", "--sigma-gnss-m", "1", "--sigma-catalogue-m", "0.5"]
run("ingest", "--example", "flight-pass", *noise, "--out", str(OUT / "pass.ecsv"))

# %%
# The convention doctor: mirrored axes, quaternion order and direction, transposed matrices.
run("check", str(OUT / "pass.ecsv"))

# %%
# θ ± σ with the file's noise model, and the residual plots.
run("estimate", str(OUT / "pass.ecsv"), "--out", str(OUT / "flight-results"))
