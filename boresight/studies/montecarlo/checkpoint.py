"""Interrupted and concurrent studies: the output-folder lock, block checkpoints, resume.

A study's output folder ``OUT`` gets

* ``OUT/.boresight.lock`` — held (``fcntl.flock``) by the running study and holding its pid. A
  second study on the same folder is refused with ``StudyLockedError`` naming that pid. The
  kernel releases the lock when its holder dies, even by SIGKILL, so a killed study never
  leaves a stale lock.
* ``OUT/.checkpoint/`` — ``study.json`` (the study's identity: everything its numbers depend
  on) and one ``block-NNNNNNNNN.npz`` per finished block of runs (its streamed moments, its
  non-converged counts and the error samples it keeps), each written to a temporary name and
  renamed (``os.replace``, atomic on POSIX), so a file either is complete or does not exist.
  Block files are flushed to disk (``fsync``) as a group, every ``SYNC_INTERVAL_S`` seconds and
  when the study is interrupted, not one by one; a resume reads back (CRC of every array) the
  blocks it reuses and redoes any a power cut left unreadable.

Blocks are merged in block order (``accumulator``), so the finished blocks are always a prefix
0..k−1; ``--resume`` loads them, merges them exactly as the uninterrupted study would have, and
runs the rest: the final files are byte-identical to an uninterrupted run with the same inputs.
A resume whose identity differs (scenario, seed, runs, algorithms, …) is refused with
``ResumeError`` naming the differences (the option as the user wrote it, or the scenario's
value, with the old and new values); a new study (no ``--resume``) on a folder holding an
interrupted one is refused too, so an analyst never silently throws hours away.

Every study command (``montecarlo``, ``sensitivity``) uses the same machinery through
``study_folder``: lock ``OUT``, hand the engine a ``Checkpoint`` named for the study, and delete
the checkpoint once the final files are written (still under the lock).

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> with StudyLock(d):
...     try:
...         StudyLock(d).acquire()
...     except StudyLockedError as exc:
...         print("refused, pid named:", str(os.getpid()) in str(exc))
refused, pid named: True
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

from boresight.errors import ResumeError, StudyLockedError
from boresight.files import atomic_write_bytes, sync_files
from boresight.studies.montecarlo.moments import Moments

__all__ = ["StudyLock", "Checkpoint", "study_folder", "LOCK_NAME", "CHECKPOINT_DIR", "OPTION_NAMES"]

LOCK_NAME = ".boresight.lock"
CHECKPOINT_DIR = ".checkpoint"
#: block files are flushed to disk together at most this often (seconds; and on an interruption)
# DECISION: an fsync per block dominated the checkpoint's wall time (one disk flush per 1000 runs).
# Renamed without it, a block is still complete or absent for any crash of the *process* (Ctrl-C,
# SIGTERM, SIGKILL, out of memory: the kernel has the data). A power cut or kernel crash can lose
# what was written since the last group flush — at most this many seconds of blocks, and the study
# folder can then hold a renamed block file that is empty or torn. ``finished_blocks`` reads every
# block back (zip CRCs) and stops at the first unreadable one, so a resume redoes those blocks
# (same seeds, same numbers: the final files are still byte-identical) and never loads a bad one.
SYNC_INTERVAL_S = 30.0
#: bump when the block file layout or the identity's fields change (part of the identity)
FORMAT = 2

#: identity field → what the user wrote, for the refusal of a resume with other inputs
OPTION_NAMES = {
    "study": "the command",
    "seed": "--seed",
    "runs": "--runs",
    "block_runs": "--block-runs",
    "algorithms": "--algorithm",
    "image_counts": "--image-counts",
    "weighting": "--weighting",
    "format": "the checkpoint format (an older boresight wrote it)",
}


class StudyLock:
    """Exclusive lock of a study's output folder (a context manager; ``acquire``/``release``)."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self.path = self.out / LOCK_NAME
        self.fd: int | None = None

    def acquire(self) -> "StudyLock":
        import fcntl

        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                pid = int(os.read(fd, 32).decode().strip() or 0) or None
            except ValueError:
                pid = None
            os.close(fd)
            who = f"pid {pid}" if pid else "another process"
            raise StudyLockedError(
                f"{self.out}: another boresight study is writing this folder ({who}); wait for it to finish or choose another --out",
                pid=pid,
            ) from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self.fd = fd
        return self

    def release(self):
        if self.fd is not None:
            import fcntl

            try:
                os.ftruncate(self.fd, 0)
                fcntl.flock(self.fd, fcntl.LOCK_UN)
            finally:
                os.close(self.fd)
                self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


def _readable(path: Path) -> bool:
    """Whether a block file reads back whole: a zip whose every member matches its CRC."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            return z.testzip() is None
    except (OSError, zipfile.BadZipFile, EOFError, ValueError):
        return False


def identity_digest(identity: dict) -> str:
    return hashlib.sha256(json.dumps(identity, sort_keys=True, default=str).encode()).hexdigest()


def _flat(value, prefix: str = "") -> dict:
    """{dotted path: leaf} of a JSON value (lists indexed ``[i]``)."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flat(v, f"{prefix}.{k}" if prefix else str(k)))
        return out or {prefix: {}}
    if isinstance(value, list) and value and any(isinstance(v, (dict, list)) for v in value):
        out = {}
        for i, v in enumerate(value):
            out.update(_flat(v, f"{prefix}[{i}]"))
        return out
    return {prefix: value}


def _short(v, width: int = 40) -> str:
    s = "(absent)" if v is _MISSING else v if isinstance(v, str) else json.dumps(v, default=str)
    return s if len(s) <= width else s[: width - 1] + "…"


_MISSING = object()


def describe_differences(old: dict, new: dict, options: dict | None = None, most: int = 4) -> list[str]:
    """What differs between two study identities, as the user would name it: ``--seed 7 → 8``,
    ``scenario sigma_pixel_m 3e-06 → 4e-06`` (at most ``most`` scenario values, then a count).

    >>> describe_differences({"seed": 7, "scenario": {"a": 1, "b": [1, 2]}}, {"seed": 8, "scenario": {"a": 1, "b": [1, 3]}})
    ['scenario b [1, 2] → [1, 3]', '--seed 7 → 8']
    """
    names = {**OPTION_NAMES, **(options or {})}
    changed = [k for k in set(old) | set(new) if old.get(k, _MISSING) != new.get(k, _MISSING)]
    for key in ("format", "study"):  # another layout or kind of study: the rest differs by construction
        if key in changed:
            changed = [key]
            break
    if any(names.get(k, k) is not None for k in changed):  # None: derived from fields named otherwise
        changed = [k for k in changed if names.get(k, k) is not None]
    out = []
    for key in sorted(changed, key=lambda k: (k != "study", k != "scenario", k)):
        a, b = old.get(key, _MISSING), new.get(key, _MISSING)
        if key == "scenario" and isinstance(a, dict) and isinstance(b, dict):
            fa, fb = _flat(a), _flat(b)
            diff = [k for k in sorted(set(fa) | set(fb)) if fa.get(k, _MISSING) != fb.get(k, _MISSING)]
            out += [f"scenario {k} {_short(fa.get(k, _MISSING))} → {_short(fb.get(k, _MISSING))}" for k in diff[:most]]
            if len(diff) > most:
                out.append(f"and {len(diff) - most} more scenario value(s)")
            continue
        out.append(f"{names.get(key) or key} {_short(a)} → {_short(b)}")
    return out


class Checkpoint:
    """Block files of one study in ``folder`` (``OUT/.checkpoint``).

    ``study`` names the kind of study (``"montecarlo"``, ``"sensitivity"``; part of the
    identity, so one never resumes the other); ``extra`` adds the study's own inputs to the
    identity (``{"rel_step": 1.0}``); ``options`` maps identity fields to the option the user
    wrote (``{"rel_step": "--rel-step"}``) for the refusal message, ``None`` for a field derived
    from others (named only if nothing else differs).
    ``open(identity, resume)`` checks the folder against the study and returns the number of
    finished blocks to load (``load(b)``); ``save(b, ...)`` writes one block atomically.
    """

    def __init__(self, folder: Path, study: str = "montecarlo", options: dict | None = None, extra: dict | None = None):
        self.folder = Path(folder)
        self.study = study
        self.options = dict(options or {})
        self.extra = dict(extra or {})
        self._unsynced: list[Path] = []
        self._synced_at = time.monotonic()

    def with_extra(self, **extra) -> "Checkpoint":
        """The same checkpoint with more identity fields (a study's own inputs, e.g. ``rel_step``)."""
        return Checkpoint(self.folder, self.study, self.options, {**self.extra, **extra})

    def _block_path(self, b: int) -> Path:
        return self.folder / f"block-{b:09d}.npz"

    def finished_blocks(self) -> int:
        """The finished blocks 0..k−1 a resume can reuse: the prefix of block files that read back
        whole (a block after an unreadable one — a power cut before the group flush — is redone)."""
        k = 0
        while self._block_path(k).exists() and _readable(self._block_path(k)):
            k += 1
        return k

    def sync(self) -> None:
        """Flush the block files written since the last flush, and the folder, to disk."""
        if self._unsynced:
            sync_files(self._unsynced, self.folder)
            self._unsynced = []
        self._synced_at = time.monotonic()

    def open(self, identity: dict, resume: bool) -> int:
        identity = json.loads(json.dumps({"format": FORMAT, "study": self.study, **self.extra, **identity}, default=str))
        meta = self.folder / "study.json"
        if meta.exists():
            try:
                old = json.loads(meta.read_text())
            except (OSError, ValueError):
                old = None
            done = self.finished_blocks()
            if not resume:
                raise ResumeError(
                    f"{self.folder.parent}: holds an interrupted study ({done} block(s) finished); continue it with "
                    f"--resume, or delete {self.folder} to start again"
                )
            if old is None or old.get("digest") != identity_digest(identity):
                theirs = (old or {}).get("identity") or {}
                diff = describe_differences(theirs, identity, self.options) if old is not None else []
                raise ResumeError(
                    f"{self.folder.parent}: the interrupted study there has other inputs "
                    f"({'; '.join(diff) or f'unreadable {meta.name}'}); resume it with the same scenario and options, "
                    "or choose another --out"
                )
            return done
        self.folder.mkdir(parents=True, exist_ok=True)
        payload = {"digest": identity_digest(identity), "identity": identity}
        atomic_write_bytes(meta, (json.dumps(payload, indent=1, sort_keys=True, default=str) + "\n").encode())
        return 0

    def save(self, b: int, moments: dict, unconverged: dict, samples: dict):
        arrays: dict[str, Any] = {}
        for k, m in moments.items():
            arrays[f"m|{k}|count"] = np.array(m.count)
            arrays[f"m|{k}|mean"] = m.mean
            arrays[f"m|{k}|m2"] = m.m2
            arrays[f"m|{k}|max_abs"] = m.max_abs
        for k, v in unconverged.items():
            arrays[f"n|{k}"] = np.asarray(v)
        for k, v in samples.items():
            arrays[f"s|{k}"] = np.asarray(v)
        import io

        buf = io.BytesIO()
        np.savez(buf, **arrays)
        path = atomic_write_bytes(self._block_path(b), buf.getvalue(), sync=False)  # flushed as a group (SYNC_INTERVAL_S)
        self._unsynced.append(path)
        if time.monotonic() - self._synced_at >= SYNC_INTERVAL_S:
            self.sync()

    def load(self, b: int) -> tuple[dict, dict, dict]:
        moments, unconverged, samples = {}, {}, {}
        with np.load(self._block_path(b)) as z:
            parts: dict[str, dict] = {}
            for name in z.files:
                kind, rest = name.split("|", 1)
                if kind == "m":
                    key, field = rest.rsplit("|", 1)
                    parts.setdefault(key, {})[field] = z[name]
                elif kind == "n":
                    unconverged[rest] = z[name]
                else:
                    samples[rest] = z[name]
            for key, f in parts.items():
                moments[key] = Moments(int(f["count"]), f["mean"], f["m2"], f["max_abs"])
        return moments, unconverged, samples

    def remove(self):
        shutil.rmtree(self.folder, ignore_errors=True)


@contextlib.contextmanager
def study_folder(out: Path, study: str, options: dict | None = None):
    """``with study_folder(OUT, "sensitivity") as ckpt:`` — hold ``OUT``'s lock for the whole
    study and yield its ``Checkpoint`` (pass it to ``montecarlo.montecarlo_study(checkpoint=…)``); when the
    block ends normally (the final files written) the checkpoint is deleted, still under the
    lock. An exception or a signal leaves it for ``--resume``."""
    with StudyLock(out):
        ckpt = Checkpoint(Path(out) / CHECKPOINT_DIR, study, options)
        yield ckpt
        ckpt.remove()


def resumed_line(result, ckpt: Checkpoint) -> str | None:
    """The line a command prints after a resumed study (None for a fresh one)."""
    if not getattr(result, "resumed_blocks", 0):
        return None
    return f"resumed: {result.resumed_blocks} finished block(s) of {result.block_runs} runs reused from {ckpt.folder}"
