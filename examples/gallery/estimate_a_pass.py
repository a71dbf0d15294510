"""θ ± σ of one simulated 20-image pass, compared with the truth it was made from (README).

The scenario is the seminar's Kalman-table geometry with its noise model; ``estimate`` uses GLS
under that noise model, and the summary prints the error against the truth in units of σ.
"""

import numpy as np

import boresight
import orbits

scenario = orbits.load_scenario("kiev2012-kalman20")
obs = boresight.simulate(scenario, np.random.default_rng(7))
est = boresight.estimate(obs)
print(est.summary())
