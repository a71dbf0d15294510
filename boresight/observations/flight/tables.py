"""CSV reading with errors naming the file, the column and the row."""

from __future__ import annotations

import csv

import numpy as np

from boresight.observations.flight.common import IngestError

__all__ = ["read_csv_columns"]


def read_csv_columns(path, required=(), optional=(), text=("time_utc", "landmark", "id")) -> dict:
    """Columns of a CSV with a header line (``#`` comment lines skipped): numbers as float arrays
    (refusing non-numbers and non-finite values with the row), ``text`` columns as str arrays."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = [r for r in csv.reader(line for line in f if line.strip() and not line.lstrip().startswith("#"))]
    except FileNotFoundError:
        raise
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise IngestError(f"{path}: cannot read as CSV: {exc}") from exc
    if not rows:
        raise IngestError(f"{path}: empty CSV (a header line is needed)")
    head = [h.strip() for h in rows[0]]
    body = rows[1:]
    if not body:
        raise IngestError(f"{path}: no data rows")
    missing = [c for c in required if c not in head]
    if missing:
        raise IngestError(
            f"{path}: missing column(s) {', '.join(repr(c) for c in missing)}; the header has {', '.join(repr(h) for h in head)}"
        )
    out = {}
    for name in list(required) + [c for c in optional if c in head]:
        j = head.index(name)
        vals = []
        for i, row in enumerate(body, start=1):
            if j >= len(row):
                raise IngestError(f"{path}: row {i}: column {name!r} is missing (the row has {len(row)} fields)")
            vals.append(row[j].strip())
        if name in text:
            out[name] = np.array(vals, dtype=str)
            continue
        arr = np.empty(len(vals))
        for i, s in enumerate(vals, start=1):
            try:
                arr[i - 1] = float(s)
            except ValueError:
                raise IngestError(f"{path}: column {name!r} row {i}: {s!r} is not a number") from None
            if not np.isfinite(arr[i - 1]):
                raise IngestError(f"{path}: column {name!r} row {i}: non-finite value {s!r}")
        out[name] = arr
    return out
