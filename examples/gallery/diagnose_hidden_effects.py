"""Name the effects hidden in a simulated campaign (docs/discrepancy.md): the worked example's
scenario hides a time-tag offset and a radial distortion; ``diagnose`` fits the base model,
tests the residuals, checks what the data can separate from θ and names what it finds."""

from _common import OUT, run

run("diagnose", "diagnose-example", "--seed", "1", "--out", str(OUT / "diagnosis"), "--no-plots")
