"""Residual diagnostics and the "find the missing effect" workflow.

``residuals`` holds generic, model-agnostic diagnostics over numpy arrays; ``linear`` the
whitened linear-Gaussian core of the diagnosis; ``campaign`` the adapter for landmark
campaigns; ``structure`` the residual tests; ``workflow`` ``diagnose`` itself; ``report`` the
summary, markdown, JSON and plots (``docs/discrepancy.md``).
"""

from boresight.stats.residuals import (
    MAD_TO_SIGMA,
    BinnedResiduals,
    HarmonicFit,
    NestedTest,
    autocorrelation,
    binned_residuals,
    effective_sample_size,
    gaussian_aic,
    harmonic_fit,
    ljung_box,
    nested_f_test,
    newey_west_covariance,
    newey_west_default_lag,
    outlier_flags,
    robust_sigma,
    robust_z,
)
from boresight.studies.discrepancy.workflow import Diagnosis, diagnose

__all__ = [
    "Diagnosis",
    "diagnose",
    "MAD_TO_SIGMA",
    "BinnedResiduals",
    "HarmonicFit",
    "NestedTest",
    "autocorrelation",
    "binned_residuals",
    "effective_sample_size",
    "gaussian_aic",
    "harmonic_fit",
    "ljung_box",
    "nested_f_test",
    "newey_west_covariance",
    "newey_west_default_lag",
    "outlier_flags",
    "robust_sigma",
    "robust_z",
]
