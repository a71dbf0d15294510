"""The data: ``ObservationSet`` (``model``), its ECSV file format (``ecsv``), velocities from
positions, simulation of a scenario into observations, the convention doctor, and flight-data
ingestion (``flight``: CCSDS OEM/AEM, TLE, landmark lists, pixel detections)."""
