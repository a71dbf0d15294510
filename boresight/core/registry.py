"""The one table of θ algorithms: name → aliases, kind, module, Monte Carlo kernel.

Everything that lists algorithms reads this table: ``boresight.estimate`` (``algorithms()``,
the lookup of a name or alias, the lazy import of an estimator's module: ``resolve``), the Monte Carlo
engine (``ALGORITHMS``, ``LEAST_SQUARES``, which kernel runs a name) and the command line
(``--algorithm`` help and checks). It is complete without importing any algorithm module:
the entries name their module and functions as strings.

The run-time side lives here too (one registry): ``register_algorithm`` adds a name (or replaces
one) for ``estimate``; ``resolve`` turns a name or alias into its callable, importing a built-in
row's module on first use.

Kinds:

* ``linearizer`` — ``module.linearize(obs, θ) -> (G, q)`` (and ``residual_map`` for the weighted
  forms) joins ``estimate``'s shared Gauss–Newton loop;
* ``estimator`` — ``module.<function>(obs, ...) -> Estimate`` does everything itself;
* ``study`` — a Monte Carlo kernel only, not available to ``estimate`` (``kalman_theta``: the
  θ-only information filter of the Monte Carlo engine, with R_n fixed at the nominal geometry;
  ``estimate(algorithm="kalman")`` is the library's filter, with bias and catalogue states).

``montecarlo_kernel`` names the function in ``boresight.core.algorithms.batched`` that runs the
algorithm over a batch of runs (None: the Monte Carlo engine cannot run it).

Names and aliases. A name says what the algorithm fits (``image_plane``, ``ground_plane``,
``unit_vector``, ``homography``, ``kalman``, ``line_scan``); ``Estimate.algorithm`` and every output carry
the name, never an alias.

DECISION: the aliases are the paper's own names and stay, documented here: the Kiev 2012 seminar numbers
Algorithms 1-3 (``alg1`` homography, ``alg2`` ground plane, ``alg3`` image plane) and names the unit-vector
criterion and the Kalman filter only by their equations (``eq31``, ``eq32``); a reader of the paper types
those, and the reproduction and its report use them. ``pushbroom`` is the sensor's usual name for
``line_scan``. The hyphenated ``unit-vector`` (the one alias that was a spelling, not a name) is removed:
it is refused with "did you mean 'unit_vector'" (``CHANGES.md``).

DECISION: Algorithm 1 has two functions in ``core.algorithms.homography``, one per result type, as the
Kalman filter has (``kalman_filter`` → ``KalmanResult``, ``estimate_kalman`` → ``Estimate``):
``estimate_homography`` returns the per-image ``HomographyResult`` (θ, μ, δr and heights of every image:
the paper's tables, which the reproduction prints), and ``estimate_alg1``, this table's entry, the
``Estimate`` ``boresight.estimate(obs, algorithm="homography")`` returns (the mean θ over images).
The line scanner has the same pair (``estimate_line_scan`` → its own result, ``estimate_lines`` → ``Estimate``).
Renaming either of a pair would change the type a caller gets under a name it already uses; a row names
its ``Estimate`` function in ``function``, so the table reads the same for all three.

>>> lookup("alg3").name, lookup("alg3").montecarlo_kernel
('image_plane', 'image_plane_kernel')
>>> montecarlo_names()
('image_plane', 'ground_plane', 'unit_vector', 'kalman_theta')
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from boresight.errors import InputTypeError, InputValueError, UnknownAlgorithmError

__all__ = [
    "Algorithm",
    "ALGORITHMS",
    "KINDS",
    "UnknownAlgorithmError",
    "lookup",
    "names",
    "estimator_names",
    "names_text",
    "montecarlo_names",
    "least_squares_names",
    "Registered",
    "register_algorithm",
    "algorithms",
    "resolve",
]

KINDS = ("linearizer", "estimator", "study")


@dataclass(frozen=True)
class Algorithm:
    """One row of the table (strings only: nothing is imported to build it)."""

    name: str
    aliases: tuple[str, ...]
    kind: str  # KINDS
    module: str  # where the estimator lives
    function: str | None  # the linearizer / estimator function in ``module`` (None for a study kernel)
    residual_map: str | None  # the residual map in ``module`` (linearizers)
    residual_unit: str
    montecarlo_kernel: str | None  # in boresight.core.algorithms.batched
    summary: str
    reference: str  # equations in docs/references.md's [Kiev2012]


_ROWS = (
    Algorithm(
        "image_plane",
        ("alg3",),
        "linearizer",
        "boresight.core.algorithms.image_plane",
        "linearize",
        "residual_map",
        "m (focal plane)",
        "image_plane_kernel",
        "Algorithm 3: focal-plane residuals, Gauss–Newton",
        "Kiev 2012 eqs 19-22",
    ),
    Algorithm(
        "ground_plane",
        ("alg2",),
        "linearizer",
        "boresight.core.algorithms.ground_plane",
        "linearize",
        "residual_map",
        "m (ground, east/north)",
        "ground_plane_kernel",
        "Algorithm 2: ground-plane residuals",
        "Kiev 2012 eqs 14-18",
    ),
    Algorithm(
        "unit_vector",
        ("eq31",),
        "linearizer",
        "boresight.core.algorithms.unit_vector",
        "linearize",
        "residual_map",
        "rad",
        "unit_vector_kernel",
        "unit-vector (direction) residuals",
        "Kiev 2012 eqs 29-31",
    ),
    Algorithm(
        "homography",
        ("alg1",),
        "estimator",
        "boresight.core.algorithms.homography",
        "estimate_alg1",
        None,
        "m (focal plane)",
        None,
        "Algorithm 1: homography per image, no GNSS",
        "Kiev 2012 eqs 4-13",
    ),
    Algorithm(
        "kalman",
        ("eq32",),
        "estimator",
        "boresight.core.algorithms.kalman",
        "estimate_kalman",
        None,
        "m (focal plane)",
        None,
        "Kalman filter with shared-error (bias, catalogue) states",
        "Kiev 2012 eq 32",
    ),
    Algorithm(
        "line_scan",
        ("pushbroom",),
        "estimator",
        "boresight.core.line_scan",
        "estimate_lines",
        None,
        "m (focal plane)",
        None,
        "pushbroom lines: θ with the line's own unknowns, GLS on the attitude-sample table",
        "Kiev 2012 eq 24; docs/pushbroom.md",
    ),
    Algorithm(
        "kalman_theta",
        (),
        "study",
        "boresight.core.algorithms.batched",
        None,
        None,
        "m (focal plane)",
        "kalman_theta_kernel",
        "θ-only Kalman filter, R_n at the nominal geometry (Monte Carlo study)",
        "Kiev 2012 eq 32",
    ),
)

#: name → Algorithm, in the table's order
ALGORITHMS = {a.name: a for a in _ROWS}
_ALIASES = {alias: a.name for a in _ROWS for alias in a.aliases}


def lookup(name: str) -> Algorithm:
    """The table row of a name or alias; ``UnknownAlgorithmError`` (a ``ValueError``) listing the valid names."""
    key = _ALIASES.get(name, name)
    if key not in ALGORITHMS:
        from orbits.errors import did_you_mean

        raise UnknownAlgorithmError(
            f"unknown algorithm {name!r}{did_you_mean(name, names(aliases=True))}; expected one of {names(aliases=True)}"
        )
    return ALGORITHMS[key]


def names(kind: str | None = None, *, aliases: bool = False) -> list[str]:
    """Names (of ``kind``, or all), with their aliases if ``aliases``, sorted."""
    rows = [a for a in _ROWS if kind is None or a.kind == kind]
    out = {a.name for a in rows}
    if aliases:
        out |= {x for a in rows for x in a.aliases}
    return sorted(out)


def estimator_names(*, aliases: bool = True) -> list[str]:
    """What ``estimate(obs, algorithm=...)`` accepts from the table (linearizers and estimators)."""
    return sorted(set(names("linearizer", aliases=aliases)) | set(names("estimator", aliases=aliases)))


def names_text(kinds: tuple[str, ...] = ("linearizer", "estimator")) -> str:
    """Each name of ``kinds`` in the table's order with its aliases after it — how a help text lists them, so a
    reader sees which words are one algorithm.

    >>> names_text()
    'image_plane (alg3), ground_plane (alg2), unit_vector (eq31), homography (alg1), kalman (eq32), line_scan (pushbroom)'
    """
    return ", ".join(a.name + (f" ({', '.join(a.aliases)})" if a.aliases else "") for a in _ROWS if a.kind in kinds)


def montecarlo_names() -> tuple[str, ...]:
    """Algorithms with a Monte Carlo kernel, in the table's order ("all" in the CLI means these)."""
    return tuple(a.name for a in _ROWS if a.montecarlo_kernel)


def least_squares_names() -> tuple[str, ...]:
    """The least-squares algorithms with a Monte Carlo kernel ("least_squares" in the CLI)."""
    return tuple(a.name for a in _ROWS if a.kind == "linearizer" and a.montecarlo_kernel)


# ---- the run-time table: what ``estimate`` calls for a name (built-in rows are loaded on first
# use; ``register_algorithm`` adds or replaces names)
@dataclass(frozen=True)
class Registered:
    """A callable ``estimate`` can dispatch to."""

    func: Callable[..., Any]
    kind: str  # "linearizer" | "estimator"
    residual_map: Callable[..., Any] | None = None
    residual_unit: str = ""


_RUNTIME: dict[str, Registered] = {}
_RUNTIME_ALIASES: dict[str, str] = {}


def register_algorithm(
    name: str,
    func: Callable[..., Any],
    *,
    kind: str = "estimator",
    residual_map: Callable[..., Any] | None = None,
    residual_unit: str = "",
    aliases: tuple[str, ...] = (),
) -> None:
    """Make ``estimate(obs, algorithm=name)`` available.

    ``kind="estimator"``: ``func(obs, *, weighting, iterate, model, prior_sigma_arcsec,
    **options) -> Estimate`` does everything itself. ``kind="linearizer"``:
    ``func(obs, theta_rad) -> (G (R, K, 2, 3), q (R, K, 2))`` (one row per observation of the row
    set ``obs``) joins the shared Gauss-Newton loop; give ``residual_map(obs, theta_rad) -> L (R, K, 2, 2)``
    to allow weighted forms.
    Re-registering a name replaces it.

    >>> register_algorithm("demo", lambda obs, **kw: None, aliases=("d",))
    >>> "demo" in algorithms() and "d" in algorithms()
    True
    """
    if kind not in ("estimator", "linearizer"):
        raise InputValueError(f"register_algorithm: kind must be 'estimator' or 'linearizer', got {kind!r}")
    if not callable(func):
        raise InputValueError(f"register_algorithm: func for {name!r} is not callable")
    _RUNTIME[name] = Registered(func, kind, residual_map, residual_unit)
    for a in aliases:
        _RUNTIME_ALIASES[a] = name


def algorithms() -> list[str]:
    """Every algorithm name and alias ``estimate`` accepts: the table's (complete without importing
    the algorithm modules) and any registered at run time with ``register_algorithm``."""
    return sorted(set(estimator_names()) | set(_RUNTIME) | set(_RUNTIME_ALIASES))


def _load(row: Algorithm) -> None:
    """Register a built-in row: import its module (lazily, on first use) and take its functions."""
    import importlib

    module = importlib.import_module(row.module)
    assert row.function is not None  # every linearizer and estimator row names its function
    register_algorithm(
        row.name,
        getattr(module, row.function),
        kind=row.kind,
        residual_map=getattr(module, row.residual_map) if row.residual_map else None,
        residual_unit=row.residual_unit,
        aliases=row.aliases,
    )


def resolve(algorithm: str) -> tuple[str, Registered]:
    """(name, ``Registered``) of a name or alias ``estimate`` accepts; a run-time registration of a
    name wins over the table's row. ``UnknownAlgorithmError`` (one line, with the valid names) for
    an unknown name or a Monte Carlo study kernel."""
    if not isinstance(algorithm, str):
        raise InputTypeError.expected("estimate", "algorithm", f"an algorithm's name (one of {list(ALGORITHMS)})", algorithm)
    name = _RUNTIME_ALIASES.get(algorithm, algorithm)
    if name in _RUNTIME:
        return name, _RUNTIME[name]
    key = _ALIASES.get(algorithm, algorithm)
    row = ALGORITHMS.get(key)
    if row is not None and row.kind == "study":
        raise UnknownAlgorithmError(
            f"estimate: {algorithm!r} is a Monte Carlo study kernel ({row.summary}), not an estimator; "
            f"expected one of {algorithms()}"
        )
    if row is None:
        from orbits.errors import did_you_mean

        raise UnknownAlgorithmError(
            f"estimate: unknown algorithm {algorithm!r}{did_you_mean(algorithm, algorithms())}; expected one of {algorithms()}"
        )
    if row.name not in _RUNTIME:
        _load(row)
    return row.name, _RUNTIME[row.name]
