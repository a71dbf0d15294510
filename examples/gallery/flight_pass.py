"""The flight tutorial (docs/tutorial-flight-data.md): CCSDS OEM + AEM, a landmark list, pixel
detections and a camera calibration → an observation file → θ ± σ."""

from _common import EXAMPLES, OUT, run

d = EXAMPLES / "flight-pass"
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
run("check", str(OUT / "pass.ecsv"))
run("estimate", str(OUT / "pass.ecsv"), "--out", str(OUT / "flight-results"))
