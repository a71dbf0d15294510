"""Figures of the studies (matplotlib, an optional dependency: the extra ``plot``, ``orbits.errors.extra_hint``).

Library code used alike by the commands (``montecarlo``, ``sensitivity``) and by the reproduction
report (``boresight.reproductions.kiev2012``). Each function takes a study result and a path, writes a PNG and
returns the path; matplotlib is imported inside, so importing this module costs nothing and a
missing matplotlib raises ``ImportError`` only when a figure is asked for. Commands and reports ask
``available()`` / ``want_figures()`` first and skip their figures with one note (``MISSING``).

DECISION: every figure of the package is a ``matplotlib.figure.Figure`` on its own Agg canvas
(``figure``), never ``pyplot``: no global state (no figure manager to close, no backend switch that
could surprise a caller's own pyplot session) and no pyplot import (~0.1–0.2 s of start-up for a
command that draws one figure).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from orbits.errors import extra_hint

__all__ = [
    "available",
    "want_figures",
    "MISSING",
    "figure",
    "plot_histograms",
    "plot_sigma_vs_images",
    "plot_sensitivity_bars",
    "plot_kalman_table",
]

#: the one sentence every command prints when it skips its figures for want of matplotlib
MISSING = f"matplotlib is not installed: figures skipped ({extra_hint('plot')}); every other output is written"


def available() -> bool:
    """True when matplotlib and its Agg canvas can be imported: the one "plots available?" check
    of every command and report (code review 2026-11-27 §7.3 found four copies in three
    wordings on two streams, and two commands without one that exited 70)."""
    try:
        import matplotlib  # noqa: F401
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: F401
    except ImportError:
        return False
    return True


def want_figures(requested: bool = True) -> bool:
    """Whether a command draws its figures: ``requested`` (not ``--no-plots``) and ``available()``.
    When requested but matplotlib is missing, prints ``MISSING`` once on stdout, as a ``note``
    line like the command's other lines, and returns False.

    DECISION: stdout, not stderr: figures skipped is an outcome of the run (exit 0, everything
    else written), reported beside the ``wrote`` lines that list what was written."""
    if not requested:
        return False
    if available():
        return True
    print(f"note          {MISSING}")
    return False


def figure(**kwargs):
    """A ``matplotlib.figure.Figure(**kwargs)`` attached to an Agg canvas (files only, no display,
    no pyplot): draw on it, write it with ``outputs.save_figure``, and let it be collected."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def _panels(height_in: float = 3.6, bottom_in: float = 0.55, top_in: float = 0.45, **kwargs):
    """A figure of three panels side by side (one per axis x, y, z) and its axes; ``bottom_in``
    inches below the panels for the axis labels (and what a figure puts under them), ``top_in``
    above them for the title (and the panels' own titles).

    DECISION: fixed margins, not the constrained layout, which measured every artist's
    extent at each save and was about a third of a study's figure time."""
    fig = figure(figsize=(12, height_in))
    fig.subplots_adjust(left=0.055, right=0.99, top=1.0 - top_in / height_in, bottom=bottom_in / height_in, wspace=0.28)
    return fig, fig.subplots(1, 3, **kwargs)


def _save(fig, title: str, path: Path) -> Path:
    fig.suptitle(title)
    from boresight.reporting.outputs import save_figure

    save_figure(fig, path, dpi=110)  # atomic: never a half-written PNG
    return path


def _same_curves(result, j: int, i: int) -> list[list[str]]:
    """Algorithms grouped when their errors agree run by run to within 1 % of σ on axis ``i`` —
    indistinguishable in a histogram (the least-squares algorithms agree to ~0.1 % of σ on the
    seminar's data): one curve and one legend entry per group, the names joined by ≈."""
    groups: list[list[str]] = []
    for name in result.algorithms:
        x = result.samples[name][:, j, i]
        for g in groups:
            ref = result.samples[g[0]][:, j, i]
            if np.max(np.abs(ref - x), initial=0.0) <= 0.01 * max(float(np.std(ref)), 1e-12):
                g.append(name)
                break
        else:
            groups.append([name])
    return groups


def plot_histograms(result, path: Path) -> Path:
    """Histograms of θ errors per axis (the largest number of images): one curve per distinct
    algorithm (algorithms with identical errors share a curve and a legend entry), with the normal
    density of the σ each estimator predicts overlaid where it is known (``result.predicted``) and
    the legend below the panels, off the data."""
    fig, axes = _panels(4.4, bottom_in=1.0)
    j = len(result.image_counts) - 1
    handles: dict[Any, Any] = {}
    for i, ax in enumerate(axes):
        for k, group in enumerate(_same_curves(result, j, i)):
            x = result.samples[group[0]][:, j, i]
            sd = result.moments[group[0]].std[j, i]
            label = f"{' ≈ '.join(group)}: sample"
            _, edges, patch = ax.hist(x, bins=80, histtype="step", color=f"C{k}", label=label)
            handles.setdefault(label, patch[0])
            ax.text(0.02, 0.97 - 0.07 * k, f"σ {sd:.2f}″", transform=ax.transAxes, color=f"C{k}", va="top", fontsize=8)
            pred = result.predicted.get(group[0]) if getattr(result, "predicted", None) else None
            if pred is not None:
                ps = float(np.asarray(pred)[j, i])
                grid = np.linspace(edges[0], edges[-1], 200)
                dens = len(x) * (edges[1] - edges[0]) * np.exp(-0.5 * (grid / ps) ** 2) / (ps * np.sqrt(2 * np.pi))
                (line,) = ax.plot(grid, dens, "--", color=f"C{k}", lw=1)
                handles.setdefault(f"{' ≈ '.join(group)}: normal density of the predicted σ", line)
        ax.set_xlabel(f"θ{'xyz'[i]} error θ̂ − θ (arcsec)")
        ax.set_ylabel("runs per bin")
    fig.legend(
        list(handles.values()),
        list(handles),
        loc="lower center",
        ncol=min(3, len(handles)),
        fontsize=7,
        bbox_to_anchor=(0.5, 0.0),
    )
    shown = result.samples[result.algorithms[0]].shape[0]
    return _save(
        fig, f"{result.scenario_name}: θ̂ − θ, {result.image_counts[j]} image(s), {shown} runs shown of {result.runs}", path
    )


def plot_sigma_vs_images(result, path: Path, beta: float) -> Path:
    """σθ per axis versus the number of images, one line per algorithm, χ² intervals as bars."""
    from boresight.stats import sigma_interval

    fig, axes = _panels(sharex=True)
    n = np.asarray(result.image_counts)
    # DECISION: the algorithms often agree to a few parts in 10⁴ (image_plane, ground_plane and
    # unit_vector on the sensitivity case), so identical markers hid one curve under another: each
    # algorithm gets its own marker, line style and a small horizontal offset (a fraction of the gap
    # between image counts, on the log-free axis), drawn hollow so coincident points stay visible.
    markers, styles = "osD^vP", ("-", "--", ":", "-.", (0, (5, 1)), (0, (1, 1)))
    k = len(result.algorithms)
    gap = float(np.min(np.diff(n))) if n.size > 1 else 1.0
    for i, ax in enumerate(axes):
        for j, name in enumerate(result.algorithms):
            mo = result.moments[name]
            sd = mo.std[:, i]
            lo, hi = sigma_interval(sd, mo.count, beta)
            dx = (j - (k - 1) / 2) * 0.12 * gap / max(k - 1, 1)
            ax.errorbar(
                n + dx,
                sd,
                yerr=[sd - lo, hi - sd],
                marker=markers[j % len(markers)],
                linestyle=styles[j % len(styles)],
                mfc="none",
                capsize=3,
                label=name,
            )
        ax.set_xlabel("number of images")
        ax.set_ylabel(f"σθ{'xyz'[i]} (arcsec)")
        ax.set_xticks(n)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    return _save(
        fig, f"{result.scenario_name}: σθ vs number of images ({result.runs} runs); bars: {100 * beta:g} % χ² interval of σ", path
    )


def plot_sensitivity_bars(study, path: Path, algorithm: str) -> Path:
    """Error-budget bars: each source's σθ contribution per axis (linear) with the FD values."""
    from boresight.core.error_sources import ERROR_SOURCES, SOURCES

    fig, axes = _panels(4.2, bottom_in=0.95, top_in=0.7, sharey=True)
    lin = study.linear[study.linear["algorithm"] == algorithm]
    fd = study.fd[study.fd["algorithm"] == algorithm]
    x = np.arange(len(SOURCES))
    for i, (ax, a) in enumerate(zip(axes, "xyz")):
        ax.bar(x - 0.2, [lin[lin["source"] == s][0][f"contribution_{a}"] for s in SOURCES], 0.4, label="linear propagation")
        f = fd[[list(fd["source"]).index(s) for s in SOURCES]]
        coef_to_contrib = np.asarray(f[f"contribution_{a}"]) / np.where(
            np.asarray(f[f"coef_{a}"]) > 0, np.asarray(f[f"coef_{a}"]), np.inf
        )
        ax.bar(
            x + 0.2,
            f[f"contribution_{a}"],
            0.4,
            yerr=np.asarray(f[f"coef_se_{a}"]) * np.nan_to_num(coef_to_contrib),
            capsize=3,
            label="Monte Carlo finite difference (bars: ±1 standard error)",
        )
        ax.set_xticks(x, [ERROR_SOURCES[s].label for s in SOURCES], rotation=30, ha="right", fontsize=8)
        ax.set_title(f"θ{a}")
        ax.set_ylabel("σθ contribution a·σ (arcsec)")
    axes[0].legend(fontsize=7)
    return _save(fig, f"{study.scenario_name}: error budget per source ({algorithm})", path)


def plot_kalman_table(sem, ours, path: Path) -> Path:
    """σθ per axis versus the number of images: the seminar's eq 32 table (``sem``) and ours
    (``ours``: {label: table}), one panel per axis."""
    fig, axes = _panels(bottom_in=0.75)
    for i, (ax, a) in enumerate(zip(axes, "xyz")):
        ax.plot(sem["n_images"], sem[f"sigma_theta_{a}"], "ko-", label="seminar")
        for k, t in ours.items():
            ax.plot(t["n_images"], t[f"sigma_theta_{a}"], "o-", label=f"ours, {k}")
        ax.set_xlabel("number of images")
        ax.set_ylabel(f"σθ{a} (arcsec)")
        ax.set_xticks(np.asarray(sem["n_images"]))
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.text(
        0.5,
        0.01,
        "The seminar gives no geometry for this table: only the trends compare, and our curves are expected to "
        "differ from its values (docs/reproduction.md, 'Assumptions that explain the differences').",
        ha="center",
        fontsize=7,
        style="italic",
    )
    return _save(fig, "Kiev 2012 eq 32: Kalman filter σθ vs number of images", path)
