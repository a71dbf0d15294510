"""Deprecated location: the reproduction report moved to ``boresight.reproductions.kiev2012.report``.

Kept so that ``from boresight.reproduce import generate`` (and the other names) keeps working.
"""

from boresight.reproductions.kiev2012.report import *  # noqa: F401,F403
from boresight.reproductions.kiev2012.report import __all__  # noqa: F401
