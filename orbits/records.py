"""``ImageRecords``: a campaign's observations as three tables — images, targets, rows — the one
field list of the estimator's ``boresight.observations.ObservationSet`` (and, once the simulator
is on rows, of ``orbits.measurements.Measurements``). Its own module, importing only numpy, so the
data model does not load the simulator to get it. The design is in ``docs/architecture.md``, "The
row model".

One row per observation (a target measured in an image), sorted by (image, target), each pair at
most once. So the rows of image n are the contiguous slice ``row_start[n]:row_start[n + 1]``
(CSR offsets, derived once), and no array has an images × targets axis pair: memory is
O(rows + images + targets).

>>> import numpy as np
>>> rec = ImageRecords(
...     t_s=np.array([0.0, 1.0]), pass_index=np.zeros(2, int), q_is=np.tile([0.0, 0, 0, 1], (1, 2, 1)),
...     r_sc_i_m=np.zeros((1, 2, 3)), C_GI=np.tile(np.eye(3), (2, 1, 1)), landmark_ids=np.array(["a", "b", "c"]),
...     landmark_g_m=np.zeros((1, 3, 3)), image_index=np.array([0, 0, 1]), target_index=np.array([0, 2, 1]),
...     xy_m=np.zeros((1, 3, 2)))
>>> rec.row_start.tolist(), rec.n_observations, rec.is_complete
([0, 2, 3], 3, False)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ImagesAndTargets", "ImageRecords", "row_offsets", "rows_are_canonical", "complete_rows"]


def row_offsets(image_index: Any, n_images: int) -> np.ndarray:
    """CSR offsets (N + 1,) of rows sorted by image: image n's rows are ``row_start[n]:row_start[n + 1]``."""
    return np.searchsorted(np.asarray(image_index), np.arange(n_images + 1), side="left").astype(np.int64)


def rows_are_canonical(image_index: Any, target_index: Any) -> np.ndarray:
    """(K − 1,) bool: row k + 1 comes strictly after row k in (image, target) order (sorted, no duplicate)."""
    i = np.asarray(image_index)
    t = np.asarray(target_index)
    return np.asarray((i[1:] > i[:-1]) | ((i[1:] == i[:-1]) & (t[1:] > t[:-1])))


def complete_rows(n_images: int, n_targets: int) -> tuple[np.ndarray, np.ndarray]:
    """``(image_index, target_index)`` of the complete set: every target in every image, canonical order."""
    return (
        np.repeat(np.arange(n_images, dtype=np.int64), n_targets),
        np.tile(np.arange(n_targets, dtype=np.int64), n_images),
    )


@dataclass(frozen=True)
class ImagesAndTargets:
    """The images and targets tables of a campaign (R runs, N images, T targets), without its
    observations (``ImageRecords`` adds the rows; the tests' images × landmarks grid, ``tests/oracles.py``,
    adds its grid and mask).

    Images: ``t_s`` (N,) image times; ``pass_index`` (N,); ``q_is`` (R, N, 4) star-tracker attitude
    quaternion inertial → star tracker, scalar last; ``r_sc_i_m`` (R, N, 3) GNSS position in I;
    ``C_GI`` (N, 3, 3) Earth-fixed → inertial. Targets: ``landmark_ids`` (T,); ``landmark_g_m``
    (R, T, 3) catalogue coordinates in G.
    """

    t_s: np.ndarray
    pass_index: np.ndarray
    q_is: np.ndarray
    r_sc_i_m: np.ndarray
    C_GI: np.ndarray
    landmark_ids: np.ndarray
    landmark_g_m: np.ndarray

    @property
    def n_images(self) -> int:
        return int(np.shape(self.t_s)[0])

    @property
    def n_targets(self) -> int:
        return int(np.shape(self.landmark_ids)[0])

    @property
    def n_landmarks(self) -> int:
        """The number of targets T (the name from before stars were targets)."""
        return self.n_targets


@dataclass(frozen=True)
class ImageRecords(ImagesAndTargets):
    """A campaign's observations: R runs, N images, T targets, K rows.

    The images and targets tables of ``ImagesAndTargets``; rows: ``image_index`` (K,) and
    ``target_index`` (K,) (int, canonical (image, target) order), ``xy_m`` (R, K, 2) measured
    focal-plane points.
    """

    image_index: np.ndarray
    target_index: np.ndarray
    xy_m: np.ndarray

    @property
    def runs(self) -> int:
        return int(self.xy_m.shape[0])

    @property
    def n_observations(self) -> int:
        """Rows K: observations per run."""
        return int(np.shape(self.image_index)[0])

    @property
    def row_start(self) -> np.ndarray:
        """CSR offsets (N + 1,): image n's rows are ``row_start[n]:row_start[n + 1]``."""
        cached = self.__dict__.get("_row_start")
        if cached is None:
            cached = row_offsets(self.image_index, self.n_images)
            object.__setattr__(self, "_row_start", cached)
        return np.asarray(cached)

    @property
    def rows_per_image(self) -> np.ndarray:
        """m_n (N,): the number of rows of each image."""
        return np.diff(self.row_start)

    @property
    def is_complete(self) -> bool:
        """Every target in every image, in order (K = N·T): ``xy_m`` reshapes to (R, N, T, 2) as a view."""
        cached = self.__dict__.get("_is_complete")
        if cached is None:
            n, t = self.n_images, self.n_targets
            cached = bool(self.n_observations == n * t and np.all(np.asarray(self.target_index) == np.tile(np.arange(t), n)))
            cached = cached and bool(np.all(self.rows_per_image == t))
            object.__setattr__(self, "_is_complete", cached)
        return bool(cached)
