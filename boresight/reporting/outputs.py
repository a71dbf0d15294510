"""Output folders and files of the commands: checked, contained and written atomically.

* ``output_folder(path, option)`` creates the folder a command writes into, or refuses with
  ``OutputPathError`` when ``path`` names an existing file (rather than a ``FileExistsError``
  traceback);
* ``inside(out, name)`` is ``out / name``, refused when ``name`` would leave ``out`` (``..``,
  an absolute path, a separator) — scenario names are also checked where they are read
  (``orbits.scenario_schema``), this is the second line of defence;
* ``atomic_path(path)`` yields a temporary name in the same folder and renames it onto
  ``path`` when the block succeeds, so a killed command never leaves a half-written file;
  ``atomic_write_text(path, text)``, ``write_table(table, path)`` (ECSV) and
  ``save_figure(fig, path)`` (matplotlib) are the same for a text file, a table and a plot;
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
import errno
import os
import signal
import threading
from pathlib import Path

from boresight.errors import OutputPathError

__all__ = ["output_folder", "inside", "atomic_path", "atomic_write_text", "write_table", "save_figure", "writing_outputs"]


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


@contextlib.contextmanager
def atomic_path(path):
    """``with atomic_path(p) as tmp: write(tmp)`` → ``p`` appears complete or not at all."""
    path = Path(path)
    if path.is_dir():  # refused before any work, naming the user's path (not the temporary)
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")  # keeps the suffix (savefig's format)
    try:
        yield tmp
        try:
            os.replace(tmp, path)
        except OSError as exc:  # name the user's path, not the temporary one
            raise type(exc)(exc.errno, exc.strerror, str(path)) from None
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """``Path(path).write_text(text)``, but the file appears complete or not at all."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return path


def write_table(table, path) -> Path:
    """``table.write(path, format="ascii.ecsv", overwrite=True)``, atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        table.write(tmp, format="ascii.ecsv", overwrite=True)
    return path


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
