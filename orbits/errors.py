"""The root of the project's one error hierarchy.

Every rejection of a user's input or data — a malformed scenario or observation file, an
unobservable geometry, an estimate that cannot be trusted — raises a subclass of
``BoresightError``. It lives here, in the lower layer, because ``orbits`` must not import
``boresight``; ``boresight.errors`` re-exports it. Subclasses also derive from ``ValueError``
where the old API promised one, so ``except ValueError`` keeps working.

Every error class of ``orbits`` is defined in this file: ``InputTypeError``, ``InputValueError`` (an
argument refused), ``EffectError``, ``MissingContextError`` (the effects catalogue), ``ScenarioError`` (a
scenario file), ``StarCatalogueError`` (the star catalogue), ``LocationError`` (pushbroom location) and
``MemoryBudgetError`` (the memory budget); the modules that raise them import them from here, and still
expose them (``orbits.limits.MemoryBudgetError`` is this one).

The command line prints a ``BoresightError`` as one line and exits non-zero; a traceback is
reserved for real bugs.

>>> issubclass(BoresightError, Exception)
True
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "BoresightError",
    "EffectError",
    "InputTypeError",
    "InputValueError",
    "LocationError",
    "MemoryBudgetError",
    "MissingContextError",
    "ScenarioError",
    "StarCatalogueError",
    "checked_table",
    "did_you_mean",
    "extra_hint",
    "unknown_keys_message",
]


class BoresightError(Exception):
    """Base of every error boresight raises on purpose (bad input, unusable data or geometry).

    Messages name the file, the key or column as the user wrote it, the row and the value.
    """


class InputTypeError(BoresightError, TypeError):
    """An argument of a kind the function does not take (a list where an ``ObservationSet`` is
    wanted, a number for a path); the message names the function, the argument, what it takes and
    what it got (``InputTypeError.expected``). A ``TypeError`` too, as Python's own would be."""

    @classmethod
    def expected(cls, who: str, name: str, takes: str, value: Any) -> "InputTypeError":
        """The one wording: ``"estimate: observations must be an ObservationSet …, got list"``.

        >>> str(InputTypeError.expected("simulate", "rng", "a numpy.random.Generator", 42))
        'simulate: rng must be a numpy.random.Generator, got int'
        """
        return cls(f"{who}: {name} must be {takes}, got {type(value).__name__}")


class InputValueError(BoresightError, ValueError):
    """An argument of the right kind with a value the function does not take (``weighting="gsl"``,
    a negative σ); the message names the function, the argument, what it takes and the value."""


class EffectError(BoresightError, ValueError):
    """A malformed effect name, size or parameter array; the message names it and the value."""


class ScenarioError(BoresightError, ValueError):
    """A scenario file or dict is malformed; the message names the file, the key and the value
    (``orbits.scenario_schema``)."""


class StarCatalogueError(BoresightError, ValueError):
    """The star catalogue cannot be read or used (missing package or file, malformed record, bad value;
    ``orbits.star_catalogue``)."""


class LocationError(BoresightError, ValueError):
    """Direct or inverse location failed (a time outside the samples, no convergence, a ray missing the Earth;
    ``orbits.pushbroom``)."""


class MemoryBudgetError(BoresightError, ValueError):
    """A requested size would allocate more memory than the budget allows (``orbits.limits``).

    Attributes: ``estimate_bytes`` and ``budget_bytes``.
    """

    def __init__(self, message: str, *, estimate_bytes: float, budget_bytes: float) -> None:
        super().__init__(message)
        self.estimate_bytes = float(estimate_bytes)
        self.budget_bytes = float(budget_bytes)


class MissingContextError(EffectError):
    """An effect's basis needs a quantity the data do not carry (velocity, attitude rate)."""

    def __init__(self, what: str) -> None:
        super().__init__(f"needs {what}")
        self.what = what


def did_you_mean(word: Any, options: Any, cutoff: float = 0.6) -> str:
    """``" — did you mean 'x'?"`` for the closest of ``options`` to ``word``, or ``""`` — the one
    "did you mean" of every message (commands, options, keys, shipped names, algorithms).

    DECISION: difflib's ratio with cutoff 0.6 (the standard library's matcher, as Python's own
    "Did you mean" for names): a typo of one or two characters matches, an unrelated word does not.

    >>> did_you_mean("estimat", ["simulate", "estimate", "check"])
    " — did you mean 'estimate'?"
    >>> did_you_mean("zzz", ["simulate", "estimate"])
    ''
    """
    import difflib

    close = difflib.get_close_matches(str(word), [str(o) for o in options], n=1, cutoff=cutoff)
    return f" — did you mean '{close[0]}'?" if close else ""


def extra_hint(extra: str) -> str:
    """How to install the optional extra ``extra`` — the one wording of every message and help text
    that names one (the figures' note, ``MissingExtraError``, the ingestion and catalogue refusals).

    DECISION: the README's form, ``python -m pip install ".[flight]"`` in a checkout: boresight is not
    on PyPI, so installing ``boresight[flight]`` by name fails for a user who follows it (it works only
    once a wheel of boresight is on a local index). The extra's name is kept as ``boresight[flight]`` so a
    reader can find it in ``pyproject.toml``'s ``[project.optional-dependencies]``.

    >>> extra_hint("flight")
    'the optional extra boresight[flight]: python -m pip install ".[flight]" in a boresight checkout'
    """
    return f'the optional extra boresight[{extra}]: python -m pip install ".[{extra}]" in a boresight checkout'


def unknown_keys_message(where: str, unknown: Any, known: Any) -> str:
    """The one wording of an unknown-key refusal: the keys as the user wrote them, the closest
    valid spelling of each, then the valid keys.

    >>> unknown_keys_message("my.toml: [misalignment]", ["sigma0_arcsecs"], ["true_arcsec", "sigma0_arcsec"])
    "my.toml: [misalignment]: unknown key 'sigma0_arcsecs' — did you mean 'sigma0_arcsec'?; expected some of ['sigma0_arcsec', 'true_arcsec']"
    """
    bad = sorted(map(str, unknown))
    named = ", ".join(f"'{k}'{did_you_mean(k, known)}" for k in bad)
    return f"{where}: unknown key{'s' if len(bad) > 1 else ''} {named}; expected some of {sorted(map(str, known))}"


def checked_table(value: Any, where: str, keys: Any, error: type[Exception] = ValueError) -> dict[str, Any]:
    """A TOML table (``value``, at ``where``) as a new dict, refused with ``error`` when it is not a table
    or has a key outside ``keys`` (the wording of ``unknown_keys_message``) — the one check of a table's
    keys for the scenario and sensor files.

    >>> checked_table({"roll_deg": 5}, "s.toml: [strip]", ["roll_deg", "n_lines"])
    {'roll_deg': 5}
    >>> checked_table([1], "s.toml: [strip]", ["roll_deg"])
    Traceback (most recent call last):
    ...
    ValueError: s.toml: [strip] must be a table, got [1]
    """
    if not isinstance(value, dict):
        raise error(f"{where} must be a table, got {value!r}")
    unknown = sorted(set(value) - set(keys))
    if unknown:
        raise error(unknown_keys_message(where, unknown, keys))
    return dict(value)
