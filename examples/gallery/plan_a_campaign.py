"""
Plan a calibration campaign
===========================

The cheapest calibration campaign that reaches a target σθ and on which ``diagnose`` would name
the effects that matter (``boresight docs planning``, the shipped ``kiev680`` plan). The figure
is the Pareto front of σθ against cost.
"""

# %%
from _common import OUT, run

run("plan", "kiev680", "--out", str(OUT / "plan"))
