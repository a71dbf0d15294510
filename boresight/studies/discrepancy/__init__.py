"""Residual diagnostics and the "find the missing effect" workflow.

The generic, model-agnostic residual statistics it uses are in ``boresight.stats``; ``linear`` the
whitened linear-Gaussian core of the diagnosis; ``campaign`` the adapter for landmark
campaigns; ``structure`` the residual tests; ``workflow`` ``diagnose`` itself (the steps in order),
``state`` a fitted model, ``naming`` identifiability, naming and withdrawal, ``scatter`` the
unexplained-scatter step, ``result`` the ``Diagnosis`` it returns; ``report`` the summary, markdown,
JSON and plots (``docs/discrepancy.md``).
"""

__all__ = ["Diagnosis", "diagnose"]


def __getattr__(name: str):
    """``Diagnosis`` and ``diagnose`` load ``workflow`` (and scipy.stats) on first use: the planner
    imports only ``rule`` and ``linear`` from this package (issue 19)."""
    if name in __all__:
        from boresight.studies.discrepancy import workflow

        return getattr(workflow, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
