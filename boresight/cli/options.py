"""Option types checked at parse time: a bad value is one argparse line naming the option.

``argparse`` calls the ``type=`` function on the text the user wrote; raising
``argparse.ArgumentTypeError`` makes it print ``boresight CMD: error: argument --max-images: must
be a whole number ≥ 1, got '0'`` and exit 2 (``EXIT_USAGE``) before anything is read or computed.
Without these, ``check --max-rotation-deg nan`` ran and passed everything, ``diagnose --max-steps
-1`` ran and named nothing, and ``check --max-images 0`` failed deep in numpy.

>>> whole(1)("3")
3
>>> whole(1)("0")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: must be a whole number ≥ 1, got '0'
>>> real(0, 180, lo_open=True)("nan")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: must be a finite number in (0, 180], got 'nan'
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

__all__ = [
    "whole",
    "real",
    "probability",
    "effect_list",
    "SEED",
    "add_command",
    "add_loss_argument",
    "add_join_argument",
    "joined_files",
    "read_merged",
    "add_engine_arguments",
    "add_resume_argument",
    "check_engine_arguments",
    "study_options",
]


def _num(v) -> str:
    return str(v) if isinstance(v, int) else f"{v:g}"


def _range(lo, hi, lo_open, hi_open) -> str:
    if lo is not None and hi is not None:
        return f" in {'(' if lo_open else '['}{_num(lo)}, {_num(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f" {'>' if lo_open else '≥'} {_num(lo)}"
    if hi is not None:
        return f" {'<' if hi_open else '≤'} {_num(hi)}"
    return ""


def _bounded(convert, noun: str, lo, hi, lo_open: bool, hi_open: bool, name: str):
    """An argparse type: ``convert(text)`` (int or float), finite, inside the range; the one
    message "must be <noun> in [lo, hi], got 'text'" otherwise."""

    def parse(text: str):
        want = f"must be {noun}{_range(lo, hi, lo_open, hi_open)}, got {text!r}"
        try:
            v = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(want) from None
        outside = (lo is not None and (v <= lo if lo_open else v < lo)) or (hi is not None and (v >= hi if hi_open else v > hi))
        if outside or (isinstance(v, float) and not math.isfinite(v)):
            raise argparse.ArgumentTypeError(want)
        return v

    parse.__name__ = name
    return parse


def whole(lo: int | None = None, hi: int | None = None):
    """A whole number in [lo, hi] (either bound may be None)."""
    return _bounded(int, "a whole number", lo, hi, False, False, "whole number")


def real(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False, hi_open: bool = False):
    """A finite number in the range (open or closed at either end; a bound may be None)."""
    return _bounded(float, "a finite number", lo, hi, lo_open, hi_open, "number")


#: a random seed (numpy's generators take any whole number ≥ 0)
SEED = whole(0)

#: a probability or significance level strictly between 0 and 1
probability = real(0, 1, lo_open=True, hi_open=True)


def effect_list(text: str) -> list[str]:
    """Comma-separated names from the effects catalogue (``docs/effects.md``), checked by the
    catalogue's own ``check_effect_names``; ``none``: no effect (an empty list: a default off)."""
    from boresight.core.effect_model import check_effect_names

    if text.strip() == "none":
        return []
    try:
        return check_effect_names(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_command(sub, name: str, help: str, epilog: str):
    """A command's parser whose epilog (exit codes, examples) keeps its line breaks."""
    return sub.add_parser(name, help=help, epilog=epilog, formatter_class=argparse.RawDescriptionHelpFormatter)


def add_loss_argument(p, help: str) -> None:
    """``--loss``: the robust losses the library has (``boresight.core.losses.LOSSES``: loaded at --help without the estimators), estimate's and a study's refits alike."""
    from boresight.core.losses import LOSSES

    p.add_argument("--loss", choices=tuple(LOSSES), default=None, help=help)


def add_join_argument(p) -> None:
    """``--join FILE`` (repeatable): more observation files fitted together with the command's first (``estimate``,
    ``check``): one campaign merged by ``observations.merge.merge_observations``, as ``diagnose A B`` merges its files
    (``read_merged``) — e.g. star frames joined with a landmark pass (docs/tutorial-stars.md)."""
    p.add_argument(
        "--join",
        type=Path,
        action="append",
        default=None,
        metavar="FILE",
        help="another observation file of the same campaign fitted together with FILE (repeatable; one run per file, "
        "the same camera; merged as diagnose merges its files)",
    )


def joined_files(args) -> list[Path]:
    """``args.file`` and every ``--join`` file, each refused by name when it does not exist."""
    files = [args.file, *(getattr(args, "join", None) or [])]
    for f in files:
        if not f.exists():
            raise FileNotFoundError(f"no such observation file: {f}")
    return files


def read_merged(files, read):
    """One ``ObservationSet`` from ``files``, each read by ``read(path)``, merged by
    ``observations.merge.merge_observations`` (a single file is returned as read: its runs and truth kept).
    The one merge of the commands that take several observation files (``diagnose``, ``estimate --join``,
    ``check --join``)."""
    from boresight.observations.merge import merge_observations

    # the files' noise models are reconciled in the merge itself (each file's pixel σ on its rows, a conflicting
    # term refused by file name: observations/merge.py, "Noise models"); nothing to note here
    return merge_observations([read(f) for f in files], names=[str(f) for f in files])


# the study options shared by montecarlo and sensitivity (one meaning, one help text)


def add_strip_argument(p):
    """``--strip FILE`` (repeatable): more pushbroom files of one campaign beside the command's first (``estimate``,
    ``montecarlo FILE``, ``sensitivity``; ``cli/pushbroom_inputs.campaign_files``)."""
    p.add_argument(
        "--strip",
        type=Path,
        action="append",
        default=None,
        metavar="FILE",
        help="with a pushbroom file: another strip of the same campaign (repeatable; θ and the floated unknowns common)",
    )


def add_resume_argument(p):
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted study in --out (same scenario and options; finished blocks are reused and the result is identical to an uninterrupted run)",
    )


def add_engine_arguments(p):
    from boresight.studies.montecarlo.seeding import BLOCK_OBSERVATIONS, BLOCK_RUNS  # not the engines

    p.add_argument(
        "--chunk-runs",
        type=int,
        default=None,
        help="runs per task (memory ∝ chunk × workers; default: ~200 000 landmark observations, 400 000 for the structure-of-arrays kernels only, ≤ 5000 runs; see montecarlo.default_chunk_runs)",
    )
    p.add_argument(
        "--block-runs",
        type=int,
        default=None,
        help=f"runs per random-number block (part of the result's identity; default {BLOCK_RUNS}, "
        f"fewer when a block would hold over {BLOCK_OBSERVATIONS:,} landmark observations: montecarlo.default_block_runs)",
    )
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: the CPUs available)")
    p.add_argument("--engine", choices=("local", "dask"), default="local", help="local processes (default) or dask.distributed")
    p.add_argument("--scheduler", default=None, help="dask scheduler address (default: a LocalCluster)")


def check_engine_arguments(args):
    """Range checks of the shared engine options (one line per refusal, naming the option)."""
    from boresight.errors import StudyError

    for opt in ("runs", "chunk_runs", "block_runs", "workers"):
        v = getattr(args, opt, None)
        lo = 2 if opt == "runs" else 1
        if v is not None and v < lo:
            raise StudyError(f"--{opt.replace('_', '-')} must be ≥ {lo}, got {v}")
    if getattr(args, "workers", None) is not None and args.workers > 1024:
        raise StudyError(f"--workers must be ≤ 1024, got {args.workers}")
    beta = getattr(args, "beta", None)
    if beta is not None and not (0 < beta < 1):
        raise StudyError(f"--beta must be in (0, 1), got {beta}")


def study_options(args, progress, checkpoint) -> dict:
    """The study keywords a study command's shared options set — ``--runs``, ``--seed``, those of
    ``add_engine_arguments`` and ``add_resume_argument`` — with its progress display (whose
    pre-flight line opens it) and checkpoint, as ``montecarlo_study`` and ``sensitivity_study`` take them."""
    return {
        "runs": args.runs,
        "seed": args.seed,
        "progress": progress,
        "checkpoint": checkpoint,
        "preflight": getattr(progress, "preflight", None),
        "chunk_runs": args.chunk_runs,
        "block_runs": args.block_runs,
        "workers": args.workers,
        "engine": args.engine,
        "scheduler": args.scheduler,
        "resume": args.resume,
    }
