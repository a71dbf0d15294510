"""What ``pyproject.toml`` promises about the extras: reading flight data installs only permissively
licensed packages; writing CCSDS files (``flight-export``) is where the GPL package is."""

import tomllib

from paths import ROOT

#: packages under a copyleft licence that boresight may use only behind an extra of their own
COPYLEFT = {"ccsds-ndm": "GPL-3.0-or-later"}


def _extras():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]


def _names(reqs):
    import re

    return {re.split(r"[<>=\[ ;]", r, maxsplit=1)[0].lower() for r in reqs}


def test_reading_flight_data_installs_no_copyleft_package():
    extras = _extras()
    assert {"lxml", "sgp4"} <= _names(extras["flight"])
    assert not _names(extras["flight"]) & set(COPYLEFT), "the flight (reading) extra must stay permissive"
    assert {"oem", "ccsds-ndm"} <= _names(extras["flight-export"])
    assert not _names(extras["dask"] + extras["plot"] + extras["docs"] + extras["spice"]) & set(COPYLEFT)


def test_the_writer_names_its_own_extra():
    from boresight.observations.flight.common import _EXTRAS

    assert _EXTRAS["ccsds_ndm"] == _EXTRAS["oem"] == "flight-export"
    assert _EXTRAS["lxml"] == _EXTRAS["sgp4"] == "flight"
