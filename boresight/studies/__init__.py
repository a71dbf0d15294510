"""Studies built on the estimation core: Monte Carlo (``montecarlo``), the eq 28 sensitivity study
(``sensitivity``), the missing-effect diagnosis (``discrepancy``) and the campaign planner
(``planning``)."""
