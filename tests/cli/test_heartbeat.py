"""The heartbeat of long commands without a progress bar (``boresight.cli.heartbeat``; issue 19)."""

from __future__ import annotations

import io
import time

import pytest

from boresight.cli.heartbeat import heartbeat


def test_heartbeat_is_silent_for_short_work_and_beats_for_long_work():
    buf = io.StringIO()
    with heartbeat("quick", first_s=5.0, stream=buf):
        pass
    assert buf.getvalue() == ""
    buf = io.StringIO()
    with heartbeat("slow", first_s=0.05, every_s=0.05, stream=buf):
        time.sleep(0.4)
    lines = buf.getvalue().splitlines()
    assert len(lines) >= 3 and lines[0].startswith("slow: still working, ") and lines[-1].startswith("slow: done in ")


def test_heartbeat_stops_when_the_work_raises():
    buf = io.StringIO()
    with pytest.raises(RuntimeError):
        with heartbeat("failing", first_s=0.01, every_s=0.01, stream=buf):
            time.sleep(0.1)
            raise RuntimeError("boom")
    n = len(buf.getvalue().splitlines())
    time.sleep(0.1)
    assert len(buf.getvalue().splitlines()) == n  # no beat after the block ended
