"""
Name the effects hidden in a campaign
=====================================

The worked example of the missing-effect diagnosis (``boresight docs discrepancy``): the scenario
``diagnose-example`` hides a time-tag offset and a radial distortion. ``diagnose`` fits the base
model, tests the residuals, checks what the data can separate from θ and names what it finds;
the plots show the residuals before and after each step.
"""

# %%
from _common import OUT, run

run("diagnose", "diagnose-example", "--seed", "1", "--out", str(OUT / "diagnosis"))
