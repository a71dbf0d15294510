"""The front door (``boresight/__init__.py``'s ``_EXPORTS``): every name is defined under the name
it is exported as, and documented in numpydoc's sections (rendered as tables by napoleon in the
API reference).

Rules, per kind of object:

* a function: ``Parameters``, ``Returns`` and ``Raises`` (every entry point refuses bad input with
  a typed error, so every one has something to say under ``Raises``);
* a class that is not an exception: ``Parameters`` or ``Attributes``;
* an exception: a docstring (its constructor is the message).

``UNDOCUMENTED`` (empty) would list sections still missing; it may only shrink (the test fails when an
entry is no longer needed).
"""

import importlib
import inspect
import re

import pytest

import boresight

#: (exported name, missing section) still undocumented; empty, and to stay so
UNDOCUMENTED: set[tuple[str, str]] = set()


def _resolve(name):
    module, attr = boresight._EXPORTS[name]
    return attr, getattr(importlib.import_module(module), attr)


def sections(doc: str) -> set:
    """The numpydoc section titles of a docstring (a title line underlined with dashes).

    >>> sorted(sections("Text.\\n\\nParameters\\n----------\\nx : int\\n\\nReturns\\n-------\\nint\\n"))
    ['Parameters', 'Returns']
    """
    return set(re.findall(r"^[ \t]*(\w[\w ]*?)[ \t]*\n[ \t]*-{3,}[ \t]*$", doc or "", re.M))


def _missing(obj) -> list:
    have = sections(inspect.getdoc(obj) or "")
    if inspect.isclass(obj) and issubclass(obj, BaseException):
        return []
    if inspect.isclass(obj):
        return [] if have & {"Parameters", "Attributes"} else ["Parameters or Attributes"]
    return [s for s in ("Parameters", "Returns", "Raises") if s not in have]


@pytest.mark.parametrize("name", sorted(boresight._EXPORTS))
def test_export_is_defined_under_its_name(name):
    attr, obj = _resolve(name)
    assert attr == name, f"boresight.{name} is {attr} in its module: define it as {name}"
    assert getattr(obj, "__name__", name) == name, f"boresight.{name}.__name__ is {obj.__name__}"
    assert inspect.getdoc(obj), f"boresight.{name} has no docstring"


def test_every_export_has_its_numpydoc_sections():
    missing = {(name, s) for name in boresight._EXPORTS for s in _missing(_resolve(name)[1])}
    new = sorted(missing - UNDOCUMENTED)
    gone = sorted(UNDOCUMENTED - missing)
    assert new == [], f"numpydoc sections missing from exported names: {new}"
    assert gone == [], f"documented now, remove from UNDOCUMENTED: {gone}"


def raised_names(doc: str) -> list:
    """The exception names a numpydoc ``Raises`` section lists (its unindented lines, comma-separated).

    >>> raised_names("Raises\\n------\\nInputTypeError, StudyError\\n    When.\\nValueError\\n    Other.\\n\\nNotes\\n-----\\nX\\n")
    ['InputTypeError', 'StudyError', 'ValueError']
    """
    m = re.search(r"^Raises\n-{3,}\n(.*?)(?=^\w[\w ]*\n-{3,}|\Z)", doc or "", re.M | re.S)
    lines = m.group(1).splitlines() if m else []
    return [n.strip() for line in lines if line and not line[0].isspace() for n in line.split(",")]


def untyped_raises(obj) -> list:
    """Names in ``obj``'s ``Raises`` section that are not a typed error of the one hierarchy
    (``boresight.errors``, ``orbits.errors``: each a ``BoresightError``)."""
    import boresight.errors
    import orbits.errors

    def typed(n):
        c = getattr(boresight.errors, n, getattr(orbits.errors, n, None))
        return isinstance(c, type) and issubclass(c, boresight.errors.BoresightError)

    return [n for n in raised_names(inspect.getdoc(obj) or "") if not typed(n)]


@pytest.mark.parametrize("name", sorted(n for n in boresight._EXPORTS if inspect.isfunction(_resolve(n)[1])))
def test_every_export_raises_typed_errors(name):
    """What an entry point's ``Raises`` section lists is a typed error of the hierarchy, under the name it
    has there (a stale or misspelt name, or a bare ``ValueError``, fails)."""
    obj = _resolve(name)[1]
    assert raised_names(inspect.getdoc(obj) or ""), f"boresight.{name}: no exception named under Raises"
    assert untyped_raises(obj) == []


def undocumented_fields(cls) -> list:
    """The fields of dataclass ``cls`` its docstring never names (as ``name`` or in ``a, name : …``)."""
    import dataclasses

    doc = inspect.getdoc(cls) or ""
    return [f.name for f in dataclasses.fields(cls) if not re.search(rf"(?<![\w.]){re.escape(f.name)}(?!\w)", doc)]


@pytest.mark.parametrize("name", sorted(n for n in boresight._EXPORTS if __import__("dataclasses").is_dataclass(_resolve(n)[1])))
def test_every_field_of_an_exported_result_is_documented(name):
    """A result's fields are its API: each is named in the class docstring (its Attributes section)."""
    assert undocumented_fields(_resolve(name)[1]) == []


def test_the_section_rule_can_fail():
    def bare(x):
        """Prose only, no sections."""

    assert _missing(bare) == ["Parameters", "Returns", "Raises"]

    class Plain:
        """A class with prose only."""

    assert _missing(Plain) == ["Parameters or Attributes"]

    import dataclasses

    @dataclasses.dataclass
    class Result:
        """Attributes
        ----------
        theta, sigma : float
            Named.
        covariance_note : str
            Mentions ``theta_rad`` only (a longer name).
        """

        theta: float
        sigma: float
        covariance_note: str
        theta_r: float
        note: str

    assert undocumented_fields(Result) == ["theta_r", "note"]

    def loose(x):
        """Parameters
        ----------
        x : int

        Raises
        ------
        ValueError
            Bare.
        StudyError, ObservationEror
            A typed one and a misspelt one.
        """

    assert untyped_raises(loose) == ["ValueError", "ObservationEror"]


def test_one_version():
    """The version is written once, ``boresight.__version__``; ``pyproject.toml`` reads it (``dynamic``)."""
    import tomllib

    from paths import ROOT

    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in cfg["project"] and "version" in cfg["project"]["dynamic"]
    assert cfg["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "boresight.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", boresight.__version__)
