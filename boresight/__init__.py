"""boresight — camera / star-tracker misalignment from ground landmarks.

Public names are re-exported here; see ``docs/architecture.md`` for the map.
"""

__version__ = "0.1.0"
