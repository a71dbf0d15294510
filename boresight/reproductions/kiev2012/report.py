"""``boresight reproduce kiev2012``: regenerate ``docs/reproduction.md`` and its figures.

The report has four regenerated sections (``*_HEADING``), each ours side by side with the paper's:

* **Algorithm 1** (Kiev 2012) — its prose is kept verbatim from the existing report (the
  template) and its two tables are regenerated with ``kiev2012.algorithm1_table`` and
  ``algorithm1_variants``. ``algorithm1_section`` says whether the regenerated tables equal the
  ones in the template (they must before the file is overwritten).
* **Eq 28 sensitivity case** (Kiev 2012) — σθ per axis (Monte Carlo with χ² intervals and linear
  propagation) and the sensitivity table (FD, analytic, CRLB) under each assumption the
  seminar leaves open: one image vs ten, star-tracker and GNSS errors per image vs per pass.
  Every number in its prose is computed (``eq28_findings``).
* **Kalman variant (eq 32)** (Kiev 2012) — ``kiev2012.kalman_table`` (σθ and max |θ error| vs 1,
  2, 4, 8, 12, 20 images) with per-image and per-pass errors, against ``seminar_kalman_table``.
* **USV sea-sky** — the paper's 120 measured frames, its (α, β) beside ours: a second paper, whose
  section is ``boresight.reproductions.usv_sea_sky.sea_sky_section`` (appended here).

Any other section of the existing report is kept as it is. Numbers in the prose are computed
from the results, or checked by ``tests/reproductions/test_reproduce.py`` where they describe a fixed input.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from boresight.errors import InputValueError
from boresight.reproductions.usv_sea_sky.report import SEA_SKY_HEADING, sea_sky_section
from boresight.stats import sigma_interval

__all__ = [
    "split_sections",
    "algorithm1_section",
    "eq28_section",
    "eq28_findings",
    "kalman_section",
    "generate",
    "ReproductionReport",
]

from boresight.reproductions.kiev2012.scenarios import SCENARIOS, sensitivity_case

ALG1_HEADING = "## Kiev 2012 — Algorithm 1"
EQ28_HEADING = "## Kiev 2012 — eq 28 sensitivity case"
KALMAN_HEADING = "## Kiev 2012 — Kalman variant (eq 32)"


def split_sections(text: str) -> list:
    """Split markdown into ``[(heading, text)]`` at level-2 headings; the preamble has heading ''.

    >>> [h for h, _ in split_sections("# T\\nx\\n## A\\ny\\n## B\\nz\\n")]
    ['', '## A', '## B']
    """
    out: list[Any] = []
    head = ""
    buf: list[str] = []
    for line in text.splitlines(keepends=True):
        if line.startswith("## "):
            out.append((head, "".join(buf)))
            head, buf = line.rstrip("\n"), [line]
        else:
            buf.append(line)
    out.append((head, "".join(buf)))
    return out


def _fmt(v, d=1):
    return f"{float(v):.{d}f}"


def _alg1_main_table(t) -> list:
    labels = ["0", "1", "5"]
    head = "| t, s |"
    for lab in labels:
        head += f" μ″ seminar r_p={lab} | μ″ ours r_p={lab} | δr m seminar r_p={lab} | δr m ours r_p={lab} |"
    lines = [head, "|" + "---|" * (1 + 4 * len(labels))]
    for i, ts in enumerate(t["t_s"]):
        cells = [f"{float(ts):g}"]
        for lab in labels:
            for q, unit in (("mu", "arcsec"), ("dr", "m")):
                sem = t[f"seminar_{q}_{unit}_rp{lab}"][i]
                mean, sd = t[f"{q}_{unit}_mean_rp{lab}"][i], t[f"{q}_{unit}_std_rp{lab}"][i]
                if lab == "0":
                    cells += [_fmt(sem), _fmt(mean)]
                else:
                    pct = t[f"seminar_{q}_pct_rp{lab}"][i]
                    cells += [f"{_fmt(sem)} ({pct:.0f} %)", f"{_fmt(mean)} ± {_fmt(sd)}"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _alg1_variants_table(v, seminar) -> list:
    combos = [
        ("best_fit", "tangent_plane"),
        ("best_fit", "sphere"),
        ("horizontal", "tangent_plane"),
        ("site", "tangent_plane"),
        ("site", "sphere"),
    ]
    names = [f"{p}, {'tangent' if pl == 'tangent_plane' else 'sphere'}" for p, pl in combos]
    head = (
        "| t, s | μ″ seminar | "
        + " | ".join(f"μ″ {n}" for n in names)
        + " | δr m seminar | "
        + " | ".join(f"δr m {n}" for n in names)
        + " |"
    )
    lines = [head, "|" + "---|" * (3 + 2 * len(combos))]
    v = v[v["attitude"] == "site_tracking"]
    ts = sorted(set(float(x) for x in v["t_s"]))
    for i, t in enumerate(ts):
        row = [f"{t:g}", _fmt(seminar["mu_arcsec_rp0"][i])]
        sel = {c: v[(v["plane"] == c[0]) & (v["placement"] == c[1]) & (np.isclose(v["t_s"], t))][0] for c in combos}
        row += [_fmt(sel[c]["mu_arcsec"]) for c in combos]
        row += [_fmt(seminar["dr_m_rp0"][i])] + [_fmt(sel[c]["dr_m"]) for c in combos]
        lines.append("| " + " | ".join(row) + " |")
    return lines


def _replace_table_after(text: str, heading_prefix: str, new_lines: list) -> tuple[str, bool]:
    """Replace the first markdown table after the line starting with ``heading_prefix``."""
    lines = text.split("\n")
    start = next((i for i, ln in enumerate(lines) if ln.startswith(heading_prefix)), None)
    if start is None:
        return text, False
    a = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("|")), None)
    if a is None:
        return text, False
    b = a
    while b < len(lines) and lines[b].startswith("|"):
        b += 1
    same = lines[a:b] == new_lines
    return "\n".join(lines[:a] + new_lines + lines[b:]), same


def algorithm1_section(template: str, runs: int = 1000, seed: int = 2012) -> tuple[str, bool]:
    """The Algorithm 1 section: the template's prose with both tables regenerated.

    Returns ``(text, reproduced)``: ``reproduced`` is True when the regenerated tables equal
    the template's (same runs and seed as the report states: 1000, 2012, plane best_fit).
    """
    from boresight.reproductions.kiev2012.algorithm1 import algorithm1_table, algorithm1_variants
    from boresight.reproductions.kiev2012.published import SEMINAR_ALGORITHM1_TABLE

    path = SCENARIOS / "kiev2012-algorithm1.toml"
    t = algorithm1_table(path, r_p_values=(0.0, 1.0, 5.0), runs=runs, seed=seed, plane="best_fit")
    v = algorithm1_variants(path)
    text, ok1 = _replace_table_after(template, "### The table, seminar vs ours", _alg1_main_table(t))
    text, ok2 = _replace_table_after(text, "### The r_p = 0 column", _alg1_variants_table(v, SEMINAR_ALGORITHM1_TABLE))
    return text, ok1 and ok2


# ---------------------------------------------------------------------------- eq 28

EQ28_CASES = (
    ("A", 1, "per_image", "1 image (our baseline; per image = per pass)"),
    ("B", 10, "per_image", "10 images, star tracker and GNSS errors independent per image"),
    ("C", 10, "per_pass", "10 images, star tracker and GNSS errors constant over the pass"),
)


@dataclass
class _Eq28Case:
    key: str
    n_images: int
    scenario: object
    sigma_arcsec: np.ndarray  # Monte Carlo σθ per axis
    linear: object  # linear_sensitivities table (meta: sigma_theta_arcsec, crlb_sigma_arcsec)


def _eq28_cases(runs, seed, workers) -> dict:
    """Monte Carlo σθ (Algorithm 3) and linear propagation for each case of ``EQ28_CASES``."""
    from boresight.studies import montecarlo as mc
    from boresight.studies import sensitivity as se

    cases = {}
    for key, n, mode, _ in EQ28_CASES:
        sc = sensitivity_case(n, mode)
        r = mc.montecarlo_study(sc, ["image_plane"], runs, seed, workers=workers, image_counts=[n])
        cases[key] = _Eq28Case(key, n, sc, r.moments["image_plane"].std[0], se.linear_sensitivities(sc, ["image_plane"]))
    return cases


def _eq28_sigma_table(cases, runs, seed) -> list:
    from boresight.reproductions.kiev2012.published import SEMINAR_EQ28_SIGMA_ARCSEC as s

    lines = [
        f"### σθ (arcsec): seminar vs ours, {runs} runs per case (seed {seed}), 99.73 % χ² intervals",
        "",
        "| case | assumption | σθx | σθy | σθz | total | linear σθx/σθy/σθz | CRLB σθx/σθy/σθz |",
        "|---|---|---|---|---|---|---|---|",
        f"| seminar | (not stated) | {s[0]} | {s[1]} | {s[2]} | {s[3]} | | |",
    ]
    for key, _, _, text in EQ28_CASES:
        c = cases[key]
        sd = c.sigma_arcsec
        lo, hi = sigma_interval(sd, runs, 0.9973)
        la = c.linear.meta["sigma_theta_arcsec"]["image_plane"]
        cr = c.linear.meta["crlb_sigma_arcsec"]
        cells = [f"{sd[i]:.2f} [{lo[i]:.2f}, {hi[i]:.2f}]" for i in range(3)]
        lines.append(
            f"| {key} | {text} | {' | '.join(cells)} | {np.sqrt((sd**2).sum()):.2f} | {la[0]:.2f}/{la[1]:.2f}/{la[2]:.2f} | {cr[0]:.2f}/{cr[1]:.2f}/{cr[2]:.2f} |"
        )
    return lines


def _eq28_sensitivity_table(st, runs) -> list:
    lines = [
        "",
        f"### Sensitivities ∂σθi/∂σs, case A: finite differences of Monte Carlo ({runs} runs, common random numbers,",
        "σs → 2σs) ± standard error | linear covariance propagation | CRLB (optimal GLS gain) | seminar",
        "",
        "Units: β rows ″/″; P, R rows ″/m; K row ″/m. The quantity is a_is = sqrt(∂σθi²/∂σs²), the σθi that",
        "source s alone causes per unit σs — what the seminar's table holds (its rows add in quadrature to its σθ).",
        "",
        "| source | x: FD | x: linear | x: CRLB | x: seminar | y: FD | y: linear | y: CRLB | y: seminar | z: FD | z: linear | z: CRLB | z: seminar |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    from boresight.reproductions.kiev2012.eq28 import eq28_comparison

    for row in eq28_comparison(st, "image_plane"):
        cells = [row["source"]]
        for a in "xyz":
            cells += [
                f"{row[f'fd_{a}']:.4g} ± {row[f'fd_se_{a}']:.2g}",
                f"{row[f'analytic_{a}']:.4g}",
                f"{row[f'crlb_{a}']:.4g}",
                f"{row[f'seminar_{a}']:.3g}",
            ]
        lines.append("| " + " | ".join(cells) + " |")
    n = 3 * len(st.comparison("image_plane"))
    lines += ["", f"FD vs linear: max |difference| / SE = {st.agreement['image_plane']:.2f} over the {n} entries.", ""]
    return lines


def _coef(lin, src) -> np.ndarray:
    row = lin[(lin["algorithm"] == "image_plane") & (lin["source"] == src)][0]
    return np.array([float(row[f"coef_{a}"]) for a in "xyz"])


def _eq28_assumption_table(cases) -> list:
    from boresight.core.error_sources import SOURCES
    from boresight.reproductions.kiev2012.published import SEMINAR_EQ28

    lines = [
        "### What each assumption gives (linear propagation, ″ per unit σ; |x, y, z|)",
        "",
        "| source | seminar | A: 1 image | B: 10 images, per image | C: 10 images, per pass |",
        "|---|---|---|---|---|",
    ]
    for src in SOURCES:
        cells = [src, "/".join(f"{v:.3g}" for v in SEMINAR_EQ28[src][:3])]
        cells += ["/".join(f"{v:.3g}" for v in _coef(cases[key].linear, src)) for key in ("A", "B", "C")]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _eq28_budget_table(budget) -> list:
    lines = [
        "",
        "### Error budget, case A (share of σθ² per axis, linear propagation)",
        "",
        "| source | x | y | z |",
        "|---|---|---|---|",
    ]
    for row in budget:
        lines.append(
            f"| {row['label']} | {100 * row['share_x']:.1f} % | {100 * row['share_y']:.1f} % | {100 * row['share_z']:.1f} % |"
        )
    return lines


def eq28_findings(cases) -> dict:
    """The numbers the eq 28 prose states, computed from the cases (``tests/reproductions/test_reproduce.py`` checks them).

    ``sigma_dev_pct``: max over axes of |σθ(A) / σθ(seminar) − 1| (%); ``sens_dev_pct``: per
    source and axis, |a(A, linear) / a(seminar) − 1| (%) where the seminar's entry is not 0;
    ``beta_dev_max``: max |a(A) − a(seminar)| over the β rows (the mount match); ``R_one_image``,
    ``R_expected``: R's x sensitivity (″/m) and 1/altitude; ``lever_km``: sqrt(Σ horizontal
    landmark distance²); ``beta_norm_B``, ``R_B``, ``sigma_B``, ``sigma_C``: cases B and C.
    """
    from boresight.core.error_sources import SOURCES
    from boresight.reproductions.kiev2012.published import SEMINAR_EQ28, SEMINAR_EQ28_SIGMA_ARCSEC
    from orbits.rotations import ARCSEC

    A, B, C = cases["A"], cases["B"], cases["C"]
    sem_sigma = np.asarray(SEMINAR_EQ28_SIGMA_ARCSEC[:3])
    dev, pairs = {}, {}
    for src in SOURCES:
        ours, sem = _coef(A.linear, src), np.asarray(SEMINAR_EQ28[src][:3])
        for i, a in enumerate("xyz"):
            if sem[i] != 0:
                dev[(src, a)] = 100 * abs(ours[i] / sem[i] - 1)
                pairs[(src, a)] = (float(ours[i]), float(sem[i]))
    beta = [src for src in SOURCES if src.startswith("beta")]
    enu = np.asarray(A.scenario.landmarks.enu_km, float)
    return {
        "sigma_dev_pct": float(100 * np.max(np.abs(A.sigma_arcsec / sem_sigma - 1))),
        "sens_dev_pct": dev,
        "sens_values": pairs,
        "beta_dev_max": float(max(np.max(np.abs(_coef(A.linear, s) - np.asarray(SEMINAR_EQ28[s][:3]))) for s in beta)),
        "R_one_image": float(_coef(A.linear, "R")[0]),
        "R_expected": float(1.0 / (A.scenario.orbit.altitude_km * 1e3) / ARCSEC),
        "altitude_km": float(A.scenario.orbit.altitude_km),
        "lever_km": float(np.sqrt((enu[:, :2] ** 2).sum())),
        "landmark_distance_km": float(np.median(np.hypot(enu[:, 0], enu[:, 1]))),
        "n_landmarks": int(enu.shape[0]),
        "beta_norm_B": float(np.mean([np.linalg.norm(_coef(B.linear, s)) for s in beta])),
        "R_B": float(_coef(B.linear, "R")[0]),
        "sigma_B": (float(B.sigma_arcsec.min()), float(B.sigma_arcsec.max())),
        "sigma_C": tuple(float(v) for v in C.sigma_arcsec),
        "n_images_B": B.n_images,
    }


def _eq28_explanation(f, runs) -> list:
    from boresight.studies.montecarlo import achieved_epsilon

    dev = f["sens_dev_pct"]
    worst = max(dev, key=dev.get)
    close = sorted(k for k, v in dev.items() if v <= 5.0)
    nb = f["n_images_B"]
    sc = f["sigma_C"]
    return [
        "",
        "### Assumptions that explain the differences",
        "",
        f"* **One image (case A) reproduces the seminar's σθ** — within {f['sigma_dev_pct']:.1f} % per axis at {runs} runs, and",
        f"  {len(close)} of the {len(dev)} non-zero sensitivities within 5 %, including the unit-norm β rows and",
        f"  R = {f['R_one_image']:.3f}″/m ≈ 1/({f['altitude_km']:.0f} km) = {f['R_expected']:.3f}″/m: with one image a star-tracker error is",
        "  indistinguishable from θ and is passed on whole. The largest difference is "
        f"{worst[0]} about {worst[1]}: {f['sens_values'][worst][0]:.3g} against the seminar's {f['sens_values'][worst][1]:.3g} ({dev[worst]:.0f} %).",
        f"* **{nb} images with per-image errors (case B)** average the star-tracker and GNSS errors down (β rows' norm",
        f"  {f['beta_norm_B']:.2f} against 1/√{nb} = {1 / np.sqrt(nb):.2f}, R = {f['R_B']:.2f}″/m), and the pixel and catalogue terms by the larger",
        f"  lever of {nb} viewpoints; σθ drops to {f['sigma_B'][0]:.1f}-{f['sigma_B'][1]:.1f}″. The seminar's unit-norm β rows rule this out.",
        f"* **{nb} images with per-pass errors (case C)** keep the β and R rows at their one-image values",
        f"  (a bias is not averaged), while K and P still average: σθx, σθy stay at {sc[0]:.1f}, {sc[1]:.1f}″ (star tracker and",
        f"  GNSS dominate), σθz drops to {sc[2]:.1f}″. The seminar's K and P rows (one-image values) rule this out: its",
        "  numbers are those of a single image (or of errors of all kinds fully correlated over the pass).",
        f"* **Landmark layout and star-tracker mount are ours** (the seminar gives neither): a cross of {f['n_landmarks']}",
        f"  landmarks at {f['landmark_distance_km']:.0f} km reproduces both z sensitivities (K and P need a lever sqrt(Σρ²) = {f['lever_km']:.0f} km); the",
        f"  mount is chosen so |C_SK| matches the β rows (to {f['beta_dev_max']:.4f}). These choices fit the seminar's numbers; they",
        "  are not evidence for its layout.",
        f"* Remaining differences of σθ ({f['sigma_dev_pct']:.1f} % here): our Monte Carlo uncertainty (ε = "
        f"{100 * achieved_epsilon(runs, 0.9973):.1f} % at {runs} runs, β = 0.9973),",
        f"  the seminar's rounding (two digits) and its own Monte Carlo uncertainty (ε = {100 * achieved_epsilon(45000, 0.9973):.1f} % at 45 000 runs if it",
        "  used its own sample-size rule).",
        "",
    ]


def eq28_section(runs: int = 45000, seed: int = 1, workers=None, out_dir=None) -> str:
    """The eq 28 block and sensitivity table, seminar vs ours under each assumption."""
    from boresight.studies import sensitivity as se

    cases = _eq28_cases(runs, seed, workers)
    st = se.sensitivity_study(sensitivity_case(1, "per_image"), ["image_plane"], runs=runs, seed=seed, workers=workers)
    lines = [
        EQ28_HEADING,
        "",
        'Kiev 2012 eq 28 (section "Sensitivity analysis", docs/references.md): σθ of the misalignment estimate and its sensitivities',
        "∂σθ/∂σs to the star tracker (β1-β3), catalogue (P), GNSS (R) and pixel (K) errors. Scenario",
        "`scenarios/kiev2012-sensitivity.toml` (680 km, i = 98°, F = 2.2 m, 3.4° field, σβ = 4″, σP = 0.1 m,",
        "σR = 15 m, σK = 3 µm, θ ~ N(0, 10′²) per run) with our choices: 4 landmarks in a cross 13 km from",
        "the site, the star-tracker mount inferred from the seminar's β rows, Algorithm 3 (unit-weight",
        "least squares, 2 Gauss-Newton steps from θ0 = 0). Code: `boresight/studies/montecarlo/`,",
        "`boresight/studies/sensitivity.py` (`docs/montecarlo.md`); regenerate with `boresight reproduce kiev2012 --out docs/`.",
        "",
    ]
    lines += _eq28_sigma_table(cases, runs, seed)
    lines += _eq28_sensitivity_table(st, runs)
    lines += _eq28_assumption_table(cases)
    lines += _eq28_budget_table(st.budget)
    lines += _eq28_explanation(eq28_findings(cases), runs)
    from boresight.reporting.plots import available

    if out_dir is not None and available():  # without matplotlib: no figure, and no link to one
        from boresight.reporting.plots import plot_sensitivity_bars

        plot_sensitivity_bars(st, Path(out_dir) / "reproduction-eq28.png", "image_plane")
        lines += ["![eq 28 sensitivities, FD vs linear, case A](reproduction-eq28.png)", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- Kalman


def kalman_section(runs: int = 2000, seed: int = 2012, out_dir=None) -> str:
    """The eq 32 table: ours (``kalman_table``) under three error/filter assumptions vs the seminar's."""
    from boresight.reproductions.kiev2012.kalman_table import kalman_table
    from boresight.reproductions.kiev2012.published import seminar_kalman_table
    from boresight.reproductions.kiev2012.scenarios import kalman_scenario

    sem = seminar_kalman_table()
    per_pass = kalman_scenario(10.0, star_tracker_mode="per_pass", gnss_mode="per_pass")
    ours = {
        "per image": kalman_table(kalman_scenario(10.0), runs=runs, seed=seed),
        "per pass, bias states": kalman_table(per_pass, runs=runs, seed=seed),
        "per pass, θ-only filter": kalman_table(per_pass, runs=runs, seed=seed, states=("theta",)),
    }
    keys = list(ours)
    lines = [
        KALMAN_HEADING,
        "",
        'Kiev 2012 eq 32 table (section "Kalman variant"): σθ and max |θ error| of the Kalman filter versus the',
        "number of images, initial uncertainty σ = 10″. Ours: `kiev2012.kalman_table` (Algorithm 3",
        "measurements, per-image R_n from the disturbance model including the star-tracker and GNSS errors",
        "common to an image's landmarks; IEKF, 3 iterations) on `kalman_scenario()`: the eq 28 scenario with",
        "20 images every 5 s from the passage (our choice: the seminar gives no geometry for this table),",
        f"{runs} runs, seed {seed}. Three assumptions: star-tracker and GNSS errors independent per image",
        "(the filter's default model); constant over the pass with the filter estimating them as per-pass",
        "bias states (its default for that model); constant over the pass with a θ-only filter that treats",
        "them as per-image noise (a filter inconsistent with its disturbances).",
        "",
        "σθx/σθy/σθz (arcsec):",
        "",
        "| images | seminar | " + " | ".join(f"ours, {k}" for k in keys) + " |",
        "|---|---|" + "---|" * len(keys),
    ]

    def trip(t, stem, j):
        return "/".join(f"{float(t[f'{stem}_{a}'][j]):.1f}" for a in "xyz")

    def idx(t, n):
        return list(t["n_images"]).index(n)

    for i, n in enumerate(sem["n_images"]):
        lines.append(
            f"| {int(n)} | {trip(sem, 'sigma_theta', i)} | "
            + " | ".join(trip(ours[k], "sigma_theta", idx(ours[k], n)) for k in keys)
            + " |"
        )
    lines += [
        "",
        "max |θ error| x/y/z (arcsec):",
        "",
        "| images | seminar | " + " | ".join(f"ours, {k}" for k in keys) + " |",
        "|---|---|" + "---|" * len(keys),
    ]
    for i, n in enumerate(sem["n_images"]):
        lines.append(
            f"| {int(n)} | {trip(sem, 'max_abs_theta', i)} | "
            + " | ".join(trip(ours[k], "max_abs_theta", idx(ours[k], n)) for k in keys)
            + " |"
        )
    t0 = ours[keys[0]]
    lo, hi = float(t0["nees_lo"][-1]), float(t0["nees_hi"][-1])
    nees = {k: float(t["nees_mean"][-1]) for k, t in ours.items()}
    lines += [
        "",
        "NEES after 20 images (mean normalised error², 3 for a consistent filter; 99 % band "
        f"{lo:.2f}-{hi:.2f}): "
        + ", ".join(f"{k}: {v:.2f}{'' if lo <= v <= hi else ' (outside)'}" for k, v in nees.items())
        + ".",
        "",
        "### Assumptions that explain the differences",
        "",
    ]

    def sx(k, n):
        t = ours[k]
        return float(np.hypot(t["sigma_theta_x"][idx(t, n)], t["sigma_theta_y"][idx(t, n)]) / np.sqrt(2))

    lines += [
        "* **Geometry** (orbit, camera, landmarks, image times) is the eq 28 scenario's; the seminar gives",
        "  none for this table, so only trends compare. Its one-image row (σθz "
        f"{float(sem['sigma_theta_z'][0]):.1f}″ against σθx,y {float(sem['sigma_theta_x'][0]):.1f}, {float(sem['sigma_theta_y'][0]):.1f}″)",
        "  implies a weaker lever about the boresight than our 13 km cross (our one-image σθz "
        f"{float(t0['sigma_theta_z'][0]):.1f}″).",
        f"* **Per-image errors**: σθx,y falls from {sx(keys[0], 1):.1f}″ (1 image) to {sx(keys[0], 4):.1f}″ (4) and "
        f"{sx(keys[0], 20):.1f}″ (20) — a consistent filter keeps improving, as it should.",
        f"* **Per-pass errors, bias states**: σθx,y {sx(keys[1], 1):.1f}″ → {sx(keys[1], 4):.1f}″ → {sx(keys[1], 20):.1f}″: the",
        "  bias is only separated from θ as the viewing geometry changes along the pass; the filter stays",
        f"  consistent (NEES {nees[keys[1]]:.2f}).",
        f"* **Per-pass errors, θ-only filter**: σθx,y {sx(keys[2], 1):.1f}″ → {sx(keys[2], 4):.1f}″ (4) → "
        f"{max(sx(keys[2], n) for n in (8, 12, 20)):.1f}″ (worst of 8-20) → {sx(keys[2], 20):.1f}″ (20), NEES {nees[keys[2]]:.2f}:",
        "  the filter believes it averages the bias away, stops improving and is far from consistent. This",
        f"  is the seminar's symptom (σθx growing after 4 images, {float(sem['sigma_theta_x'][idx(sem, 4)]):.1f}″ → "
        f"{float(sem['sigma_theta_x'][-1]):.1f}″ at {int(sem['n_images'][-1])}) in kind; its size depends on",
        "  the geometry and on how much of the error is a bias, which the slides do not give.",
        "",
    ]
    from boresight.reporting.plots import available

    if out_dir is not None and available():  # without matplotlib: no figure, and no link to one
        from boresight.reporting.plots import plot_kalman_table

        plot_kalman_table(sem, ours, Path(out_dir) / "reproduction-kalman.png")
        lines += ["![Kalman σθ vs number of images](reproduction-kalman.png)", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- the report


@dataclass
class ReproductionReport:
    text: str
    algorithm1_reproduced: bool
    path: Path | None = None


#: the report as shipped (package data; in a checkout a symlink to docs/reproduction.md): the
#: default template of ``boresight reproduce kiev2012 --out DIR`` when DIR has none
SHIPPED_TEMPLATE = Path(__file__).resolve().parent / "reproduction.md"


def generate(
    template_path, runs: int = 45000, seed: int = 1, kalman_runs: int = 2000, workers=None, out_dir=None, alg1_runs: int = 1000
) -> ReproductionReport:
    """Build the report from the template (the existing ``docs/reproduction.md``).

    Sections other than ours are kept; the Algorithm 1 section's tables are regenerated; the
    eq 28 and Kalman sections are (re)built after it.
    """
    template_path = Path(template_path)
    if not template_path.exists():
        raise FileNotFoundError(f"template {template_path} not found (the existing docs/reproduction.md)")
    sections = split_sections(template_path.read_text())
    if not any(h == ALG1_HEADING for h, _ in sections):
        raise InputValueError(
            f"template {template_path} (--template) has no {ALG1_HEADING!r} section: the Algorithm 1 tables are regenerated in it"
        )
    out, ok = [], False
    for head, text in sections:
        if head in (EQ28_HEADING, KALMAN_HEADING, SEA_SKY_HEADING):
            continue
        if head == ALG1_HEADING:
            text, ok = algorithm1_section(text, runs=alg1_runs)
        out.append(text if text.endswith("\n") else text + "\n")
    body = "".join(out).rstrip("\n") + "\n\n"
    body += eq28_section(runs, seed, workers, out_dir) + "\n" + kalman_section(kalman_runs, out_dir=out_dir)
    body += "\n" + sea_sky_section()
    body = re.sub(r"\n{3,}", "\n\n", body)
    return ReproductionReport(body, ok)
