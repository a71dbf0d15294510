"""The USV sea-sky section of ``docs/reproduction.md``: the paper's numbers beside ours."""

from __future__ import annotations

import numpy as np

from boresight.reproductions.usv_sea_sky.published import PAPER_COARSE_DEG, PAPER_FINE_DEG, PAPER_SPECIAL_POINTS_DEG

__all__ = ["SEA_SKY_HEADING", "sea_sky_section"]

SEA_SKY_HEADING = "## USV sea-sky — installation perpendicularity on the paper's measured data"


def sea_sky_section() -> str:
    """The USV sea-sky section: the paper's 120 measured frames, its numbers beside ours (< 1 s).

    Computed live from ``boresight.pointing`` (USV sea-sky eqs 23-24 and our least squares).
    """
    from boresight.pointing import (
        analyse_sea_sky,
        coarse_estimate_deg,
        grid_search_deg,
        load_sea_sky,
        mean_abs_error_deg,
        special_points_deg,
    )
    from boresight.pointing.turntable import coupling_error_from_rotation_rad, coupling_error_rad

    scan = load_sea_sky()
    az, h, P, R = scan.azimuth_deg, scan.h_meas_deg, scan.pitch_deg, scan.roll_deg
    c_paper = tuple(float(v) for v in coarse_estimate_deg(*PAPER_SPECIAL_POINTS_DEG))
    sp = special_points_deg(az, h)
    c_table = tuple(float(v) for v in sp.coarse_estimate_deg())
    g = grid_search_deg(az, h, P, R, *PAPER_COARSE_DEG)
    g_round = grid_search_deg(az, np.round(h, 2), P, R, *PAPER_COARSE_DEG)
    obj_ours = mean_abs_error_deg(g.alpha_deg, g.beta_deg, az, h, P, R)
    obj_paper = mean_abs_error_deg(*PAPER_FINE_DEG, az, h, P, R)
    d = analyse_sea_sky(scan)
    f = d.fit
    om, al = np.meshgrid(np.radians(np.linspace(-40, 40, 81)), np.radians(np.linspace(-20, 20, 41)))
    turn = float(np.abs(coupling_error_rad(om, al) - coupling_error_from_rotation_rad(om, al)).max())
    att_change = max(abs(f.alpha_deg - d.fit_no_attitude.alpha_deg), abs(f.beta_deg - d.fit_no_attitude.beta_deg))
    res = np.asarray(d.outlier_residuals_deg)
    outlier_signs = (
        "all positive" if np.all(res > 0) else ("all negative" if np.all(res < 0) else f"{int((res > 0).sum())} positive")
    )
    az_of = dict(zip(np.asarray(scan.frame).tolist(), np.asarray(az).tolist()))
    outlier_az = ", ".join(f"{az_of[int(fr)]:.0f}°" for fr in d.outlier_frames)
    rows = [
        (
            f"coarse, eq 23, the paper's special points ({PAPER_SPECIAL_POINTS_DEG[0]:.2f}°, {PAPER_SPECIAL_POINTS_DEG[1]:.3f}°)",
            PAPER_COARSE_DEG,
            c_paper,
        ),
        (f"coarse, eq 23, special points found in the table ({sp.q1_deg:.2f}°, {sp.h2_deg:.4f}°)", None, c_table),
        ("fine, eq 24 two-stage 21×21 grid", PAPER_FINE_DEG, (g.alpha_deg, g.beta_deg)),
        ("fine, eq 24 grid with h′ rounded to 0.01°", PAPER_FINE_DEG, (g_round.alpha_deg, g_round.beta_deg)),
    ]
    lines = [
        SEA_SKY_HEADING,
        "",
        "The USV sea-sky paper's 120 measured frames (`boresight/data/usv_sea_sky_line.csv`, Table 1 of the",
        "paper), its estimates of the installation perpendicularity errors (α, β) beside ours. Regenerated",
        "by `boresight reproduce kiev2012` (this section is computed from `boresight.pointing`); the",
        "analysis in full, with the residual study, is in `docs/pointing.md` and `boresight pointing sea-sky`.",
        "",
        "| estimate | paper α, β (deg) | ours α, β (deg) |",
        "|---|---|---|",
    ]
    for name, paper, ours in rows:
        pp = "–" if paper is None else f"{paper[0]:.4f}, {paper[1]:.4f}"
        lines.append(f"| {name} | {pp} | {ours[0]:.4f}, {ours[1]:.4f} |")
    lines.append(
        f"| least squares, {f.loss} loss (ours; 1σ Newey–West, lag {f.max_lag}) | – | "
        f"{f.alpha_deg:.4f} ± {f.se[0]:.4f}, {f.beta_deg:.4f} ± {f.se[1]:.4f} |"
    )
    lines += [
        "",
        "* **Coarse.** From the paper's printed special points we get the paper's result to the rounding of",
        "  those points (half a unit of their last digit moves α by up to ±5.5e-4° and β by ±2.4e-4°).",
        "  Special points read from the table itself (5-frame running median) differ, since the paper read",
        "  them off images.",
        f"* **Grid.** One 0.01° step from the paper in α: a near-tie, mean |h″ − h′| = {obj_ours:.6f}° at",
        f"  ours and {obj_paper:.6f}° at the paper's point. With h′ rounded to 0.01° (the precision of the",
        "  paper's own worked example) the grid returns the paper's values exactly. The grid resolves α, β",
        "  to its 0.01° step; that is the precision to which we reproduce the paper.",
        "* **Least squares** (beyond the paper): the residuals are serially correlated along the scan",
        f"  (effective sample size {f.n_eff:.0f} of {f.n}); ignoring that would give ± {f.se_iid[0]:.4f}, ± {f.se_iid[1]:.4f}.",
        f"  Hull pitch and roll change the fit by {att_change:.1e}° at this data's small angles; {len(d.outlier_frames)} frames are",
        f"  outliers ({outlier_signs}, at azimuths {outlier_az} — `docs/pointing.md`).",
        "* **Turntable coupling** (Tang 2015 eq 34): η agrees with the exact rotation (scipy `Rotation`) to",
        f"  {turn:.1e} rad over Ω ∈ [−40°, 40°], α ∈ [−20°, 20°].",
        "",
    ]
    return "\n".join(lines)
