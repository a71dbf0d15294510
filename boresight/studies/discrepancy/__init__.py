"""Residual diagnostics and the "find the missing effect" workflow.

The generic, model-agnostic residual statistics it uses are in ``boresight.stats``; ``linear`` the
whitened linear-Gaussian core of the diagnosis; ``campaign`` the adapter for landmark campaigns,
``sea_sky`` for the USV sea-sky scan; ``candidates`` the candidate effects; ``rule`` the one naming
rule; ``structure`` the residual tests; ``workflow`` ``diagnose`` itself (the steps in order, and the
noise model's variance components when the χ² test still fails after naming); ``state`` a fitted
model, ``naming`` identifiability, naming and withdrawal, ``result`` the ``Diagnosis`` it returns;
``line_scan`` the diagnosis of pushbroom lines; ``report`` the summary, markdown, JSON and plots
(``docs/discrepancy.md``).
"""

__all__ = ["Diagnosis", "diagnose"]


def __getattr__(name: str):
    """``Diagnosis`` and ``diagnose`` load ``workflow`` (and scipy.stats) on first use: the planner
    imports only ``rule`` and ``linear`` from this package, and every command's start-up stays free of
    scipy.stats (+0.8 s when ``boresight/__init__`` loaded the diagnosis)."""
    if name in __all__:
        from boresight.studies.discrepancy import workflow

        return getattr(workflow, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
