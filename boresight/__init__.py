"""boresight — camera / star-tracker misalignment from ground landmarks.

Public names are re-exported here; see ``docs/architecture.md`` for the map.
"""

from boresight.observations.model import ObservationError, ObservationFileError, ObservationSet
from boresight.observations.simulate import simulate
from boresight.errors import BoresightError, ObservabilityError
from boresight.core.normal_equations import NormalEquations
from boresight.core.disturbances import DisturbanceModel
from boresight.core.estimation import estimate
from boresight.core.result import Estimate
from boresight.studies.discrepancy import Diagnosis, diagnose

__version__ = "0.1.0"

__all__ = ["ObservationError", "ObservationFileError", "ObservationSet", "simulate", "__version__"]
__all__ += ["BoresightError", "DisturbanceModel", "Estimate", "NormalEquations", "ObservabilityError", "estimate"]
__all__ += ["Diagnosis", "diagnose"]


def plan(spec, *, max_candidates=None):
    """Plan a calibration campaign (``boresight.studies.planning.plan``; ``docs/planning.md``).

    ``spec``: a plan file path, a parsed plan document (dict) or a ``PlanSpec``. Returns a
    ``boresight.studies.planning.PlanResult``. Imported on first use (the planner pulls in scipy.stats).
    """
    from boresight.studies.planning import plan as _plan

    return _plan(spec, max_candidates=max_candidates)


__all__ += ["plan"]
