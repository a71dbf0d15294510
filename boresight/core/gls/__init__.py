"""The one GLS of the estimation core (``docs/architecture.md``, "The row model").

* ``normal_equations`` — the information-form accumulator every least-squares algorithm shares
  (Kiev 2012 eqs 18, 22): ``NormalEquations``, ``Solution``.
* ``structure`` — the one builder of the noise model's nuisance columns (per image, per pass,
  catalogue), scaled so that every nuisance has the prior N(0, E).
* ``campaign`` — the campaign GLS: the nuisances eliminated exactly, the normal equations of x,
  the MAP nuisances, pixel-level residuals, the sandwich middle, leverages and reduced rows.
"""
