"""The arrays of an ``ObservationSet``'s three tables (images, targets, rows: ``docs/architecture.md``,
the row model) and its mount, and the check that two sets hold them alike bit for bit — what a
lossless file round trip, a rebuilt set or a file read another way must keep."""

import numpy as np

ARRAYS = (
    "t_s",
    "pass_index",
    "q_is",
    "r_sc_i_m",
    "v_sc_i_m_s",
    "C_GI",
    "landmark_ids",
    "landmark_g_m",
    "image_index",
    "target_index",
    "xy_m",
    "C_SK_nominal",
)


def assert_same_arrays(got, want) -> None:
    """Every array of ``ARRAYS`` of ``got`` has the shape and the values of ``want``'s (``v_sc_i_m_s`` may be
    None in both); the failure names the array."""
    for name in ARRAYS:
        a, b = getattr(got, name), getattr(want, name)
        assert np.shape(a) == np.shape(b), (name, np.shape(a), np.shape(b))
        np.testing.assert_array_equal(a, b, err_msg=name)
