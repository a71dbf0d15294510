"""The cheapest calibration campaign that reaches a target σθ and on which ``diagnose`` would
name the effects that matter (docs/planning.md, the kiev680 plan)."""

from _common import OUT, run

run("plan", "kiev680", "--out", str(OUT / "plan"), "--no-plots")
