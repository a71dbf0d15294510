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
    "plot_residual_map",
    "plot_residuals_time",
]

#: the one sentence every command prints when it skips its figures for want of matplotlib
MISSING = f"matplotlib is not installed: figures skipped ({extra_hint('plot')}); every other output is written"


def available() -> bool:
    """True when matplotlib and its Agg canvas can be imported: the one "plots available?" check
    of every command and report (it replaced four copies in three wordings on two streams, and two
    commands without one exited 70)."""
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


#: the relative difference of σθ below which two algorithms' curves of ``sigma_vs_images`` are said to coincide
COINCIDE_REL = 1e-3


def _coinciding(result, tol: float = COINCIDE_REL) -> list[tuple[list[str], float]]:
    """Groups of ≥ 2 algorithms whose σθ agree at every image count and axis to ``tol`` relative
    to the group's first, each with its largest relative difference max |σ_a − σ_first| / σ_first."""
    groups: list[list[str]] = []
    worst: list[float] = []
    for name in result.algorithms:
        sd = np.asarray(result.moments[name].std, dtype=float)
        for g, members in enumerate(groups):
            ref = np.asarray(result.moments[members[0]].std, dtype=float)
            with np.errstate(invalid="ignore", divide="ignore"):
                rel = float(np.nanmax(np.abs(sd - ref) / ref, initial=0.0))
            if rel <= tol:
                members.append(name)
                worst[g] = max(worst[g], rel)
                break
        else:
            groups.append([name])
            worst.append(0.0)
    return [(members, w) for members, w in zip(groups, worst) if len(members) > 1]


def plot_sigma_vs_images(result, path: Path, beta: float) -> Path:
    """σθ per axis versus the number of images, one line per algorithm, χ² intervals as bars.
    Algorithms whose σθ agree to ``COINCIDE_REL`` at every point are named under the panels with the
    largest relative difference measured (their curves overlap: the offsets keep each visible)."""
    from boresight.stats import sigma_interval

    same = _coinciding(result)
    fig, axes = _panels(bottom_in=0.55 + 0.2 * len(same), sharex=True)
    n = np.asarray(result.image_counts)
    # DECISION: the algorithms often agree to a few parts in 10⁴ (image_plane, ground_plane and
    # unit_vector on the sensitivity case), so identical markers hid one curve under another: each
    # algorithm gets its own marker, line style and a small horizontal offset (a fraction of the gap
    # between image counts, on the log-free axis), drawn hollow so coincident points stay visible,
    # and the figure says which curves coincide, to the relative difference computed here.
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
    for row, (names, rel) in enumerate(same):
        fig.text(
            0.5,
            0.01 + row * 0.2 / fig.get_figheight(),
            f"{', '.join(names)} coincide: their σθ differ by at most {rel:.1e} of σθ (≤ {COINCIDE_REL:g}) at every "
            "image count and axis, so their curves overlap (offset sideways to stay visible)",
            ha="center",
            fontsize=7,
            style="italic",
        )
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


#: the confidence level of the residual map's ellipses about each landmark's mean residual
RESIDUAL_MAP_LEVEL = 0.95


def _landmark_means(xy_mm, d_um, group):
    """Per group of observations (a landmark in one pass), by one pass over the rows (no loop over
    groups): its mean point (mm), mean residual (µm), the residuals' sample covariance (ddof 1, as
    np.cov; 0 for a group of one, µm²) and its number of observations."""
    _, inv, cnt = np.unique(group, return_inverse=True, return_counts=True)
    at = np.stack([np.bincount(inv, xy_mm[:, i]) for i in range(2)], axis=-1) / cnt[:, None]
    mean = np.stack([np.bincount(inv, d_um[:, i]) for i in range(2)], axis=-1) / cnt[:, None]
    dev = d_um - mean[inv]
    outer = (dev[:, :, None] * dev[:, None, :]).reshape(-1, 4)
    S = np.stack([np.bincount(inv, outer[:, i], minlength=cnt.size) for i in range(4)], axis=-1).reshape(-1, 2, 2)
    covs = np.where((cnt > 1)[:, None, None], S / np.maximum(cnt - 1, 1)[:, None, None], 0.0)
    return at, mean, covs, cnt


def _round_key(mag: float) -> float:
    """A round length (1, 2 or 5 × 10ᵏ) not above ``mag``: the arrow of a scale key."""
    key = float(10 ** np.floor(np.log10(mag)))
    return next((k * key for k in (5, 2, 1) if k * key <= mag), key)


def plot_residual_map(xy_m, residual_m, target_index, n_images: int, path: Path, pass_index=None) -> Path:
    """The residuals on the focal plane at the estimated θ: ``xy_m`` (K, 2) measured points and
    ``residual_m`` (K, 2) measured − predicted, both in metres, ``target_index`` (K,) the landmark of
    each observation and ``pass_index`` (K,) its pass (None: one pass).

    With more than 3 images a landmark sits at nearly one place on the focal plane during a pass, and
    one arrow per observation would draw a starburst that shows neither a systematic part nor the
    scatter: each landmark in each pass gets instead its **mean residual** (at its mean point: in
    another pass it is seen elsewhere on the focal plane), an arrow drawn above the points and scaled so that
    the longest spans 15 % of the points' spread (the key gives the scale in µm). An arrow is red
    where the mean differs from 0 at 5 % — Hotelling's T² = n m̄ᵀ S⁻¹ m̄ from the landmark's own n
    residuals (``stats.hotelling_t2_isf``) — and blue where it does not; the title counts them and
    the legend gives the range of the means' 95 % confidence semi-axes (√(T²·λ(S/n))). With 3
    images or fewer every observation gets its own arrow.

    DECISION: the confidence of each mean is stated, not drawn as an ellipse at the arrows' scale. The
    residuals' scatter is dominated by the per-image star-tracker error, common to every landmark of
    an image, so its ellipses (at the same scale as the arrows) were all about the same size and
    dwarfed the means (sub-pixel specks under the points); a confidence ellipse of the mean is still
    several times the mean when nothing is missing. The test is conservative in that case: θ̂ takes
    the average of the common error out of every mean, which S / n still counts.
    """
    from boresight.stats import hotelling_t2_isf

    xy = np.asarray(xy_m, dtype=float) * 1e3  # mm
    d = np.asarray(residual_m, dtype=float) * 1e6  # µm
    fig = figure(figsize=(7.2, 7.4), layout="constrained")
    ax = fig.subplots()
    span = max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), 1e-9)
    many = n_images > 3
    ax.scatter(xy[:, 0], xy[:, 1], s=6, color="0.6", label="measured point", zorder=1)
    title = f"Residuals measured − predicted at the estimated θ (run 0, {n_images} image(s))"
    colour = np.full(len(xy) if not many else 0, "C3")
    labels = {"C3": "residual of each observation"}
    if many:
        tgt = np.asarray(target_index, dtype=np.int64)
        group = tgt if pass_index is None else np.asarray(pass_index, dtype=np.int64) * (int(tgt.max()) + 1) + tgt
        at, mean, covs, cnt = _landmark_means(xy, d, group)
        t2 = hotelling_t2_isf(1.0 - RESIDUAL_MAP_LEVEL, cnt)  # NaN for a landmark seen ≤ 2 times: no test
        se = covs / cnt[:, None, None]  # the mean's covariance S / n (µm²)
        with np.errstate(invalid="ignore"):
            t2_mean = np.einsum("li,lij,lj->l", mean, np.linalg.pinv(se), mean)
            semi = np.sqrt(np.maximum(np.linalg.eigvalsh(se), 0.0) * t2[:, None])  # (landmarks, 2) µm; NaN: untested
        tested = np.isfinite(t2)
        off = tested & (t2_mean > t2)
        colour = np.where(off, "C3", "C0")
        pct = f"{100 * (1 - RESIDUAL_MAP_LEVEL):g} %"
        lo, hi = (float(np.min(semi[tested])), float(np.max(semi[tested]))) if tested.any() else (np.nan, np.nan)
        labels = {
            "C3": f"mean residual of a landmark, differs from 0 at {pct}",
            "C0": f"mean residual, within its {100 * RESIDUAL_MAP_LEVEL:g} % confidence ellipse (semi-axes {lo:.2g}–{hi:.2g} µm)",
        }
        what = "landmarks'" if pass_index is None or np.unique(pass_index).size == 1 else "landmark-passes'"
        title += f"\n{int(off.sum())} of {int(tested.sum())} {what} mean residual differs from 0 at {pct} (Hotelling T²)"
    else:
        at, mean = xy, d
    mag = float(np.max(np.linalg.norm(mean, axis=-1))) or 1.0
    scale = 0.15 * span / mag  # mm of the plot per µm of residual
    q = None
    for c in ("C0", "C3"):  # the significant arrows last, on top
        sel = colour == c
        if not sel.any():
            continue
        q = ax.quiver(
            at[sel, 0],
            at[sel, 1],
            mean[sel, 0] * scale,
            mean[sel, 1] * scale,
            angles="xy",
            scale_units="xy",
            scale=1,
            color=c,
            width=0.004,
            zorder=3,
            label=labels[c],
        )
    key = _round_key(mag)
    ax.quiverkey(
        q,
        0.80,
        -0.13,
        key * scale,
        f"{key:g} µm (arrow scale)",
        labelpos="E",
        coordinates="axes",
        fontproperties={"size": 8},
    )
    ax.set_xlabel("x on the focal plane (mm)")
    ax.set_ylabel("y on the focal plane (mm)")
    ax.set_title(title, loc="left", fontsize=9)
    ax.update_datalim(at + mean * scale)  # the arrows' tips inside the axes (quiver does not extend the limits)
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.1), fontsize=8)  # below the axes: never hides data
    from boresight.reporting.outputs import save_figure

    save_figure(fig, path, dpi=110)
    return path


def plot_residuals_time(t_s, residual_m, z, epoch_utc: str, path: Path) -> Path:
    """The residuals against time, x and y in two panels (µm): ``t_s`` (K,) seconds from
    ``epoch_utc``, ``residual_m`` (K, 2) measured − predicted (m), ``z`` (K, 2) the same over its
    model σ (``Estimate.residual_z``) or None. With ``z`` a band of ±1σ of the noise model (r / z,
    the median over each image's observations) is drawn behind the points."""
    d = np.asarray(residual_m, dtype=float) * 1e6
    t = np.asarray(t_s, dtype=float)
    fig = figure(figsize=(8, 6), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        sd_obs = np.abs(d / np.asarray(z)) if z is not None else None
    for k, ax in enumerate(axes):
        if sd_obs is not None:
            ti = np.unique(t)
            band = np.array([np.nanmedian(sd_obs[t == v, k]) for v in ti])
            ax.fill_between(
                ti, -band, band, color=f"C{k}", alpha=0.15, lw=0, label="±1σ, the noise model (median over the image)"
            )
            ax.legend(loc="upper right", fontsize=8)
        ax.plot(t, d[:, k], ".", color=f"C{k}", ms=4)
        ax.axhline(0, color="0.6", lw=0.8)
        ax.set_ylabel(f"{'xy'[k]} residual (µm)")
    axes[-1].set_xlabel(f"t (s from {epoch_utc})")
    axes[0].set_title("Residuals against time (run 0)" + ("" if sd_obs is not None else "; no noise model: no σ band"))
    from boresight.reporting.outputs import save_figure

    save_figure(fig, path, dpi=110)
    return path
