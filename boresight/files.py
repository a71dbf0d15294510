"""Files that appear complete or not at all: the one atomic writer, for every layer.

Low-level infrastructure like :mod:`boresight.errors` (``tests/project/test_layering.py``): the data
format (``observations.ecsv``), the studies' checkpoints and every command's outputs write
through here, so a killed process never leaves a half-written file.

* ``atomic_path(path)`` yields a temporary name in the same folder (``.<stem>.tmp-<pid><suffix>``,
  keeping the suffix that tells a writer its format) and renames it onto ``path`` when the block
  succeeds; on failure the temporary is removed and ``path`` is untouched;
* ``atomic_write_bytes`` / ``atomic_write_text``: the same for bytes (flushed to disk, or with
  ``sync=False`` left to a later ``sync_files`` of a whole group: the checkpoints) and text;
* ``write_json(path, payload)``: the one JSON writer (indent 2, UTF-8, a final newline; numpy
  arrays and scalars as lists and numbers, anything else JSON cannot hold as its ``str``). It writes
  strict JSON (RFC 8259), which has no NaN or infinity: a non-finite number is written as ``null``
  (:func:`json_ready`), and each format's schema says what ``null`` means there (a σ the data do not
  determine, a ratio of an effect the campaign cannot separate, an undefined p-value). DECISION:
  ``null`` rather than Python's non-standard ``Infinity``/``NaN`` tokens, which ``jq``, JavaScript
  and most JSON readers refuse;
* ``write_table(table, path)``: an astropy table as ECSV.

>>> import tempfile, numpy as np
>>> p = write_json(Path(tempfile.mkdtemp()) / "a.json", {"x": np.arange(2), "n": np.int64(3)})
>>> p.read_text()
'{\\n  "x": [\\n    0,\\n    1\\n  ],\\n  "n": 3\\n}\\n'
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "atomic_path",
    "atomic_write_bytes",
    "sync_files",
    "atomic_write_text",
    "json_text",
    "write_json",
    "json_default",
    "write_table",
]


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """``with atomic_path(p) as tmp: write(tmp)`` → ``p`` appears complete or not at all."""
    path = Path(path)
    if path.is_dir():  # refused before any work, naming the user's path (not the temporary)
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")  # keeps the suffix (savefig's format)
    try:
        try:
            yield tmp
        except OSError as exc:
            # a write that failed (no permission, a file-size limit, disk full) names the user's
            # path: the temporary name, or none at all ("[Errno 27] File too large"), misleads
            if exc.errno is not None and exc.filename in (None, str(tmp), tmp):
                raise type(exc)(exc.errno, exc.strerror or os.strerror(exc.errno), str(path)) from None
            raise
        try:
            os.replace(tmp, path)
        except OSError as exc:  # name the user's path, not the temporary one
            raise type(exc)(exc.errno, exc.strerror, str(path)) from None
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, sync: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically, flushed to disk (``fsync``) before the rename.

    ``sync=False``: renamed without the ``fsync`` — still complete or absent for any crash of the
    process, but a power cut may leave the renamed file empty; the caller then syncs a group of
    files at once (``sync_files``) and checks what it reads back."""
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            if sync:
                os.fsync(fh.fileno())
    return path


def sync_files(paths: Any, folder: str | os.PathLike[str] | None = None) -> None:
    """``fsync`` each of ``paths`` that still exists, then ``folder`` (the renames), if given."""
    for p in paths:
        try:
            fd = os.open(p, os.O_RDONLY)
        except FileNotFoundError:
            continue
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    if folder is not None:
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def atomic_write_text(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> Path:
    """``Path(path).write_text(text)``, but the file appears complete or not at all."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return path


def json_ready(v: Any) -> Any:
    """``v`` made strict-JSON-ready, recursively: dicts and sequences rebuilt, numpy arrays and scalars
    as Python lists and numbers, non-finite floats as None (JSON's ``null``).

    >>> import numpy as np
    >>> json_ready({"a": np.array([1.0, np.nan]), "b": (np.int64(2), np.bool_(True), float("inf"))})
    {'a': [1.0, None], 'b': [2, True, None]}
    """
    if isinstance(v, dict):
        return {k: json_ready(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_ready(x) for x in v]
    if hasattr(v, "tolist") and hasattr(v, "dtype"):  # numpy array or scalar, without importing numpy
        return json_ready(v.tolist())
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    return v


def json_default(o: Any) -> Any:
    """``json.dumps``'s ``default``: numpy arrays as lists, numpy scalars as Python numbers,
    anything else as its ``str``."""
    if hasattr(o, "tolist") and hasattr(o, "dtype"):  # numpy array or scalar, without importing numpy
        return o.tolist()
    return str(o)


def json_text(payload: Any) -> str:
    """``payload`` as strict JSON text (indent 2, a final newline; :func:`json_ready`, then
    :func:`json_default` for what JSON cannot hold): what ``write_json`` writes."""
    return json.dumps(json_ready(payload), indent=2, default=json_default, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike[str], payload: Any) -> Path:
    """``payload`` as strict JSON (:func:`json_text`), atomically."""
    return atomic_write_text(path, json_text(payload))


def write_table(table: Any, path: str | os.PathLike[str]) -> Path:
    """``table.write(path, format="ascii.ecsv", overwrite=True)``, atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        table.write(tmp, format="ascii.ecsv", overwrite=True)
    return path
