"""One error hierarchy: every typed error boresight raises on purpose derives from BoresightError."""

import boresight
import orbits
from boresight.core.algorithms.homography import HomographyError
from boresight.errors import ObservabilityError
from orbits.errors import BoresightError
from orbits.scenario import ScenarioError


def test_typed_errors_share_one_root():
    for cls in (ObservabilityError, HomographyError, boresight.ObservationError, boresight.ObservationFileError, ScenarioError):
        assert issubclass(cls, BoresightError), cls
        assert issubclass(cls, ValueError), cls  # the old promise: except ValueError still catches them
    assert boresight.BoresightError is BoresightError
    assert not issubclass(BoresightError, ValueError)


def test_scenario_error_is_raised_as_boresight_error():
    import pytest

    with pytest.raises(BoresightError, match="camera"):
        orbits.scenario_from_dict({"name": "x", "orbit": {"altitude_km": -1.0, "inclination_deg": 98.0}})
