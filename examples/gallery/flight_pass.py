"""
A flight pass: from CCSDS files to θ ± σ
========================================

The flight tutorial's data set (``boresight docs tutorial-flight-data``): a CCSDS OEM orbit and AEM
attitude, a landmark list, pixel detections and a camera calibration are ingested into one
observation file, checked for convention slips, and estimated. ``estimate --out`` writes the
residual plots shown below.
"""

# %%
# Ingest the pass (the noise model is given in the units the sensors are specified in).
from _common import FLIGHT_PASS, OUT, run

d = FLIGHT_PASS
OUT.mkdir(parents=True, exist_ok=True)
run(
    "ingest",
    "--oem",
    str(d / "orbit.oem"),
    "--aem",
    str(d / "attitude.aem"),
    "--landmarks",
    str(d / "landmarks.csv"),
    "--detections",
    str(d / "detections.csv"),
    "--camera",
    str(d / "camera.toml"),
    "--sigma-pixel-px",
    "0.3",
    "--sigma-star-tracker-arcsec",
    "4",
    "--sigma-gnss-m",
    "1",
    "--sigma-catalogue-m",
    "0.5",
    "--out",
    str(OUT / "pass.ecsv"),
)

# %%
# The convention doctor: mirrored axes, quaternion order and direction, transposed matrices.
run("check", str(OUT / "pass.ecsv"))

# %%
# θ ± σ with the file's noise model, and the residual plots.
run("estimate", str(OUT / "pass.ecsv"), "--out", str(OUT / "flight-results"))
