"""Estimation algorithms (Kiev 2012): one module per algorithm, sharing ``boresight.core.gls.normal_equations``.

The three linearisers share one interface, ``linearize(obs, θ0) -> (G (R, K, 2, 3), q (R, K, 2))``, one
row per observation (the row model, ``docs/architecture.md``), and ``residual_map(obs, θ0) -> L (R, K, 2, 2)``,
with q = measured − predicted ≈ G (θ − θ0) in their residual's unit (``boresight.core.registry``):
focal-plane metres (``image_plane``, ``boresight.core.measurement``), ground metres
(``ground_plane``), radians (``unit_vector``). Noise-free data have a zero residual at the truth:

>>> import numpy as np
>>> from boresight import simulate
>>> from boresight.core.algorithms import ground_plane, image_plane, unit_vector
>>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0))
>>> for m, tol in ((image_plane, 1e-12), (ground_plane, 1e-6), (unit_vector, 1e-14)):
...     G, q = m.linearize(obs, obs.truth["theta_rad"])
...     print(m.__name__.rsplit(".")[-1], G.shape, bool(np.abs(q).max() < tol))
image_plane (1, 40, 2, 3) True
ground_plane (1, 40, 2, 3) True
unit_vector (1, 40, 2, 3) True
"""
