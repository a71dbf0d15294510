"""Output folders and files of the commands: checked, contained and written atomically.

* ``output_folder(path, option)`` creates the folder a command writes into, or refuses with
  ``OutputPathError`` when ``path`` names an existing file (rather than a ``FileExistsError``
  traceback);
* ``inside(out, name)`` is ``out / name``, refused when ``name`` would leave ``out`` (``..``,
  an absolute path, a separator) — scenario names are also checked where they are read
  (``orbits.scenario_schema``), this is the second line of defence;
* ``save_figure(fig, path)`` (matplotlib) writes a plot atomically, through the one atomic
  writer ``boresight.files`` (``atomic_path``, ``atomic_write_text``, ``write_json``,
  ``write_table``), so a killed command never leaves a half-written file;
* ``writing_outputs()`` holds Ctrl-C (SIGINT) and SIGTERM while a command writes its set of
  outputs and delivers them when the set is complete: an interruption leaves the old outputs
  or the complete new ones, never a mix of the two (SIGKILL cannot be held: the per-file
  atomic writes leave each file old or new).

>>> import tempfile
>>> out = output_folder(Path(tempfile.mkdtemp()) / "o")
>>> inside(out, "a.ecsv").name
'a.ecsv'
>>> inside(out, "../../x.ecsv")
Traceback (most recent call last):
...
boresight.errors.OutputPathError: output name '../../x.ecsv' would leave the output folder ...; use a plain file name
"""

from __future__ import annotations

import contextlib
import signal
import threading
from pathlib import Path

from boresight.errors import OutputPathError
from boresight.files import atomic_path

__all__ = [
    "output_folder",
    "check_output_folder",
    "check_output_file",
    "inside",
    "save_figure",
    "writing_outputs",
    "json_on_stdout",
    "write_json_output",
]


def _file_above(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path`` that is not a folder (a file in the way), or None."""
    for parent in path.parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def check_output_folder(path, option: str = "--out") -> None:
    """Refuse (``OutputPathError``, naming ``option``) an output folder that cannot be one — an
    existing file, or a path under a file — before the command does any work (``estimate
    --out FILE`` printed its whole result and then "File exists"). Creates nothing."""
    if path is None:
        return
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{option} {path}: exists and is not a folder; give a folder (new or existing)")
    blocker = _file_above(path)
    if blocker is not None:
        raise OutputPathError(f"{option} {path}: {blocker} is a file, not a folder")


def check_output_file(path, option: str = "--out") -> None:
    """Refuse an output file path that cannot be written — an existing folder, or a path under a
    file — before any work, naming ``option``; ``-`` (standard output) passes. Creates nothing."""
    if path is None or str(path) == "-":
        return
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{option} {path}: is a folder; give a file name")
    blocker = _file_above(path)
    if blocker is not None:
        raise OutputPathError(f"{option} {path}: {blocker} is a file, not a folder")


#: the real standard output while ``json_on_stdout`` sends the command's other lines to stderr
_JSON_STREAMS: list = []


@contextlib.contextmanager
def json_on_stdout():
    """``--json -``: the JSON document alone on standard output (``write_json_output``), the
    command's other lines on standard error, so ``boresight estimate F --json - | jq`` works."""
    import sys

    _JSON_STREAMS.append(sys.stdout)
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        _JSON_STREAMS.pop()


def write_json_output(path, payload) -> Path | None:
    """``files.write_json(path, payload)``, or, for ``path`` ``-``, the same text on standard output
    (the stream saved by ``json_on_stdout``); returns the path written, or None for ``-``."""
    from boresight.files import json_text, write_json

    if str(path) != "-":
        return write_json(path, payload)
    import sys

    stream = _JSON_STREAMS[-1] if _JSON_STREAMS else sys.stdout
    stream.write(json_text(payload))
    stream.flush()
    return None


def output_folder(path, option: str = "--out") -> Path:
    """Create (with parents) and return the output folder ``path``; refuse an existing file."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{option} {path}: exists and is not a folder; give a folder (new or existing)")
    path.mkdir(parents=True, exist_ok=True)
    return path


def inside(out, name: str) -> Path:
    """``out / name`` if it stays inside ``out`` (a plain file name), else ``OutputPathError``."""
    out = Path(out)
    p = Path(name)
    if p.is_absolute() or len(p.parts) != 1 or p.name in ("", ".", "..") or "\x00" in name:
        raise OutputPathError(f"output name {name!r} would leave the output folder {out}; use a plain file name")
    return out / p.name


def save_figure(fig, path, **savefig_kwargs) -> Path:
    """``fig.savefig(path, **kw)``, atomically (the temporary name keeps the suffix, which
    tells matplotlib the format)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **savefig_kwargs)
    return path


#: the signals ``writing_outputs`` holds: Ctrl-C and ``kill``'s default
HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def writing_outputs():
    """``with writing_outputs(): write every file`` — SIGINT and SIGTERM that arrive meanwhile
    are held and delivered (to the handlers in place before) when the block ends, so the
    command's outputs are all new or all old.

    DECISION: holding is done with Python-level handlers that record the signal, not with
    ``pthread_sigmask``: a process-directed signal may be delivered to any thread that does not
    block it (a worker pool's, dask's), and CPython would still run the handler in the main
    thread. Writing a command's outputs takes well under a second to a few seconds (plots);
    that is how long an interruption waits. Off the main thread (where handlers cannot be
    set), the block runs as is.

    >>> import os, signal
    >>> try:
    ...     with writing_outputs():
    ...         os.kill(os.getpid(), signal.SIGINT)
    ...         print("the writing went on")
    ... except KeyboardInterrupt:
    ...     print("then the interrupt")
    the writing went on
    then the interrupt
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {}
    for sig in HELD_SIGNALS:
        previous[sig] = signal.signal(sig, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)  # None: set outside Python
        for sig in dict.fromkeys(held):  # each signal once, in order of arrival
            signal.raise_signal(sig)
