"""Estimation algorithms (Kiev 2012): one module per algorithm, sharing ``boresight.core.normal_equations``."""
