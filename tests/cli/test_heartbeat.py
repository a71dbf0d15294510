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


def test_heartbeat_speaks_only_after_its_delay():
    """diagnose's progress line: nothing for work under the delay, one line per period after it,
    naming the stage."""
    import io
    import time

    from boresight.cli.heartbeat import Heartbeat

    buf = io.StringIO()
    with Heartbeat("diagnose", first_s=0.05, every_s=0.05, stream=buf) as beat:
        beat.stage("naming")
        time.sleep(0.3)
    lines = buf.getvalue().splitlines()
    assert lines[-1].startswith("diagnose: done in ")
    assert lines[:-1] and all(x.startswith("diagnose: naming … ") and x.endswith(" s") for x in lines[:-1])
    quick = io.StringIO()
    with Heartbeat("diagnose", first_s=5.0, stream=quick):
        pass
    assert quick.getvalue() == ""
    quiet = io.StringIO()
    with Heartbeat("diagnose", first_s=0.0, every_s=0.01, quiet=True, stream=quiet):
        time.sleep(0.05)
    assert quiet.getvalue() == ""
