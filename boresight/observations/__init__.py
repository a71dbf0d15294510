"""The data: ``ObservationSet`` (``model``), its ECSV file format (``ecsv``), velocities from
positions, simulation of a scenario into observations, the convention doctor, and flight-data
ingestion (``flight``: CCSDS OEM/AEM, TLE, landmark lists, pixel detections).

The file format is imported with the package: it registers itself as ``ObservationSet.write`` /
``read``'s format (``model.FILE_FORMAT``), so the model never imports it (no import circle).
"""

from boresight.observations import ecsv as _ecsv  # noqa: F401 (registers the file format)
