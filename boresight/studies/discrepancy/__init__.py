"""Residual diagnostics and the "find the missing effect" workflow.

The generic, model-agnostic residual statistics it uses are in ``boresight.stats``; ``linear`` the
whitened linear-Gaussian core of the diagnosis; ``campaign`` the adapter for landmark
campaigns; ``structure`` the residual tests; ``workflow`` ``diagnose`` itself; ``report`` the
summary, markdown, JSON and plots (``docs/discrepancy.md``).
"""

from boresight.studies.discrepancy.workflow import Diagnosis, diagnose

__all__ = ["Diagnosis", "diagnose"]
