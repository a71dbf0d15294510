"""Figures of the studies (matplotlib, an optional dependency: ``pip install 'boresight[plot]'``).

Library code used alike by the commands (``montecarlo``, ``sensitivity``) and by the reproduction
report (``boresight.reproductions.kiev2012``). Each function takes a study result and a path, writes a PNG and
returns the path; matplotlib is imported inside (with the non-interactive Agg backend), so
importing this module costs nothing and a missing matplotlib raises ``ImportError`` only when a
figure is asked for.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["pyplot", "plot_histograms", "plot_sigma_vs_images", "plot_sensitivity_bars", "plot_kalman_table"]


def pyplot():
    """``matplotlib.pyplot`` with the Agg backend (files only, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _panels(height_in: float = 3.6, **kwargs):
    """A figure of three panels side by side (one per axis x, y, z) and the pyplot module."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, height_in), constrained_layout=True, **kwargs)
    return plt, fig, axes


def _save(plt, fig, title: str, path: Path) -> Path:
    fig.suptitle(title)
    from boresight.reporting.outputs import save_figure

    save_figure(fig, path, dpi=110)  # atomic: never a half-written PNG
    plt.close(fig)
    return path


def plot_histograms(result, path: Path) -> Path:
    """Histograms of θ errors per axis (the largest number of images), one curve per algorithm."""
    plt, fig, axes = _panels()
    j = len(result.image_counts) - 1
    for i, ax in enumerate(axes):
        for name in result.algorithms:
            x = result.samples[name][:, j, i]
            ax.hist(x, bins=80, histtype="step", label=f"{name} (σ {result.moments[name].std[j, i]:.2f}″)")
        ax.set_xlabel(f"θ{'xyz'[i]} error (arcsec)")
        ax.set_ylabel("runs")
        ax.legend(fontsize=7)
    shown = result.samples[result.algorithms[0]].shape[0]
    return _save(plt, fig, f"{result.scenario_name}: θ̂ − θ, {result.image_counts[j]} image(s), {shown} runs shown of {result.runs}", path)


def plot_sigma_vs_images(result, path: Path, beta: float) -> Path:
    """σθ per axis versus the number of images, one line per algorithm, χ² intervals as bars."""
    from boresight.stats import sigma_interval

    plt, fig, axes = _panels(sharex=True)
    n = np.asarray(result.image_counts)
    for i, ax in enumerate(axes):
        for name in result.algorithms:
            mo = result.moments[name]
            sd = mo.std[:, i]
            lo, hi = sigma_interval(sd, mo.count, beta)
            ax.errorbar(n, sd, yerr=[sd - lo, hi - sd], marker="o", capsize=3, label=name)
        ax.set_xlabel("number of images")
        ax.set_ylabel(f"σθ{'xyz'[i]} (arcsec)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    return _save(plt, fig, f"{result.scenario_name}: σθ vs number of images ({result.runs} runs)", path)


def plot_sensitivity_bars(study, path: Path, algorithm: str) -> Path:
    """Error-budget bars: each source's σθ contribution per axis (linear) with the FD values."""
    from boresight.core.error_sources import SOURCES

    plt, fig, axes = _panels(3.8, sharey=True)
    lin = study.linear[study.linear["algorithm"] == algorithm]
    fd = study.fd[study.fd["algorithm"] == algorithm]
    x = np.arange(len(SOURCES))
    for i, (ax, a) in enumerate(zip(axes, "xyz")):
        ax.bar(x - 0.2, [lin[lin["source"] == s][0][f"contribution_{a}"] for s in SOURCES], 0.4, label="linear propagation")
        f = fd[[list(fd["source"]).index(s) for s in SOURCES]]
        coef_to_contrib = np.asarray(f[f"contribution_{a}"]) / np.where(np.asarray(f[f"coef_{a}"]) > 0, np.asarray(f[f"coef_{a}"]), np.inf)
        ax.bar(x + 0.2, f[f"contribution_{a}"], 0.4, yerr=np.asarray(f[f"coef_se_{a}"]) * np.nan_to_num(coef_to_contrib), capsize=3, label="Monte Carlo FD")
        ax.set_xticks(x, SOURCES)
        ax.set_title(f"θ{a}")
        ax.set_ylabel("σθ contribution a·σ (arcsec)")
    axes[0].legend(fontsize=7)
    return _save(plt, fig, f"{study.scenario_name}: error budget per source ({algorithm})", path)


def plot_kalman_table(sem, ours, path: Path) -> Path:
    """σθ per axis versus the number of images: the seminar's eq 32 table (``sem``) and ours
    (``ours``: {label: table}), one panel per axis."""
    plt, fig, axes = _panels()
    for i, (ax, a) in enumerate(zip(axes, "xyz")):
        ax.plot(sem["n_images"], sem[f"sigma_theta_{a}"], "ko-", label="seminar")
        for k, t in ours.items():
            ax.plot(t["n_images"], t[f"sigma_theta_{a}"], "o-", label=f"ours, {k}")
        ax.set_xlabel("number of images")
        ax.set_ylabel(f"σθ{a} (arcsec)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    return _save(plt, fig, "Kiev 2012 eq 32: Kalman filter σθ vs number of images", path)
