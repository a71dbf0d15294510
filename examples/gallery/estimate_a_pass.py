"""
Estimate θ from one simulated pass
==================================

θ ± σ of one simulated 20-image pass, compared with the truth it was made from (the README's
first example). The scenario is the seminar's Kalman-table geometry with its noise model;
``boresight.estimate`` weights by that noise model (GLS), and the summary prints the error against
the truth in units of σ.
"""

# %%
# Simulate one pass of a shipped scenario and estimate θ with its noise model.
import numpy as np

import boresight
import orbits

scenario = orbits.load_scenario("kiev2012-kalman20")
obs = boresight.simulate(scenario, np.random.default_rng(7))
est = boresight.estimate(obs)
print(est.summary())

# %%
# The residuals on the focal plane at the estimated θ, each coordinate over its own σ under the
# noise model (``Estimate.residual_z``): a consistent fit scatters them about 0 with a spread near 1.
import matplotlib.pyplot as plt  # noqa: E402 - the figure's own section

z = est.residual_z(obs, boresight.DisturbanceModel.from_scenario(scenario))[0]  # (observations, 2): one row per observation
fig, ax = plt.subplots(figsize=(6, 3.2), layout="constrained")
ax.hist(z.ravel(), bins=20, color="C0", edgecolor="white")
ax.set_xlabel("residual / its σ (x and y coordinates, dimensionless)")
ax.set_ylabel("observations")
ax.set_title(f"{obs.n_observations} landmark observations, {obs.n_images} images", loc="left", fontsize=10)
plt.show()
