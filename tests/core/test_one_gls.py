"""One error-structure builder and one GLS in the library; the deliberate oracles pinned (issue 18).

``boresight.core.gls.structure`` builds the nuisance columns of the disturbance model from
``disturbances.error_jacobians``; ``boresight.core.gls.rows`` is the one GLS (``gls.campaign`` adapts
the callers still on the dense set to it). A module that calls
``error_jacobians`` builds (a piece of) the error structure again — allowed only for the builder, for
the deliberately independent oracle ``boresight.core.crlb`` (``oracles.LIBRARY_ORACLES``) and for the
Kalman filter, which carries some errors as states (its H columns, not a covariance).
"""

import ast
import importlib

from oracles import LIBRARY_ORACLES
from paths import ROOT

PKG = ROOT / "boresight"

#: modules (relative to boresight/) allowed to call ``error_jacobians``
ALLOWED_CALLERS = {
    "core/gls/structure.py",  # the one builder
    "core/crlb.py",  # the deliberately independent dense route (an oracle)
    "core/algorithms/kalman.py",  # state columns of the filter (H), not an error structure
}
#: second copies still to be moved onto the builder; the test fails when one disappears (remove it)
KNOWN_SECOND_COPIES: set = set()


def _calls(path, name):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            if (isinstance(f, ast.Name) and f.id == name) or (isinstance(f, ast.Attribute) and f.attr == name):
                return True
    return False


def _defines(path, names):
    tree = ast.parse(path.read_text())
    return {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and n.name in names}


def test_error_jacobians_only_in_the_builder_and_the_oracles():
    callers = {str(p.relative_to(PKG)) for p in PKG.rglob("*.py") if _calls(p, "error_jacobians")}
    assert callers - ALLOWED_CALLERS == KNOWN_SECOND_COPIES, (
        "a module builds the error structure again: call boresight.core.gls.structure"
    )


def test_no_second_builder_or_dense_gls_in_the_library():
    """The dense routes live in tests/oracles.py; ``_modes`` (the error-mode parsing) once."""
    banned = {
        "dense_gls_reference",
        "error_structure",
        "ErrorStructure",
        "nuisance_columns",
        "_reduced_products",
        "_scaled_columns",
        "_slot_error_jacobians",
    }
    found = {str(p.relative_to(PKG)): _defines(p, banned | {"_modes"}) for p in PKG.rglob("*.py")}
    found = {k: v for k, v in found.items() if v}
    assert set(found) <= KNOWN_SECOND_COPIES, found


def test_one_gls_on_rows():
    """The GLS is ``gls.rows``: only the modules that build rows call ``row_gls`` — ``gls.campaign`` (``fit_rows``:
    estimate, diagnose, the variance components, the planner) and the consumers on rows that build their own columns
    (the pushbroom estimator, its diagnosis and its planner's Fisher blocks, the robust losses' sandwich on lines,
    sensitivity's per-source propagation on lines) —, only it
    factorises the reduced system (``splu``), and the slot-layout square-root GLS it replaced is not back."""
    callers = {str(p.relative_to(PKG)) for p in PKG.rglob("*.py") if _calls(p, "row_gls")}
    allowed = {
        "core/gls/campaign.py",
        "core/line_scan.py",
        "core/robust.py",
        "studies/discrepancy/line_scan.py",
        "studies/planning/line_scan.py",
        "studies/sensitivity.py",
    }
    assert callers <= allowed, callers
    assert {str(p.relative_to(PKG)) for p in PKG.rglob("*.py") if _calls(p, "splu")} == {"core/gls/rows.py"}
    old = {"_eliminate_images", "_eliminate_passes", "_eliminate_landmarks", "_qr_stack", "_landmark_groups"}
    found = {str(p.relative_to(PKG)): _defines(p, old) for p in PKG.rglob("*.py")}
    assert not {k: v for k, v in found.items() if v}


def test_the_library_oracles_exist_and_say_so():
    for dotted in LIBRARY_ORACLES:
        mod, name = dotted.rsplit(".", 1)
        assert callable(getattr(importlib.import_module(mod), name)), dotted
    doc = importlib.import_module("boresight.core.crlb").__doc__
    assert "deliberately independent" in doc
