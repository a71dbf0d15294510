"""Gimbal and platform pointing calibration (USV sea-sky, Tang 2014, Tang 2015 seeds).

* :mod:`.sea_sky`, :mod:`.sea_sky_fit`, :mod:`.sea_sky_analysis` -- installation
  perpendicularity error of a ship-borne electro-optical device from sea-sky line images
  (USV sea-sky eqs 1-27), with the paper's 120 measured frames in :mod:`.data`.
* :mod:`.gimbal`, :mod:`.collocation` -- the 14-coefficient static pointing model of a two-axis
  gimbal and its semi-parametric least-squares collocation (Tang 2014 eqs 10-19).
* :mod:`.turntable` -- turntable / platform axis coupling error (Tang 2015 eq 34).

See ``docs/pointing.md``.
"""

from boresight.pointing.collocation import (
    CollocationFit,
    LooResult,
    SemiParametricModel,
    collocation_fit,
    distance_matrix,
    fit_semiparametric,
    loo_cross_validation,
)
from boresight.pointing.data import (
    SEA_SKY_COLUMNS,
    SEA_SKY_N_FRAMES,
    SeaSkyScan,
    load_sea_sky,
    sea_sky_data_path,
)
from boresight.pointing.gimbal import (
    GimbalErrors,
    ParametricFit,
    design_matrix,
    design_matrix_azimuth,
    design_matrix_elevation,
    exact_base_tilt_error_rad,
    fit_parametric,
    pointing_error,
    table1_contributions,
)
from boresight.pointing.sea_sky import (
    SpecialPoints,
    coarse_estimate_deg,
    compensated_command_deg,
    compensated_command_rad,
    elevation_error_deg,
    los_error_rad,
    los_horizon_rad,
    los_vector,
    s_alpha,
    s_beta,
    s_pitch,
    s_roll,
    special_points_deg,
)
from boresight.pointing.sea_sky_analysis import SeaSkyDiagnostics, analyse_sea_sky
from boresight.pointing.sea_sky_fit import (
    PAPER_GRID_STAGES,
    GridSearchResult,
    GridStage,
    SeaSkyFit,
    fit_least_squares,
    grid_search_deg,
    mean_abs_error_deg,
)
from boresight.pointing.turntable import (
    compensate_azimuth_rad,
    coupling_error,
    coupling_error_from_rotation_rad,
    coupling_error_rad,
    twist_angle_rad,
)

__all__ = [
    "SeaSkyDiagnostics",
    "analyse_sea_sky",
    "GimbalErrors",
    "ParametricFit",
    "design_matrix",
    "design_matrix_azimuth",
    "design_matrix_elevation",
    "exact_base_tilt_error_rad",
    "fit_parametric",
    "pointing_error",
    "table1_contributions",
    "CollocationFit",
    "LooResult",
    "SemiParametricModel",
    "collocation_fit",
    "distance_matrix",
    "fit_semiparametric",
    "loo_cross_validation",
    "compensate_azimuth_rad",
    "coupling_error",
    "coupling_error_from_rotation_rad",
    "coupling_error_rad",
    "twist_angle_rad",
    "SEA_SKY_COLUMNS",
    "SEA_SKY_N_FRAMES",
    "SeaSkyScan",
    "load_sea_sky",
    "sea_sky_data_path",
    "SpecialPoints",
    "coarse_estimate_deg",
    "compensated_command_deg",
    "compensated_command_rad",
    "elevation_error_deg",
    "los_error_rad",
    "los_horizon_rad",
    "los_vector",
    "s_alpha",
    "s_beta",
    "s_pitch",
    "s_roll",
    "special_points_deg",
    "PAPER_GRID_STAGES",
    "GridSearchResult",
    "GridStage",
    "SeaSkyFit",
    "fit_least_squares",
    "grid_search_deg",
    "mean_abs_error_deg",
]
