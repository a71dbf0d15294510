"""Output folders and files of the commands: checked, contained and written atomically.

* ``output_folder(path, option)`` creates the folder a command writes into, or refuses with
  ``OutputPathError`` when ``path`` names an existing file (rather than a ``FileExistsError``
  traceback);
* ``inside(out, name)`` is ``out / name``, refused when ``name`` would leave ``out`` (``..``,
  an absolute path, a separator) — scenario names are also checked where they are read
  (``orbits.scenario_schema``), this is the second line of defence;
* ``atomic_path(path)`` yields a temporary name in the same folder and renames it onto
  ``path`` when the block succeeds, so a killed command never leaves a half-written file.

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
import os
from pathlib import Path

from boresight.errors import OutputPathError

__all__ = ["output_folder", "inside", "atomic_path"]


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
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")  # keeps the suffix (savefig's format)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
