"""``ImageRecords``: the images of a campaign as the sensors report them, the one field list of the
simulator's ``orbits.measurements.Measurements`` and the estimator's
``boresight.observations.ObservationSet``. Its own module, importing only numpy, so the data
model does not load the simulator to get it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ImageRecords"]


@dataclass(frozen=True)
class ImageRecords:
    """The images of a campaign as the sensors report them: R runs, N images, M landmarks.

    ``t_s`` (N,) image times; ``pass_index`` (N,); ``q_is`` (R, N, 4) star-tracker attitude
    quaternion inertial → star tracker, scalar last; ``r_sc_i_m`` (R, N, 3) GNSS position in I;
    ``C_GI`` (N, 3, 3) Earth-fixed → inertial; ``landmark_ids`` (M,); ``landmark_g_m`` (R, M, 3)
    catalogue coordinates in G; ``xy_m`` (R, N, M, 2) image points (0 where ``mask`` is False);
    ``mask`` (N, M). The one field list shared by the simulator's ``Measurements`` and the
    estimator's ``boresight.observations.ObservationSet``.
    """

    t_s: np.ndarray
    pass_index: np.ndarray
    q_is: np.ndarray
    r_sc_i_m: np.ndarray
    C_GI: np.ndarray
    landmark_ids: np.ndarray
    landmark_g_m: np.ndarray
    xy_m: np.ndarray
    mask: np.ndarray

    @property
    def runs(self) -> int:
        return int(self.xy_m.shape[0])
