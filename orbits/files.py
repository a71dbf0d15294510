"""What kind of file the user gave: a few bytes read before a parser's own message would confuse.

A scenario (TOML), an observation file (ECSV), a spreadsheet CSV and a CCSDS message are easy to
mix up on a command line; each parser's own error (``Expected '=' after a key`` from TOML,
``ECSV header line … not found`` from astropy) names the symptom, not the mix-up. ``file_kind``
recognises the kind from the first meaningful line, and ``wrong_kind_hint`` gives the one-line
next step. ``read_toml`` is the one TOML reader of scenarios and plans (same errors, same hints).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

__all__ = ["file_kind", "wrong_kind_hint", "read_toml", "utf8_error_location"]

#: how each kind is named in a message, and what to do with it
KINDS = {
    "ecsv": (
        "an observation file (ECSV)",
        "give it to `boresight estimate`, `check`, `diagnose` or `montecarlo` (a study on its own geometry)",
    ),
    "toml": (
        "a TOML file (a scenario or a plan)",
        "write observations from a scenario with `boresight simulate FILE --out DIR`, or plan with `boresight plan FILE`",
    ),
    "csv": (
        "a CSV table",
        "turn pixel detections into an observation file with `boresight ingest --detections …` (docs/data-format.md)",
    ),
    "ccsds-oem": ("a CCSDS orbit message (OEM)", "give it to `boresight ingest --oem`"),
    "ccsds-aem": ("a CCSDS attitude message (AEM)", "give it to `boresight ingest --aem`"),
    "xml": ("an XML file", "CCSDS XML messages go to `boresight ingest`"),
}


def file_kind(path: Any) -> str | None:
    """The kind of ``path`` from its first meaningful line: a key of ``KINDS``, or None if unsure.

    >>> import tempfile, os
    >>> d = tempfile.mkdtemp(); p = os.path.join(d, "f")
    >>> _ = open(p, "w").write("# %ECSV 1.0\\n")
    >>> file_kind(p)
    'ecsv'
    >>> _ = open(p, "w").write("u_px,v_px,landmark\\n1,2,M1\\n")
    >>> file_kind(p)
    'csv'
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return None
    lines = [ln.strip() for ln in head.splitlines() if ln.strip()]
    if not lines:
        return None
    first = lines[0]
    if first.startswith("# %ECSV"):
        return "ecsv"
    if first.startswith("<?xml") or first.startswith("<"):
        return "xml"
    for ln in lines[:5]:
        if ln.startswith("CCSDS_OEM_VERS"):
            return "ccsds-oem"
        if ln.startswith("CCSDS_AEM_VERS"):
            return "ccsds-aem"
    content = [ln for ln in lines if not ln.startswith("#")]
    if not content:
        return None
    if content[0].startswith("[") or ("=" in content[0] and "," not in content[0].split("=")[0]):
        return "toml"
    if content[0].count(",") >= 1 and (len(content) < 2 or content[1].count(",") == content[0].count(",")):
        return "csv"
    return None


def wrong_kind_hint(path: Any, expected_kind: str, expected: str) -> str:
    """``""`` or ``"this is <kind>, not <expected>: <next step>"`` when ``path`` is recognisably
    another kind than ``expected_kind`` (a key of ``KINDS``)."""
    kind = file_kind(path)
    if kind is None or kind == expected_kind or kind not in KINDS:
        return ""
    name, step = KINDS[kind]
    return f"this is {name}, not {expected}: {step}"


def utf8_error_location(exc: UnicodeDecodeError) -> str:
    """Where a UTF-8 decoding failed, as a user finds it in an editor: line and column (1-based),
    not a byte offset.

    >>> try:
    ...     b"a = 1\\nb = '\\xff'\\n".decode("utf-8")
    ... except UnicodeDecodeError as exc:
    ...     print(utf8_error_location(exc))
    line 2, column 6: byte 0xff is not UTF-8 (invalid start byte)
    """
    data = bytes(exc.object)
    line = data.count(b"\n", 0, exc.start) + 1
    column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
    return f"line {line}, column {column}: byte 0x{data[exc.start]:02x} is not UTF-8 ({exc.reason})"


def read_toml(path: Any, error: type[Exception], what: str) -> dict[str, Any]:
    """Parse the TOML file ``path`` (a ``what``: "scenario", "plan"); every failure is one ``error``
    line naming the file — and, when the file is another kind (an observation file, a CSV), the
    kind and the next step instead of the TOML parser's complaint."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        hint = wrong_kind_hint(path, "toml", f"a {what} file (TOML)")
        text = str(exc)
        if "(at end of document)" in text:  # named as a line, as an editor shows it
            with open(path, "rb") as fh:
                lines = fh.read().count(b"\n") + 1
            text = text.replace("(at end of document)", f"(at line {lines}, the end of the file)")
        raise error(f"{path}: {hint}" if hint else f"{path}: not valid TOML: {text}") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not valid TOML: {utf8_error_location(exc)}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not a {what} file (give the .toml file)") from None
    except FileNotFoundError:
        raise error(f"{path}: no such {what} file") from None
