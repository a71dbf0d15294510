"""Small checks shared by the readers of the data layer (the observation and strip files, the flight inputs).

A reader refuses a value with a message naming the file, the column, the row and the value; these helpers
find the row, the reader words the message.

>>> import numpy as np
>>> first_outside(np.array([1.0, 2.0, np.nan, 9.0]), 0.0, 5.0)
2
>>> first_outside(np.array([1.0, 2.0]), 0.0, 5.0) is None
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["first_outside"]


def first_outside(values: Any, lo: Any, hi: Any) -> int | None:
    """The index of the first of ``values`` (1-D) outside [``lo``, ``hi``] — bounds scalars or arrays that
    broadcast with ``values``; NaN is outside —, or None when every value is inside."""
    v = np.asarray(values)
    bad = ~((v >= lo) & (v <= hi))
    return int(np.argmax(bad)) if np.any(bad) else None
