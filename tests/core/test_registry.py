"""The one algorithm table (``boresight.core.registry``) and the one error-source table (``boresight.core.error_sources``)."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from paths import ROOT


def test_registry_is_complete_without_importing_any_algorithm_module():
    code = (
        "import sys, importlib, boresight.core.registry as r; e = importlib.import_module('boresight.core.estimation'); "
        "print(sorted(m for m in sys.modules if m in ('boresight.core.algorithms.kalman', 'boresight.core.algorithms.homography'))); "
        "print(e.algorithms())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True).stdout.splitlines()
    assert out[0] == "[]"
    listed = eval(out[1])
    for name in ("image_plane", "alg3", "ground_plane", "alg2", "unit_vector", "homography", "alg1", "kalman", "eq32"):
        assert name in listed
    assert "kalman_theta" not in listed  # a study kernel, not an estimator


def test_every_row_points_at_real_functions():
    import importlib

    from boresight.core import registry
    from boresight.core.algorithms import batched  # a submodule: loaded on use, not by the package (lazy)
    from boresight.studies import montecarlo

    for row in registry.ALGORITHMS.values():
        assert row.kind in registry.KINDS
        module = importlib.import_module(row.module)
        if row.function is not None:
            assert callable(getattr(module, row.function)), row
        if row.residual_map is not None:
            assert callable(getattr(module, row.residual_map)), row
        if row.montecarlo_kernel is not None:
            assert callable(getattr(batched, row.montecarlo_kernel)), row
    assert montecarlo.ALGORITHMS == registry.montecarlo_names()
    assert montecarlo.LEAST_SQUARES == ("image_plane", "ground_plane", "unit_vector")


def test_unknown_algorithm_lists_the_lazily_imported_ones_too():
    import boresight

    obs = boresight.simulate(ROOT / "scenarios/kiev2012-sensitivity.toml", np.random.default_rng(0), runs=1)
    with pytest.raises(ValueError, match=r"unknown algorithm 'nope'.*'alg1'.*'kalman'"):
        boresight.estimate(obs, algorithm="nope")
    with pytest.raises(ValueError, match="Monte Carlo study kernel"):
        boresight.estimate(obs, algorithm="kalman_theta")
    assert boresight.estimate(obs, algorithm="alg3").algorithm == "image_plane"


def test_montecarlo_kalman_is_refused_and_names_the_study_filter():
    from boresight.studies import montecarlo as mc

    # the library filter has no Monte Carlo kernel; the θ-only study filter is "kalman_theta"
    with pytest.raises(ValueError, match="'kalman'.*has no Monte Carlo kernel.*'kalman_theta'"):
        mc.resolve_algorithms(["kalman", "alg3"])
    assert mc.resolve_algorithms(["kalman_theta", "alg3"]) == ("kalman_theta", "image_plane")
    with pytest.raises(ValueError, match="has no Monte Carlo kernel"):
        mc.resolve_algorithms(["homography"])
    with pytest.raises(ValueError, match="algorithm must be one of"):
        mc.resolve_algorithms(["nope"])


def test_error_source_table_matches_the_models_and_the_simulator():
    import orbits
    from boresight.core.disturbances import DisturbanceModel
    from boresight.core.error_sources import ERROR_SOURCES, SOURCES, by_noise_key, source
    from orbits.rotations import ARCSEC

    sc = orbits.load_scenario(ROOT / "scenarios/kiev2012-sensitivity.toml")
    model = DisturbanceModel.from_scenario(sc)
    errors = orbits.draw_scenario_errors(sc, np.random.default_rng(0), runs=2)
    for s in SOURCES:
        row = ERROR_SOURCES[s]
        scen = getattr(sc, row.scenario_field)
        mod = getattr(model, row.model_field)
        if row.axis is None:
            assert mod == scen
        else:
            assert mod[row.axis] == pytest.approx(scen[row.axis] * ARCSEC, rel=1e-15)
        assert row.errors_key in errors
    assert len(by_noise_key("star_tracker")) == 3
    with pytest.raises(ValueError, match="unknown disturbance source 'Q'"):
        source("Q")


def test_scenario_takes_only_the_quantity_source_unit_names():
    from dataclasses import replace

    import orbits

    sc = orbits.load_scenario(ROOT / "scenarios/kiev2012-sensitivity.toml")
    assert not hasattr(sc, "pixel_sigma_m")
    with pytest.raises(TypeError, match="gnss_sigma_m"):
        replace(sc, gnss_sigma_m=3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert replace(sc, sigma_gnss_m=4.0).sigma_gnss_m == 4.0


def test_cli_refuses_a_registered_command_module_that_does_not_exist(monkeypatch):
    from boresight.cli import main as cli

    monkeypatch.setattr(cli, "_COMMAND_MODULES", cli._COMMAND_MODULES + ("boresight.cli.no_such_command",))
    with pytest.raises(ModuleNotFoundError, match="no_such_command"):
        cli.build_parser()


def test_error_source_scenario_keys_set_the_scenario_fields():
    import tomllib

    import orbits
    from boresight.core.error_sources import ERROR_SOURCES

    with open(ROOT / "scenarios/kiev2012-sensitivity.toml", "rb") as fh:
        base = tomllib.load(fh)
    for row in ERROR_SOURCES.values():
        d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
        table, key = row.scenario_key.split(".")
        value = [1.0, 2.0, 3.0] if row.axis is not None else 0.25  # inside every σ range
        d.setdefault(table, {})[key] = value
        sc = orbits.scenario_from_dict(d)
        got = getattr(sc, row.scenario_field)
        assert (got[row.axis] == value[row.axis]) if row.axis is not None else (got == value), row


def test_every_alias_is_documented_with_its_reason_and_the_spelling_alias_is_gone():
    """The aliases are the paper's names (the registry's docstring says which and why); an alias added
    without a line there fails, and ``unit-vector`` (a spelling, removed) is refused naming ``unit_vector``."""
    from boresight.core import registry

    for row in registry.ALGORITHMS.values():
        for alias in row.aliases:
            assert f"``{alias}``" in (registry.__doc__ or ""), alias
    with pytest.raises(ValueError, match="did you mean 'unit_vector'"):
        registry.resolve("unit-vector")
