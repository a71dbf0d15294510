"""Helpful errors for names that moved to another module (``module.__getattr__``, PEP 562)."""

from __future__ import annotations


def moved_names(module: str, moved: dict):
    """A module ``__getattr__`` that says where a moved name went: ``moved`` maps name → new module.

    >>> ga = moved_names("pkg.old", {"f": "pkg.new"})
    >>> try:
    ...     ga("f")
    ... except AttributeError as exc:
    ...     print(exc)
    pkg.old.f moved to pkg.new (use `from pkg.new import f`)
    """

    def __getattr__(name):
        if name in moved:
            raise AttributeError(f"{module}.{name} moved to {moved[name]} (use `from {moved[name]} import {name}`)")
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__
