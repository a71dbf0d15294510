"""``boresight check FILE.ecsv`` — the convention doctor alone (``boresight.observations.doctor``).

Fits the declared conventions and each common slip (x or y mirrored, quaternions scalar-first, scalar-last
read as scalar-first, or conjugated, mount transposed, ``cgi`` transposed, GNSS given in ITRS) to the file's images
and prints the table. Exit 0 when the declared conventions fit; 4 when a slip fits far better (the
message names it), or when no slip does but some images fit the declared conventions far worse
than the noise ("inconclusive", naming those images); 1 when the file cannot be read.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from boresight.cli.options import add_command, add_join_argument, real, whole
from orbits.errors import InputValueError

EPILOG = """examples:
  boresight check out/kiev2012-kalman20.ecsv
  boresight check flight.ecsv --max-images 30 --max-rotation-deg 2
  boresight check pass.ecsv --join stars.ecsv                         # the files merged, as estimate --join fits them

decision rule: a slip is reported when it fits the images 100x better (RMS focal-plane residual)
than the declared conventions, or when the declared conventions need a rotation above
--max-rotation-deg that the slip removes. When no slip fits better but some images' residuals are
more than 10x the noise (the file's noise model, else the residuals' robust scale) the result is
"inconclusive" and names those images. Exit codes: 0 conventions fit, 1 unreadable file, 4 slip
found or inconclusive."""


def register(sub):
    p = add_command(sub, "check", "test a file for convention slips (mirrored axes, quaternion order, frames)", EPILOG)
    p.add_argument("file", type=Path, help="ECSV observation file (docs/data-format.md)")
    add_join_argument(p)
    p.add_argument("--max-images", type=whole(1, 10**6), default=12, help="images of run 0 used, spread evenly (default 12)")
    p.add_argument(
        "--max-rotation-deg",
        type=real(0, 180, lo_open=True),
        default=1.0,
        help="largest camera/star-tracker rotation accepted as a misalignment (default 1)",
    )
    p.add_argument(
        "--json",
        type=Path,
        default=None,
        metavar="PATH",
        help="also write the verdict and the hypotheses' residuals as JSON to this path",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from boresight.cli.options import joined_files, read_merged
    from boresight.observations.doctor import convention_error, diagnose_conventions
    from boresight.observations.ecsv import read_ecsv
    from boresight.reporting.outputs import check_output_file

    check_output_file(args.json, "--json")
    files = joined_files(args)  # FILE and every --join FILE, each refused by name when missing
    from boresight.cli import pushbroom_inputs as pb

    if pb.is_pushbroom(args.file) and args.file.suffix.lower() == ".ecsv":  # a pushbroom file's lines (run_pushbroom below)
        if len(files) > 1:
            raise InputValueError(f"--join merges frame-camera observation files; {args.file} is pushbroom")
        return run_pushbroom(args)
    # --join: the doctor on the merged campaign (cli/options.read_merged), as estimate --join fits it
    obs = read_merged(files, lambda f: read_ecsv(f, geometry_checks=False))
    dg = diagnose_conventions(obs, max_images=args.max_images, max_rotation_deg=args.max_rotation_deg)
    print(f"file          {', '.join(str(f) for f in files)}")
    print(dg.table())
    if dg.passed:
        print(f"result        {dg.message}")
        if args.json is not None:
            _write_json(args.json, args.file, dg)
        return 0
    if args.json is not None:  # the refusal below is the verdict; the JSON keeps the table's numbers
        _write_json(args.json, args.file, dg)
    from boresight.observations.flight.culprit import file_input_slip

    slip = file_input_slip(obs, dg, str(args.file))  # the landmarks' or the orbit's own slip, named
    if slip is not None:
        from boresight.observations.doctor import ConventionError

        raise ConventionError(f"{args.file}: {slip.message}", slip=slip.name, report=slip.report)
    # DECISION: "inconclusive" (no slip fits better, but images fit far worse than the noise)
    # exits 4 like a slip: the conventions could not be confirmed, so check must not pass the file
    # the same error (exit 4, "boresight check: ConventionError: FILE: …") as estimate, diagnose, ingest
    raise convention_error(dg, str(args.file), hint="the table above compares the hypotheses")


def _write_json(path: Path, file: Path, dg) -> None:
    """The doctor's verdict as JSON: each hypothesis's RMS focal-plane residual (m) and rotation (deg)."""
    import numpy as np

    from boresight.reporting.outputs import write_json_output

    verdict = dg.verdict or ("inconclusive" if dg.disagreeing is not None else "conventions_fit")
    written = write_json_output(
        path,
        {
            "file": str(file),
            "verdict": verdict,
            "message": dg.message,
            "rms_residual_m": {k: float(v) for k, v in dg.rms_m.items()},
            "rotation_deg": {k: float(v) for k, v in dg.rotation_deg.items()},
            "images_used": [int(i) for i in np.ravel(dg.images)],
            "images_disagreeing": None if dg.disagreeing is None else [int(i) for i in np.ravel(dg.disagreeing)],
        },
    )
    if written is not None:  # --json -: the document went to standard output
        print(f"wrote         {path}")


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight check PUSHBROOM.ecsv``: the convention doctor on the file's lines (each line an image of one row:
    its attitude the tracker's SLERP, its point F · tan ψ of its pixel); exit as ``check`` does."""
    from boresight.observations.doctor import convention_error, diagnose_conventions
    from boresight.observations.strip_file import read_strip_file

    sf = read_strip_file(args.file, geometry_checks=False)  # a slip is the doctor's to name, not "behind the camera"
    dg = diagnose_conventions(sf.obs, max_images=args.max_images, max_rotation_deg=args.max_rotation_deg)
    print(f"file          {args.file} (pushbroom: {sf.obs.n_observations} lines with a detection)")
    print(dg.table())
    if getattr(args, "json", None) is not None:
        from boresight.reporting.outputs import write_json_output

        write_json_output(
            args.json,
            {
                "file": str(args.file),
                "verdict": dg.verdict or ("inconclusive" if dg.disagreeing is not None else "conventions_fit"),
                "message": dg.message,
                "rms_residual_m": {k: float(v) for k, v in dg.rms_m.items()},
                "rotation_deg": {k: float(v) for k, v in dg.rotation_deg.items()},
            },
        )
    if dg.passed:
        print(f"result        {dg.message}")
        return 0
    from boresight.observations.doctor import ConventionError
    from boresight.observations.flight.culprit import file_input_slip

    slip = file_input_slip(sf.obs, dg, str(args.file))  # the landmarks' or the orbit's own slip, named as check does
    if slip is not None:
        raise ConventionError(f"{args.file}: {slip.message}", slip=slip.name, report=slip.report)
    raise convention_error(dg, str(args.file), hint="the table above compares the hypotheses")
