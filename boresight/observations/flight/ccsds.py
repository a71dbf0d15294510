"""A strict reader of CCSDS OEM (502.0-B, versions 1.0 / 2.0 / 3.0) and AEM (504.0-B, versions
1.0 / 2.0) messages, KVN and XML, that checks what the standard says by version and names the
file, the keyword and the line of every refusal.

It returns the messages as text items with their line numbers (``Message``); the orbit and attitude
readers (``orbit.py``, ``attitude.py``) turn them into numbers and frames.

Rules checked (CCSDS 502.0-B-2/-3 tables 5-2, 5-3, 5-4; 504.0-B-1/-2 AEM tables; Orekit's
``OemMetadata`` / ``AemMetadata`` / ``AttitudeEndpoints`` validate methods as the reference for
behaviour):

* the first keyword is ``CCSDS_OEM_VERS`` / ``CCSDS_AEM_VERS`` with a version this reader knows;
* header: ``CREATION_DATE`` and ``ORIGINATOR`` mandatory; ``MESSAGE_ID`` and ``CLASSIFICATION``
  only from OEM 3.0 / AEM 2.0;
* metadata: every mandatory keyword present, every keyword allowed in that version
  (``REF_FRAME_EPOCH`` from OEM 2.0; AEM 1.0 requires ``ATTITUDE_DIR`` and, for quaternions,
  ``QUATERNION_TYPE``; AEM 2.0 quaternions are A2B and scalar-last, so those keywords may only
  repeat that), no keyword twice; ``INTERPOLATION_DEGREE`` required with ``INTERPOLATION``;
* data: the number of fields per line for the version and type (OEM 1.0: epoch + 6; 2.0/3.0:
  epoch + 6 or + 9; AEM per ``ATTITUDE_TYPE``), numbers that parse, epochs inside
  ``START_TIME .. STOP_TIME``, covering it, and strictly increasing within a segment; the useable
  span inside the segment's span; every OEM state plausible for an Earth orbiter (``orbit.py``);
* covariance blocks (OEM 2.0 and later): ``EPOCH``, optional ``COV_REF_FRAME``, 21 numbers in a
  lower triangle of 1..6 per line.

DECISION: our own strict layer, not the ``oem`` / ``ccsds-ndm`` readers. Those libraries refuse
valid files (OEM 3.0 ``CLASSIFICATION`` / ``MESSAGE_ID``; any AEM 2.0 quaternion segment: a
KeyError inside ccsds-ndm), accept invalid ones (AEM 1.0 without ``QUATERNION_TYPE`` silently
read scalar-first; ``ATTITUDE_DIR`` missing read as B2A), merge segments, and report errors
without a line or on the wrong one. The formats are small (key = value lines and whitespace
separated data), so checking them here costs ~400 lines and gives one behaviour for KVN and XML.
The libraries remain the independent WRITERS the tests read (``export.py`` uses them).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from boresight.observations.flight.common import IngestError

__all__ = ["Item", "Segment", "Message", "read_message", "COV_NAMES"]


@dataclass(frozen=True)
class Item:
    """A keyword's value as written, and the line it is on (1-based)."""

    value: str
    line: int


@dataclass
class Segment:
    index: int  # 0-based
    line: int  # META_START (KVN) / <segment> (XML)
    meta: dict = field(default_factory=dict)  # keyword -> Item
    rows: list = field(default_factory=list)  # (line, [field strings]) ; AEM XML rows are scalar-last quaternions
    covariance: list = field(default_factory=list)  # {"epoch": Item, "frame": Item | None, "values": [21 str], "line": int}
    end_line: int = 0


@dataclass
class Message:
    path: str
    kind: str  # "OEM" or "AEM"
    version: str  # "1.0", "2.0", "3.0"
    fmt: str  # "KVN" or "XML"
    header: dict  # keyword -> Item
    segments: list
    version_line: int = 1

    def where(self, line) -> str:
        return f"{self.path}: line {line}"


_VERSIONS = {"OEM": ("1.0", "2.0", "3.0"), "AEM": ("1.0", "2.0")}

_HEADER = {"COMMENT", "CREATION_DATE", "ORIGINATOR"}
_HEADER_NEW = {"MESSAGE_ID", "CLASSIFICATION"}  # OEM >= 3.0, AEM >= 2.0
_HEADER_MANDATORY = ("CREATION_DATE", "ORIGINATOR")

_OEM_META = {
    "COMMENT",
    "OBJECT_NAME",
    "OBJECT_ID",
    "CENTER_NAME",
    "REF_FRAME",
    "TIME_SYSTEM",
    "START_TIME",
    "USEABLE_START_TIME",
    "USEABLE_STOP_TIME",
    "STOP_TIME",
    "INTERPOLATION",
    "INTERPOLATION_DEGREE",
}
_OEM_META_NEW = {"REF_FRAME_EPOCH"}  # OEM >= 2.0
_OEM_MANDATORY = ("OBJECT_NAME", "OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM", "START_TIME", "STOP_TIME")

_AEM_META_COMMON = {
    "COMMENT",
    "OBJECT_NAME",
    "OBJECT_ID",
    "CENTER_NAME",
    "REF_FRAME_A",
    "REF_FRAME_B",
    "TIME_SYSTEM",
    "START_TIME",
    "USEABLE_START_TIME",
    "USEABLE_STOP_TIME",
    "STOP_TIME",
    "ATTITUDE_TYPE",
    "EULER_ROT_SEQ",
    "INTERPOLATION_METHOD",
    "INTERPOLATION_DEGREE",
}
_AEM_META = {
    "1.0": _AEM_META_COMMON | {"ATTITUDE_DIR", "QUATERNION_TYPE", "RATE_FRAME"},
    # 2.0: ATTITUDE_DIR is checked to say A2B (Orekit accepts it so); QUATERNION_TYPE is refused (_check_aem_segment)
    "2.0": _AEM_META_COMMON | {"ATTITUDE_DIR", "QUATERNION_TYPE", "ANGVEL_FRAME"},
}
_AEM_MANDATORY = (
    "OBJECT_NAME",
    "OBJECT_ID",
    "REF_FRAME_A",
    "REF_FRAME_B",
    "TIME_SYSTEM",
    "START_TIME",
    "STOP_TIME",
    "ATTITUDE_TYPE",
)

#: AEM attitude types this reader turns into quaternions, with the number of numbers per data line
AEM_QUATERNION_TYPES = {
    "1.0": {"QUATERNION": 4, "QUATERNION/DERIVATIVE": 8, "QUATERNION/RATE": 7},
    "2.0": {"QUATERNION": 4, "QUATERNION/DERIVATIVE": 8, "QUATERNION/ANGVEL": 7},
}

#: the 21 covariance elements of an OEM covariance block, lower triangle row by row (XML names)
_AX = ("X", "Y", "Z", "X_DOT", "Y_DOT", "Z_DOT")
COV_NAMES = tuple(f"C{_AX[i]}_{_AX[j]}" for i in range(6) for j in range(i + 1))

_KV = re.compile(r"^([A-Z][A-Z0-9_]*)\s*=\s*(.*?)\s*$")


def _refuse(msg_or_path, line, text):
    path = msg_or_path.path if isinstance(msg_or_path, Message) else str(msg_or_path)
    raise IngestError(f"{path}: line {line}: {text}")


def read_message(path, kind: str) -> Message:
    """Parse and check a CCSDS ``kind`` ("OEM" or "AEM") message, KVN or XML, from ``path``."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise IngestError(f"{path}: cannot read: {exc}") from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise IngestError(f"{path}: not UTF-8/ASCII text (byte {exc.start}); a CCSDS {kind} is ASCII") from exc
    if text.lstrip().startswith("<"):
        msg = _parse_xml(str(path), text, kind)
    else:
        msg = _parse_kvn(str(path), text, kind)
    _check(msg)
    return msg


# ------------------------------------------------------------------------------------- KVN


class _Lines:
    """The KVN lines without blanks and COMMENT lines: ``next()`` gives (1-based line number, stripped
    text), or (None, None) at the end; ``n`` is the number of lines of the file."""

    def __init__(self, text):
        self.lines = text.splitlines()
        self.n = len(self.lines)
        self.k = 0

    def next(self):
        while self.k < self.n:
            s = self.lines[self.k].strip()
            self.k += 1
            if s and not s.startswith("COMMENT"):
                return self.k, s
        return None, None

    def until(self, path, stop: str, where: str):
        """The (line, text) up to the line ``stop`` (the current line after it); the file ending
        first is refused: ``PATH: line N: the file ends <where>; no <stop>``."""
        while True:
            ln, s = self.next()
            if ln is None:
                raise IngestError(f"{path}: line {self.n}: the file ends {where}; no {stop}")
            if s == stop:
                return
            yield ln, s


def _kvn_version(path, cur, kind):
    """The first line, CCSDS_<kind>_VERS: the Message, or a refusal naming what was found."""
    ln, s = cur.next()
    if ln is None:
        raise IngestError(f"{path}: empty file; a CCSDS {kind} starts with CCSDS_{kind}_VERS")
    m = _KV.match(s)
    if not m or m.group(1) != f"CCSDS_{kind}_VERS":
        other = "AEM" if kind == "OEM" else "OEM"
        if m and m.group(1) == f"CCSDS_{other}_VERS":
            _refuse(path, ln, f"this is a CCSDS {other} (CCSDS_{other}_VERS), not the {kind} this option reads")
        _refuse(path, ln, f"a CCSDS {kind} starts with 'CCSDS_{kind}_VERS = <version>', found {s[:40]!r}")
    return Message(path, kind, m.group(2), "KVN", {}, [], ln)


def _kvn_header(msg, cur):
    """The header keywords up to the first META_START: its (line, text)."""
    for ln, s in cur.until(msg.path, "META_START", "in the header"):
        _store(msg, msg.header, ln, s, "header")
    return cur.k, "META_START"


def _kvn_metadata(msg, seg, cur):
    """A segment's metadata keywords up to META_STOP."""
    for ln, s in cur.until(msg.path, "META_STOP", f"inside the metadata of segment {seg.index + 1}"):
        _store(msg, seg.meta, ln, s, f"segment {seg.index + 1} metadata")


def _kvn_aem_data(msg, seg, cur, ln, s):
    """An AEM segment's DATA_START .. DATA_STOP rows; the (line, text) after DATA_STOP."""
    if s != "DATA_START":
        _refuse(
            msg.path,
            ln or cur.n,
            f"segment {seg.index + 1}: expected DATA_START after META_STOP, found {(s or 'the end of the file')[:40]!r}",
        )
    for ln, s in cur.until(msg.path, "DATA_STOP", f"inside the data of segment {seg.index + 1}"):
        if _KV.match(s):
            _refuse(msg.path, ln, f"segment {seg.index + 1}: keyword {s.split('=')[0].strip()} inside DATA_START .. DATA_STOP")
        seg.rows.append((ln, s.split()))
    seg.end_line = cur.k  # the DATA_STOP line
    return cur.next()


def _kvn_oem_data(msg, seg, cur, ln, s):
    """An OEM segment's state lines and its covariance block, if any; the (line, text) after them."""
    while ln is not None and s not in ("META_START", "COVARIANCE_START"):
        if _KV.match(s):
            _refuse(
                msg.path,
                ln,
                f"segment {seg.index + 1}: keyword {s.split('=')[0].strip()} among the state lines (a misplaced metadata keyword?)",
            )
        seg.rows.append((ln, s.split()))
        seg.end_line = ln
        ln, s = cur.next()
    if s == "COVARIANCE_START":
        if msg.version == "1.0":
            _refuse(msg.path, ln, "COVARIANCE_START: covariance blocks are not allowed in OEM 1.0 (from 2.0)")
        ln, s = _kvn_covariance(msg, seg, cur.next, ln)
    return ln, s


def _parse_kvn(path, text, kind):
    cur = _Lines(text)
    msg = _kvn_version(path, cur, kind)
    ln, s = _kvn_header(msg, cur)
    read_data = _kvn_aem_data if kind == "AEM" else _kvn_oem_data
    while ln is not None:  # segments
        if s != "META_START":
            _refuse(path, ln, f"expected META_START (a new segment) or the end of the file, found {s[:40]!r}")
        seg = Segment(len(msg.segments), ln)
        msg.segments.append(seg)
        _kvn_metadata(msg, seg, cur)
        ln, s = cur.next()
        ln, s = read_data(msg, seg, cur, ln, s)
    return msg


def _kvn_covariance(msg, seg, next_line, start):
    cur = None
    while True:
        ln, s = next_line()
        if ln is None:
            _refuse(msg, start, f"segment {seg.index + 1}: COVARIANCE_START without COVARIANCE_STOP")
        if s == "COVARIANCE_STOP":
            if cur is not None:
                _close_cov(msg, seg, cur)
            return next_line()
        m = _KV.match(s)
        if m:
            key, val = m.groups()
            if key == "EPOCH":
                if cur is not None:
                    _close_cov(msg, seg, cur)
                cur = {"epoch": Item(val, ln), "frame": None, "values": [], "line": ln, "rows": 0}
            elif key == "COV_REF_FRAME" and cur is not None and not cur["values"]:
                cur["frame"] = Item(val, ln)
            else:
                _refuse(
                    msg, ln, f"segment {seg.index + 1}: keyword {key} is not allowed in a covariance block (EPOCH, COV_REF_FRAME)"
                )
            continue
        if cur is None:
            _refuse(msg, ln, f"segment {seg.index + 1}: covariance numbers before the block's EPOCH")
        parts = s.split()
        cur["rows"] += 1
        if cur["rows"] > 6 or len(parts) != cur["rows"]:
            _refuse(
                msg,
                ln,
                f"segment {seg.index + 1}: covariance row {cur['rows']} has {len(parts)} number(s); a lower triangle has "
                f"{min(cur['rows'], 6)} on this row (21 in 6 rows)",
            )
        cur["values"] += parts


def _close_cov(msg, seg, cur):
    if len(cur["values"]) != 21:
        _refuse(
            msg,
            cur["line"],
            f"segment {seg.index + 1}: covariance block at EPOCH {cur['epoch'].value} has {len(cur['values'])} numbers, "
            "expected 21 (lower triangle of the 6 x 6 matrix)",
        )
    seg.covariance.append({k: cur[k] for k in ("epoch", "frame", "values", "line")})


def _store(msg, d, ln, s, where):
    m = _KV.match(s)
    if not m:
        _refuse(msg, ln, f"{where}: expected 'KEYWORD = value', found {s[:40]!r}")
    key, val = m.groups()
    val = re.sub(r"\s*\[[^\]]*\]$", "", val)  # a trailing [unit]
    if key in d:
        _refuse(msg, ln, f"{where}: keyword {key} given twice (first on line {d[key].line})")
    d[key] = Item(val, ln)


# ------------------------------------------------------------------------------------- XML


def _xml_tag(e):
    from lxml import etree

    return etree.QName(e).localname if isinstance(e.tag, str) else None


def _xml_kids(e):
    return [c for c in e if isinstance(c.tag, str)]


def _xml_root(path, text, kind):
    """The parsed root element, checked to be a <kind> with its id and version."""
    try:
        from lxml import etree
    except ImportError:  # pragma: no cover - lxml comes with the flight extra
        from boresight.errors import extra_hint

        raise IngestError(f"{path}: reading CCSDS XML needs lxml, {extra_hint('flight')}") from None
    try:
        root = etree.fromstring(text.encode("utf-8"), etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False))
    except etree.XMLSyntaxError as exc:
        raise IngestError(f"{path}: line {exc.lineno}: not well-formed XML: {exc.msg}") from None
    rt = _xml_tag(root)
    if rt != kind.lower():
        if rt in ("oem", "aem"):
            _refuse(path, root.sourceline, f"this is a CCSDS {rt.upper()} (<{rt}>), not the {kind} this option reads")
        _refuse(
            path,
            root.sourceline,
            f"root element <{rt}>; a CCSDS {kind} in XML is <{kind.lower()}> (an NDM combined message is not supported)",
        )
    if root.get("id") != f"CCSDS_{kind}_VERS" or root.get("version") is None:
        _refuse(path, root.sourceline, f'<{rt}> needs id="CCSDS_{kind}_VERS" and a version attribute')
    return root


def _xml_state_vector(msg, seg, d):
    v = {_xml_tag(c): c for c in _xml_kids(d)}
    names = ["EPOCH", "X", "Y", "Z", "X_DOT", "Y_DOT", "Z_DOT"] + (["X_DDOT", "Y_DDOT", "Z_DDOT"] if "X_DDOT" in v else [])
    miss = [x for x in names if x not in v]
    if miss or len(v) != len(names):
        _refuse(
            msg.path,
            d.sourceline,
            f"segment {seg.index + 1}: <stateVector> needs {', '.join(names)}; "
            + (f"{miss[0]} missing" if miss else f"unexpected <{sorted(set(v) - set(names))[0]}>"),
        )
    seg.rows.append((d.sourceline, [(v[x].text or "").strip() for x in names]))


def _xml_covariance(msg, seg, d):
    if msg.version == "1.0":
        _refuse(msg.path, d.sourceline, "<covarianceMatrix>: covariance is not allowed in OEM 1.0 (from 2.0)")
    v = {_xml_tag(c): c for c in _xml_kids(d)}
    miss = [x for x in ("EPOCH",) + COV_NAMES if x not in v]
    if miss:
        _refuse(msg.path, d.sourceline, f"segment {seg.index + 1}: <covarianceMatrix> without {miss[0]}")
    fr = v.get("COV_REF_FRAME")
    seg.covariance.append(
        {
            "epoch": Item((v["EPOCH"].text or "").strip(), v["EPOCH"].sourceline),
            "frame": None if fr is None else Item((fr.text or "").strip(), fr.sourceline),
            "values": [(v[x].text or "").strip() for x in COV_NAMES],
            "line": d.sourceline,
        }
    )


def _xml_attitude_state(msg, seg, d):
    st = _xml_kids(d)
    if len(st) != 1:
        _refuse(msg.path, d.sourceline, f"segment {seg.index + 1}: <attitudeState> holds one state element, found {len(st)}")
    st = st[0]
    v = {_xml_tag(c): c for c in _xml_kids(st)}
    q = v.get("quaternion")
    if "EPOCH" not in v or q is None:
        _refuse(
            msg.path,
            st.sourceline,
            f"segment {seg.index + 1}: <{_xml_tag(st)}>: only quaternion states are read (EPOCH and <quaternion>)",
        )
    qv = {_xml_tag(c): c for c in _xml_kids(q)}
    miss = [x for x in ("Q1", "Q2", "Q3", "QC") if x not in qv]
    if miss:
        _refuse(msg.path, q.sourceline, f"segment {seg.index + 1}: <quaternion> without <{miss[0]}>")
    # XML names the scalar: rows are stored scalar-last whatever the element order
    seg.rows.append(
        (st.sourceline, [(v["EPOCH"].text or "").strip()] + [(qv[x].text or "").strip() for x in ("Q1", "Q2", "Q3", "QC")])
    )


#: the elements a segment's <data> may hold, per message kind, and the reader of each
_XML_DATA = {
    ("OEM", "stateVector"): _xml_state_vector,
    ("OEM", "covarianceMatrix"): _xml_covariance,
    ("AEM", "attitudeState"): _xml_attitude_state,
}


def _xml_segment(msg, s):
    """One <segment>: its metadata keywords and its data rows."""
    if _xml_tag(s) != "segment":
        _refuse(msg.path, s.sourceline, f"<body> holds <segment> elements, found <{_xml_tag(s)}>")
    seg = Segment(len(msg.segments), s.sourceline)
    msg.segments.append(seg)
    sub = {_xml_tag(c): c for c in _xml_kids(s)}
    if "metadata" not in sub or "data" not in sub:
        _refuse(msg.path, s.sourceline, f"segment {seg.index + 1}: <segment> needs <metadata> and <data>")
    for c in _xml_kids(sub["metadata"]):
        _store_xml(msg, seg.meta, c, f"segment {seg.index + 1} metadata", _xml_tag)
    for d in _xml_kids(sub["data"]):
        t = _xml_tag(d)
        if t == "COMMENT":
            continue
        read = _XML_DATA.get((msg.kind, t))
        if read is None:
            _refuse(msg.path, d.sourceline, f"segment {seg.index + 1}: unexpected <{t}> in <data> of a CCSDS {msg.kind}")
        read(msg, seg, d)
    seg.end_line = sub["data"].sourceline


def _parse_xml(path, text, kind):
    root = _xml_root(path, text, kind)
    rt = _xml_tag(root)
    msg = Message(path, kind, root.get("version"), "XML", {}, [], root.sourceline)
    parts = {_xml_tag(c): c for c in _xml_kids(root)}
    if "header" not in parts or "body" not in parts:
        _refuse(path, root.sourceline, f"<{rt}> needs <header> and <body>")
    for c in _xml_kids(parts["header"]):
        _store_xml(msg, msg.header, c, "header", _xml_tag)
    for s in _xml_kids(parts["body"]):
        _xml_segment(msg, s)
    msg.fmt = "XML"
    return msg


def _store_xml(msg, d, e, where, tag):
    key = tag(e)
    if key == "COMMENT":
        return
    if key in d:
        _refuse(msg, e.sourceline, f"{where}: keyword {key} given twice (first on line {d[key].line})")
    d[key] = Item((e.text or "").strip(), e.sourceline)


# ------------------------------------------------------------------------------------ checks


def _check(msg: Message):
    kind, ver = msg.kind, msg.version.strip()
    if ver not in _VERSIONS[kind]:
        _refuse(
            msg,
            msg.version_line,
            f"CCSDS_{kind}_VERS = {msg.version!r} is not a version this reader knows ({', '.join(_VERSIONS[kind])})",
        )
    msg.version = ver
    new_header = ver >= ("3.0" if kind == "OEM" else "2.0")
    for key, it in msg.header.items():
        if key in _HEADER or (new_header and key in _HEADER_NEW):
            continue
        if key in _HEADER_NEW:
            first = "3.0" if kind == "OEM" else "2.0"
            _refuse(msg, it.line, f"header keyword {key} is not allowed in {kind} {ver} (from {first})")
        _refuse(msg, it.line, f"{key} is not a {kind} {ver} header keyword")
    end_header = msg.segments[0].line if msg.segments else msg.version_line
    for key in _HEADER_MANDATORY:
        if key not in msg.header:
            _refuse(msg, end_header, f"the header has no {key} (mandatory in {kind} {ver}); the header ends here")
    if not msg.segments:
        _refuse(msg, msg.version_line, f"no segment (META_START .. META_STOP) in this {kind}")
    for seg in msg.segments:
        (_check_oem_segment if kind == "OEM" else _check_aem_segment)(msg, seg)


def _meta_keys(msg, seg, allowed, mandatory, later=()):
    for key, it in seg.meta.items():
        if key not in allowed:
            hint = next((f" (from {v})" for k, v in later if k == key), "")
            _refuse(msg, it.line, f"segment {seg.index + 1}: {key} is not a {msg.kind} {msg.version} metadata keyword{hint}")
    for key in mandatory:
        if key not in seg.meta:
            _refuse(msg, seg.line, f"segment {seg.index + 1}: metadata without {key} (mandatory in {msg.kind} {msg.version})")


def _check_interpolation_degree(msg, seg, method_key):
    if method_key in seg.meta and "INTERPOLATION_DEGREE" not in seg.meta:
        _refuse(
            msg,
            seg.meta[method_key].line,
            f"segment {seg.index + 1}: {method_key} without INTERPOLATION_DEGREE (required with it)",
        )
    if "INTERPOLATION_DEGREE" in seg.meta:
        it = seg.meta["INTERPOLATION_DEGREE"]
        if not re.fullmatch(r"\+?\d+", it.value) or int(it.value) < 1:
            _refuse(msg, it.line, f"segment {seg.index + 1}: INTERPOLATION_DEGREE {it.value!r} is not a positive integer")


def _require_earth_centre(msg, seg, why):
    """Refuse a segment whose CENTER_NAME is not EARTH, naming its line and ``why`` (OEM and AEM alike)."""
    c = seg.meta["CENTER_NAME"]
    if c.value.strip().upper() != "EARTH":
        _refuse(msg, c.line, f"segment {seg.index + 1}: CENTER_NAME {c.value!r}; {why} (CENTER_NAME = EARTH)")


def _check_oem_segment(msg, seg):
    allowed = _OEM_META | (_OEM_META_NEW if msg.version >= "2.0" else set())
    _meta_keys(msg, seg, allowed, _OEM_MANDATORY, later=[("REF_FRAME_EPOCH", "2.0")])
    _check_interpolation_degree(msg, seg, "INTERPOLATION")
    if "INTERPOLATION" in seg.meta and seg.meta["INTERPOLATION"].value.upper() not in ("LAGRANGE", "HERMITE", "LINEAR"):
        it = seg.meta["INTERPOLATION"]
        _refuse(
            msg, it.line, f"segment {seg.index + 1}: INTERPOLATION {it.value!r} is not supported (LAGRANGE, HERMITE or LINEAR)"
        )
    _require_earth_centre(msg, seg, "boresight needs Earth-centred states")
    if not seg.rows:
        _refuse(msg, seg.line, f"segment {seg.index + 1}: no state lines")
    widths = (7,) if msg.version == "1.0" else (7, 10)
    for ln, parts in seg.rows:
        if len(parts) not in widths:
            _refuse(
                msg,
                ln,
                f"segment {seg.index + 1}: {len(parts)} fields on a state line; OEM {msg.version} has "
                + " or ".join(f"{w} (epoch, {'position, velocity' + (', acceleration' if w == 10 else '')})" for w in widths),
            )


def _check_aem_segment(msg, seg):
    ver = msg.version
    _meta_keys(msg, seg, _AEM_META[ver], _AEM_MANDATORY)
    _check_interpolation_degree(msg, seg, "INTERPOLATION_METHOD")
    if "CENTER_NAME" in seg.meta:
        _require_earth_centre(msg, seg, "boresight reads the attitude of an Earth orbiter")
    at = seg.meta["ATTITUDE_TYPE"]
    types = AEM_QUATERNION_TYPES[ver]
    if at.value.strip().upper() not in types:
        _refuse(msg, at.line, f"segment {seg.index + 1}: ATTITUDE_TYPE {at.value!r} is not read (AEM {ver}: {', '.join(types)})")
    d = seg.meta.get("ATTITUDE_DIR")
    qt = seg.meta.get("QUATERNION_TYPE")
    if ver == "1.0":
        # no silent defaults: AEM 1.0 requires both (504.0-B-1 table 4-3)
        if d is None:
            _refuse(msg, seg.line, f"segment {seg.index + 1}: metadata without ATTITUDE_DIR (mandatory in AEM 1.0: A2B or B2A)")
        if qt is None:
            _refuse(
                msg,
                seg.line,
                f"segment {seg.index + 1}: metadata without QUATERNION_TYPE (mandatory in AEM 1.0 for {at.value.strip()}: FIRST or LAST)",
            )
        if d.value.strip().upper() not in ("A2B", "B2A"):
            _refuse(msg, d.line, f"segment {seg.index + 1}: ATTITUDE_DIR {d.value!r} is not A2B or B2A")
        if qt.value.strip().upper() not in ("FIRST", "LAST"):
            _refuse(msg, qt.line, f"segment {seg.index + 1}: QUATERNION_TYPE {qt.value!r} is not FIRST or LAST")
    else:
        if d is not None and d.value.strip().upper() != "A2B":
            _refuse(
                msg,
                d.line,
                f"segment {seg.index + 1}: ATTITUDE_DIR {d.value!r} is not allowed in AEM 2.0 (its quaternions always rotate A into B)",
            )
        # DECISION: QUATERNION_TYPE is a 1.0 keyword; 504.0-B-2 has none (its quaternions
        # are scalar-last by definition). Orekit refuses FIRST and tolerates LAST; we refuse both: a
        # 2.0 header over 1.0 metadata is a writer's slip, and its data order cannot be trusted.
        if qt is not None:
            _refuse(
                msg,
                qt.line,
                f"segment {seg.index + 1}: QUATERNION_TYPE {qt.value!r} is not allowed in AEM 2.0 (a 1.0 keyword: 2.0 "
                "quaternions are scalar-last by definition); remove it, or write CCSDS_AEM_VERS = 1.0 if the data follow 1.0",
            )
    if not seg.rows:
        _refuse(msg, seg.line, f"segment {seg.index + 1}: no attitude lines")
    want = 1 + (4 if msg.fmt == "XML" else types[at.value.strip().upper()])
    for ln, parts in seg.rows:
        if len(parts) != want:
            _refuse(
                msg,
                ln,
                f"segment {seg.index + 1}: {len(parts)} fields on an attitude line; ATTITUDE_TYPE {at.value.strip()} in AEM {ver} has {want} (epoch and {want - 1} numbers)",
            )


# ------------------------------------------------------------------------------- epochs, numbers

_DOY = re.compile(r"^(\d{4})-(\d{3})T(\d{2}:\d{2}:\d{2}(?:\.\d*)?)Z?$")
_YMD = re.compile(r"^\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(?:\.\d*)?Z?$")
#: CCSDS TIME_SYSTEM → (astropy scale, seconds to add to the reading in that scale)
# DECISION: GPS time is TAI − 19 s exactly (no leap seconds); an epoch written in GPS is read as TAI
# after adding 19 s. MET/MRT/SCLK and the other relative systems need an epoch origin: refused.
TIME_SYSTEMS = {
    "UTC": ("utc", 0.0),
    "TAI": ("tai", 0.0),
    "TT": ("tt", 0.0),
    "GPS": ("tai", 19.0),
    "TDB": ("tdb", 0.0),
    "TCB": ("tcb", 0.0),
    "TCG": ("tcg", 0.0),
    "UT1": ("ut1", 0.0),
}


#: the time systems a slip is looked for in, instead of the declared one (``culprit``, ``common.time_slip_hint``)
TIME_SYSTEMS_TRIED = ("UTC", "TAI", "GPS", "TT")


def time_system_shift_s(t: Any, declared: str, alt: str) -> float:
    """δ (s): how much later an epoch lands in UTC when read in ``alt`` instead of ``declared`` (CCSDS
    TIME_SYSTEM names), at the middle of ``t`` (astropy Time, UTC; the leap seconds of that date)."""
    from astropy import units as u
    from astropy.time import Time

    s0, off0 = TIME_SYSTEMS[declared]
    s1, off1 = TIME_SYSTEMS[alt]
    t_mid = t[len(t) // 2]
    as_written = getattr(t_mid, s0) - off0 * u.s
    as_written.precision = 9  # isot's default 3 digits would move δ by up to 0.5 ms
    written = as_written.isot  # the epoch as the file wrote it
    return float(((Time(written, scale=s1) + off1 * u.s).utc - t_mid).to_value("s"))


def time_system_shifts(t: Any, declared: str) -> tuple:
    """((alt, δ s), …) for each of ``TIME_SYSTEMS_TRIED`` but ``declared`` (``time_system_shift_s`` at ``t``);
    empty when ``declared`` is not one of them."""
    if declared not in TIME_SYSTEMS_TRIED:
        return ()
    return tuple((alt, time_system_shift_s(t, declared, alt)) for alt in TIME_SYSTEMS_TRIED if alt != declared)


def time_system(msg, seg):
    it = seg.meta["TIME_SYSTEM"]
    ts = it.value.strip().upper()
    if ts not in TIME_SYSTEMS:
        _refuse(msg, it.line, f"segment {seg.index + 1}: TIME_SYSTEM {it.value!r} is not supported ({', '.join(TIME_SYSTEMS)})")
    return TIME_SYSTEMS[ts]


def epochs(msg, seg, items):
    """astropy Time (UTC) of ``items`` [(string, line)] in the segment's TIME_SYSTEM; a bad epoch is refused with its line."""
    from astropy import units as u
    from astropy.time import Time

    scale, offset = time_system(msg, seg)
    iso = []
    for s, ln in items:
        s = s.strip()
        m = _DOY.match(s)
        if m:
            iso.append((f"{m.group(1)}:{m.group(2)}:{m.group(3)}", "yday", ln))
        elif _YMD.match(s):
            iso.append((s.rstrip("Z"), "isot", ln))
        else:
            _refuse(
                msg,
                ln,
                f"segment {seg.index + 1}: epoch {s[:40]!r} is not a CCSDS time (YYYY-MM-DDThh:mm:ss[.d] or YYYY-DDDThh:mm:ss[.d])",
            )
    out = []
    for fmt in ("isot", "yday"):
        sel = [x for x in iso if x[1] == fmt]
        if not sel:
            continue
        try:
            t = Time([x[0] for x in sel], format=fmt, scale=scale)
        except ValueError:
            for x in sel:
                try:
                    Time(x[0], format=fmt, scale=scale)
                except ValueError as exc:
                    _refuse(msg, x[2], f"segment {seg.index + 1}: epoch {x[0]!r}: {exc}")
            raise
        out.append((sel, t))
    if len(out) == 1:
        t = out[0][1]
    else:  # mixed formats: rare; one by one in file order
        t = Time([Time(x[0], format=x[1], scale=scale) for x in iso])
    if offset:
        t = t + offset * u.s
    return t.utc


def numbers(msg, seg, line, strings, what):
    """floats of ``strings``; a field that is not a number is refused naming the line and the field."""
    out = []
    for k, s in enumerate(strings):
        try:
            out.append(float(s))
        except ValueError:
            _refuse(msg, line, f"segment {seg.index + 1}: {what} field {k + 1} {s[:30]!r} is not a number")
    return out


def data_numbers(msg, seg, what):
    """(K, n) floats of the data lines after their epoch; a field that is not a finite number is refused with its line."""
    import numpy as np

    vals = np.array([numbers(msg, seg, ln, p[1:], what) for ln, p in seg.rows])
    if not np.all(np.isfinite(vals)):
        k = int(np.argmax(~np.all(np.isfinite(vals), axis=1)))
        _refuse(msg, seg.rows[k][0], f"segment {seg.index + 1}: a {what} with a value that is not finite")
    return vals


#: how far the first / last data epoch may lie inside START_TIME / STOP_TIME (s): the epochs'
#: written rounding (a millisecond), not a gap in the data
COVER_TOLERANCE_S = 1e-3


def segment_times(msg, seg, tol_s: float = 1e-6):
    """(epochs of the data lines (Time UTC), (useable start, useable stop)) after checking that the
    epochs increase strictly, lie inside START_TIME .. STOP_TIME and cover it (to
    ``COVER_TOLERANCE_S``), and that the useable span lies inside the segment's span. The useable span is USEABLE_START/STOP_TIME, else START/STOP_TIME."""
    import numpy as np

    md = seg.meta
    ep = epochs(msg, seg, [(p[0], ln) for ln, p in seg.rows])
    ts = (ep - ep[0]).to_value("s")
    bad = np.nonzero(np.diff(ts) <= 0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        _refuse(
            msg,
            seg.rows[k][0],
            f"segment {seg.index + 1}: epoch {seg.rows[k][1][0]} is not after the previous line's "
            f"({seg.rows[k - 1][1][0]}, line {seg.rows[k - 1][0]})",
        )
    start, stop = (epochs(msg, seg, [(md[k].value, md[k].line)])[0] for k in ("START_TIME", "STOP_TIME"))
    if (stop - start).to_value("s") < 0:
        _refuse(
            msg,
            md["STOP_TIME"].line,
            f"segment {seg.index + 1}: STOP_TIME {md['STOP_TIME'].value} is before START_TIME {md['START_TIME'].value}",
        )
    for k in (0, len(ts) - 1):
        if (ep[k] - start).to_value("s") < -tol_s or (ep[k] - stop).to_value("s") > tol_s:
            _refuse(
                msg,
                seg.rows[k][0],
                f"segment {seg.index + 1}: epoch {seg.rows[k][1][0]} is outside START_TIME .. STOP_TIME "
                f"({md['START_TIME'].value} .. {md['STOP_TIME'].value}, lines {md['START_TIME'].line} and {md['STOP_TIME'].line})",
            )
    # START_TIME .. STOP_TIME is the span the data cover (502.0-B table 5-3, 504.0-B table 4-3): data
    # that start late or stop short are a truncated or mislabelled file
    late, short = (ep[0] - start).to_value("s"), (stop - ep[-1]).to_value("s")
    if short > COVER_TOLERANCE_S:
        _refuse(
            msg,
            md["STOP_TIME"].line,
            f"segment {seg.index + 1}: the data stop {short:.4g} s before STOP_TIME {md['STOP_TIME'].value} (last data line "
            f"{seg.rows[-1][0]}, epoch {seg.rows[-1][1][0]}): a truncated file?",
        )
    if late > COVER_TOLERANCE_S:
        _refuse(
            msg,
            md["START_TIME"].line,
            f"segment {seg.index + 1}: the data start {late:.4g} s after START_TIME {md['START_TIME'].value} (first data line "
            f"{seg.rows[0][0]}, epoch {seg.rows[0][1][0]})",
        )
    span = []
    for key, default in (("USEABLE_START_TIME", start), ("USEABLE_STOP_TIME", stop)):
        if key not in md:
            span.append(default)
            continue
        t = epochs(msg, seg, [(md[key].value, md[key].line)])[0]
        if (t - start).to_value("s") < -tol_s or (t - stop).to_value("s") > tol_s:
            _refuse(
                msg,
                md[key].line,
                f"segment {seg.index + 1}: {key} {md[key].value} is outside START_TIME .. STOP_TIME "
                f"({md['START_TIME'].value} .. {md['STOP_TIME'].value})",
            )
        span.append(t)
    if (span[1] - span[0]).to_value("s") < 0:
        _refuse(
            msg,
            md["USEABLE_STOP_TIME"].line if "USEABLE_STOP_TIME" in md else md["STOP_TIME"].line,
            f"segment {seg.index + 1}: the useable span ends before it starts",
        )
    return ep, tuple(span)
