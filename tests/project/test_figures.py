"""Every figure the commands write is rendered here and read as a reviewer would: each axis has a
label with its unit, error bars state their level, categories are drawn as categories, error
sources carry the names of the tables (``σK (pixel)``, not ``K``), the Monte Carlo histogram
overlays the predicted σ and keeps its legend off the data, and the residual map has an arrow
scale.

The figures are captured at ``save_figure`` (the one place every PNG is written), so the test
reads the matplotlib objects — labels, legends, tick labels — rather than pixels.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

UNIT = re.compile(r"\((arcsec|µm|mm|m|s|″|s from .*)\)|runs|number of images")


@pytest.fixture
def figures(monkeypatch):
    """Capture every figure saved through boresight.reporting.outputs.save_figure: {file name: texts}."""
    import boresight.reporting.outputs as outputs

    got = {}
    real = outputs.save_figure

    def capture(fig, path, **kw):
        texts = {
            "suptitle": fig._suptitle.get_text() if fig._suptitle else "",
            "figtext": [t.get_text() for t in fig.texts],
            "axes": [],
            "legends": [t.get_text() for lg in fig.legends for t in lg.get_texts()],
        }
        for ax in fig.axes:
            lg = ax.get_legend()
            texts["axes"].append(
                {
                    "x": ax.get_xlabel(),
                    "y": ax.get_ylabel(),
                    "title": ax.get_title() + ax.get_title("left"),
                    "xticks": [t.get_text() for t in ax.get_xticklabels()],
                    "legend": [t.get_text() for t in lg.get_texts()] if lg else [],
                    "quiverkeys": [c for c in ax.artists + ax.get_children() if type(c).__name__ == "QuiverKey"],
                }
            )
        name = re.sub(r"^\.(.*)\.tmp-\d+(\.\w+)$", r"\1\2", Path(path).name)  # files.atomic_path's temporary name
        got[name] = texts
        return real(fig, path, **kw)

    monkeypatch.setattr(outputs, "save_figure", capture)
    import boresight.cli.estimate as est_cli

    monkeypatch.setattr(est_cli, "save_figure", capture)
    return got


def _labelled(ax):
    return bool(UNIT.search(ax["x"])) and bool(UNIT.search(ax["y"]) or "contribution" in ax["y"])


def _study_with_figures(command, scenario, runs, algorithm, out):
    """``boresight COMMAND SCENARIO --runs RUNS --algorithm ALGORITHM`` on one worker, quiet, its figures drawn
    into ``out``: it must exit 0."""
    from boresight.cli.main import main

    argv = [command, scenario, "--runs", str(runs), "--algorithm", algorithm, "--workers", "1", "-q", "--out", str(out)]
    assert main(argv) == 0


def test_montecarlo_figures(figures, tmp_path):
    _study_with_figures("montecarlo", "kiev2012-kalman20", 400, "all", tmp_path)
    hist, sig = figures["theta_error_histograms.png"], figures["sigma_vs_images.png"]
    assert all(_labelled(ax) for ax in hist["axes"]) and all(_labelled(ax) for ax in sig["axes"])
    assert any("predicted σ" in t for t in hist["legends"]), hist["legends"]  # the overlay
    assert all(ax["legend"] == [] for ax in hist["axes"]), "the histogram's legend is outside the panels"
    assert "≈" in " ".join(hist["legends"]), "algorithms with equal errors share one curve"
    assert "interval" in sig["suptitle"], "error bars state their level"
    assert all(ax["xticks"] and all(re.fullmatch(r"\d+", t) for t in ax["xticks"] if t) for ax in sig["axes"]), (
        "image counts are ticks at the counts"
    )


def test_sensitivity_figure_names_sources_as_the_tables(figures, tmp_path):
    from boresight.core.error_sources import ERROR_SOURCES

    _study_with_figures("sensitivity", "kiev2012-sensitivity", 300, "image_plane", tmp_path)
    (fig,) = figures.values()
    labels = {s.label for s in ERROR_SOURCES.values()}
    for ax in fig["axes"]:
        assert set(t for t in ax["xticks"] if t) == labels, ax["xticks"]
    assert any("standard error" in t for ax in fig["axes"] for t in ax["legend"]), "the bars' level is stated"


def test_estimate_residual_map_has_an_arrow_scale(figures, tmp_path):
    from boresight.cli.main import main

    assert main(["simulate", "kiev2012-kalman20", "--seed", "2", "--out", str(tmp_path)]) == 0
    assert main(["estimate", str(tmp_path / "kiev2012-kalman20.ecsv"), "--out", str(tmp_path / "e"), "-q"]) == 0
    quiver, time = figures["residuals_image_plane.png"], figures["residuals_time.png"]
    assert quiver["axes"][0]["quiverkeys"], "an arrow-scale key"
    assert all(_labelled(ax) for ax in quiver["axes"])
    assert _labelled(time["axes"][-1]) and all(UNIT.search(ax["y"]) for ax in time["axes"])


def test_kalman_reproduction_figure_says_the_difference_is_expected(figures, tmp_path):
    from boresight.reporting.plots import plot_kalman_table

    sem = {"n_images": np.array([1, 2, 4]), **{f"sigma_theta_{a}": np.array([3.0, 2.0, 1.5]) for a in "xyz"}}
    plot_kalman_table(sem, {"per image": sem}, tmp_path / "k.png")
    fig = figures["k.png"]
    assert any("expected" in t and "reproduction.md" in t for t in fig["figtext"])
    assert all(_labelled(ax) for ax in fig["axes"])
