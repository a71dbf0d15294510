"""The root of the project's one error hierarchy.

Every rejection of a user's input or data — a malformed scenario or observation file, an
unobservable geometry, an estimate that cannot be trusted — raises a subclass of
``BoresightError``. It lives here, in the lower layer, because ``orbits`` must not import
``boresight``; ``boresight.errors`` re-exports it. Subclasses also derive from ``ValueError``
where the old API promised one, so ``except ValueError`` keeps working.

The command line prints a ``BoresightError`` as one line and exits non-zero; a traceback is
reserved for real bugs.

>>> issubclass(BoresightError, Exception)
True
"""

from __future__ import annotations

__all__ = ["BoresightError"]


class BoresightError(Exception):
    """Base of every error boresight raises on purpose (bad input, unusable data or geometry).

    Messages name the file, the key or column as the user wrote it, the row and the value.
    """
