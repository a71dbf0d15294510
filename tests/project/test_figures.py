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
            "figure": fig,
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


def test_sigma_vs_images_names_the_curves_that_coincide(figures, tmp_path):
    """Three algorithms: two whose σθ differ by 2e-4 relative (overlapping curves), one 2 % apart.
    The figure names the pair, with the difference it measured, and not the third."""
    from types import SimpleNamespace

    from boresight.reporting.plots import plot_sigma_vs_images

    n = np.array([1, 2, 4])
    base = np.array([[6.0, 6.1, 8.0], [4.3, 4.3, 5.7], [3.0, 3.1, 4.3]])
    std = {"image_plane": base, "unit_vector": base * (1 + 2e-4), "ground_plane": base * 1.02}
    result = SimpleNamespace(
        scenario_name="s",
        runs=400,
        image_counts=n,
        algorithms=list(std),
        moments={k: SimpleNamespace(std=v, count=np.full(3, 400)) for k, v in std.items()},
    )
    plot_sigma_vs_images(result, tmp_path / "s.png", 0.9973)
    (note,) = [t for t in figures["s.png"]["figtext"] if "coincide" in t]
    assert note.startswith("image_plane, unit_vector coincide") and "2.0e-04" in note, note
    assert "ground_plane" not in note


def test_residual_map_arrows_are_visible_and_flag_a_systematic_mean(figures, tmp_path):
    """Four landmarks seen in 20 images, residual scatter 10 µm, one landmark with a 20 µm systematic
    offset (its mean's T² ≈ 20·(20/10)² = 80 ≫ 7.5, the 5 % point; the others' scatter centred: T² = 0): the title counts exactly that one,
    its arrow is drawn in the 'differs' colour, and the longest arrow spans ≥ 10 % of the points' spread
    (the means were sub-pixel specks when scaled with the scatter)."""
    from boresight.reporting.plots import plot_residual_map

    rng = np.random.default_rng(3)
    centres = np.array([[-20e-3, -20e-3], [20e-3, -20e-3], [-20e-3, 20e-3], [20e-3, 20e-3]])
    target = np.repeat(np.arange(4), 20)
    xy = centres[target] + rng.normal(0, 1e-4, (80, 2))
    res = rng.normal(0, 10e-6, (80, 2))
    for m in range(4):  # zero-mean scatter (T² = 0: no landmark flagged by chance), then the one offset
        res[target == m] -= res[target == m].mean(axis=0)
    res[target == 2] += [20e-6, 0.0]
    plot_residual_map(xy, res, target, 20, tmp_path / "r.png")
    fig = figures["r.png"]
    assert "1 of 4 landmarks' mean residual differs from 0 at 5 %" in fig["axes"][0]["title"], fig["axes"][0]["title"]
    assert any("differs from 0" in t for t in fig["axes"][0]["legend"])
    ax = fig["figure"].axes[0]
    quivers = [c for c in ax.collections if type(c).__name__ == "Quiver"]
    longest = max(float(np.max(np.hypot(q.U, q.V))) for q in quivers)
    assert longest >= 0.1 * 40, f"longest arrow {longest:.3g} mm of a 40 mm spread"
    assert max(q.zorder for q in quivers) > max(c.zorder for c in ax.collections if type(c).__name__ == "PathCollection")


def test_plan_figure_has_a_cost_unit_and_drops_no_candidate(figures, monkeypatch, tmp_path):
    """plan.png of the shipped kiev680 plan: both cost axes carry the plan's ``[cost] unit``
    (pass-equivalents by default: a pass costs 1), and in each panel every candidate of the drawn
    sample (20 000 of 74 612) is a point — the ones with σθ/target or η = ∞ as a marked row at 10⁴ (matplotlib would
    skip an inf silently) —, except those the label says were not scored in full."""
    import json

    import boresight.reporting.outputs as outputs
    import boresight.studies.planning.report as plan_report
    from boresight.cli.main import main

    monkeypatch.setattr(plan_report, "save_figure", outputs.save_figure)  # the fixture's capture
    assert main(["plan", "kiev680", "--out", str(tmp_path)]) == 0
    scored = json.loads((tmp_path / "plan.json").read_text())["scored"]
    fig = figures["plan.png"]
    assert [ax["x"] for ax in fig["axes"]] == ["cost (pass-equivalents)"] * 2
    for ax in fig["figure"].axes:
        lines = {ln.get_label(): len(ln.get_xdata()) for ln in ax.get_lines()}
        cand = next(k for k in lines if k.startswith("candidates"))
        unscored = int(re.search(r"(\d+) of them dominated", cand).group(1)) if "dominated" in cand else 0
        inf_row = [k for k in lines if "= ∞" in k and "drawn at 10⁴" in k]
        assert inf_row, f"the ∞ row is marked and named: {list(lines)}"
        assert lines[cand] + lines[inf_row[0]] == min(scored, 20000) - unscored, lines


def test_residual_map_takes_a_landmark_pass_by_pass(figures, tmp_path):
    """One landmark seen in two passes, 10 images each, at two places on the focal plane, with a 20 µm
    offset of opposite sign in each pass (scatter centred, so T² = 0 without the offset): pooled, the
    two offsets cancel; pass by pass, both means differ from 0 and the title counts 2 of 2."""
    from boresight.reporting.plots import plot_residual_map

    rng = np.random.default_rng(4)
    passes = np.repeat([0, 1], 10)
    xy = np.where(passes[:, None] == 0, [-20e-3, 0.0], [20e-3, 0.0]) + rng.normal(0, 1e-4, (20, 2))
    res = rng.normal(0, 5e-6, (20, 2))
    for p in (0, 1):
        res[passes == p] -= res[passes == p].mean(axis=0)
    res[:, 0] += np.where(passes == 0, 20e-6, -20e-6)
    plot_residual_map(xy, res, np.zeros(20, int), 20, tmp_path / "p.png", pass_index=passes)
    assert "2 of 2 landmark-passes' mean residual differs from 0" in figures["p.png"]["axes"][0]["title"]
