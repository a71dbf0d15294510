"""SPICE kernels as flight inputs: the spacecraft trajectory from SPK, the star-tracker attitude from
CK with the frame kernel (FK) that defines the star-tracker frame, read through ``spiceypy`` (MIT;
optional extra ``spice``), and a writer of such kernels from a simulated pass (for tests and
examples).

Reading. The kernels given are loaded (``furnsh``) for the duration of the call and unloaded
afterwards. Image times (UTC) become ephemeris time with SPICE's own ``str2et`` (so a leapseconds
kernel must be among them). Positions: ``spkezr(target, et, "J2000", "NONE", center)`` (km, km/s,
geometric, no light time). Attitude: ``pxform("J2000", frame, et)``, the matrix that maps J2000
components to the star-tracker frame's, i.e. our attitude matrix; quaternions are made from it.
SPICE evaluates its own kernels' interpolation at the image times: boresight has no error
estimate for it, and the report says so.

DECISION: SPICE's ``J2000`` frame is read as the GCRS axes (ICRF). NAIF treats J2000 as the
inertial base frame and modern kernels (DE4xx, most missions') are ICRF-aligned under that name;
the alternative reading, EME2000 (the IERS frame bias, 23 mas), is ``j2000="EME2000"``. The printed
frame line names the choice, so a file from a mission that means EME2000 can be read that way.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from boresight.observations.flight.common import IngestError, require_extra
from boresight.observations.flight.frames import conversion, eme2000_bias

__all__ = ["read_spice", "write_spice_kernels"]


@contextlib.contextmanager
def _loaded(sp, paths):
    done = []
    try:
        for p in paths:
            if not Path(p).is_file():
                raise FileNotFoundError(f"no such file: {p}")
            try:
                sp.furnsh(str(p))
            except Exception as exc:  # spiceypy.utils.exceptions.SpiceyError
                raise IngestError(f"{p}: not a SPICE kernel SPICE can load: {_short(exc)}") from None
            done.append(str(p))
        yield
    finally:
        for p in reversed(done):
            sp.unload(p)


def _short(exc):
    """The first line of a SpiceyError's long message: '... SPICE(NOFRAMECONNECT) ...'."""
    text = str(exc).strip().splitlines()
    key = [ln.strip() for ln in text if "SPICE(" in ln]
    short = [
        ln.strip() for ln in text if ln.strip() and not ln.startswith("=") and "Toolkit version" not in ln and "---" not in ln
    ]
    return " ".join((key[:1] + short[1:3])) if key else " ".join(short[:2])


def read_spice(
    times_utc,
    *,
    spk=(),
    ck=(),
    fk=(),
    kernels=(),
    target: str,
    frame: str | None = None,
    center: str = "EARTH",
    j2000: str = "GCRS",
):
    """(OrbitTrack or None, AttitudeTrack or None) at ``times_utc`` (astropy Time, sorted) from SPICE
    kernels: the orbit if ``spk`` is given, the attitude of ``frame`` if ``ck`` is given."""
    sp = require_extra("spiceypy")
    from boresight.observations.flight.attitude import AttitudeTrack
    from boresight.observations.flight.orbit import OrbitTrack

    if j2000 not in ("GCRS", "EME2000"):
        raise IngestError(f"--spice-j2000 {j2000}: use GCRS (ICRF-aligned kernels, the default) or EME2000")
    B = eme2000_bias() if j2000 == "EME2000" else np.eye(3)  # v_J2000 = B v_GCRS
    all_k = [*kernels, *fk, *spk, *ck]
    where = ", ".join(str(p) for p in [*spk, *ck])
    with _loaded(sp, all_k):
        try:
            et = np.array([sp.str2et(s) for s in times_utc.utc.isot])
        except Exception as exc:
            raise IngestError(
                f"image times → SPICE ephemeris time: {_short(exc)} (give a leapseconds kernel, e.g. naif0012.tls, with --spice-kernel)"
            ) from None
        orbit = attitude = None
        jframe = f"SPICE J2000 → GCRS: {'identity (J2000 read as ICRF axes)' if j2000 == 'GCRS' else conversion('EME2000')}"
        if spk:
            r, v = np.zeros((et.size, 3)), np.zeros((et.size, 3))
            for k, e in enumerate(et):
                try:
                    st, _ = sp.spkezr(str(target), e, "J2000", "NONE", str(center))
                except Exception as exc:
                    raise IngestError(
                        f"{', '.join(map(str, spk))}: no state of {target} relative to {center} at image time "
                        f"{times_utc[k].isot}: {_short(exc)}"
                    ) from None
                r[k], v[k] = np.asarray(st[:3]) * 1e3, np.asarray(st[3:]) * 1e3
            orbit = OrbitTrack(
                times_utc,
                r @ B,
                v @ B,
                "LAGRANGE",
                1,
                ", ".join(map(str, spk)),
                exact=True,
                frame=jframe,
                notes=[
                    f"orbit from SPICE (spkezr {target} relative to {center}): SPICE interpolates its own segments; "
                    "boresight has no error estimate for that"
                ],
            )
        if ck:
            if frame is None:
                raise IngestError("--ck needs --spice-frame (the star-tracker frame's name in the frame kernel)")
            A = np.zeros((et.size, 3, 3))
            for k, e in enumerate(et):
                try:
                    A[k] = np.asarray(sp.pxform("J2000", str(frame), e))
                except Exception as exc:
                    raise IngestError(
                        f"{', '.join(map(str, ck))}: no attitude of frame {frame} at image time {times_utc[k].isot}: {_short(exc)}"
                    ) from None
            A = A @ B  # GCRS -> J2000 -> star tracker
            q = Rotation.from_matrix(np.swapaxes(A, -1, -2)).as_quat()
            q = np.where(q[:, 3:4] < 0, -q, q)
            attitude = AttitudeTrack(
                times_utc,
                q,
                ", ".join(map(str, ck)),
                None,
                (f"attitude from SPICE (pxform J2000 → {frame}); {jframe}",),
                (),
                "SPICE pxform at the image times",
            )
    del where
    return orbit, attitude


# ------------------------------------------------------------------------------------ writer


def _lsk_text():
    """A leapseconds kernel from ERFA's leap-second table (the one astropy uses)."""
    import erfa

    months = ["JAN", "FEB", "MAR", "APR", "MAY", "JUN", "JUL", "AUG", "SEP", "OCT", "NOV", "DEC"]
    rows = [
        f"{float(x['tai_utc']):.0f}, @{x['year']}-{months[x['month'] - 1]}-1"
        for x in erfa.leap_seconds.get()
        if x["year"] >= 1972
    ]
    return (
        "KPL/LSK\n\nLeapseconds kernel written by boresight from ERFA's leap-second table.\n\n\\begindata\n\n"
        "DELTET/DELTA_T_A = 32.184\nDELTET/K = 1.657D-3\nDELTET/EB = 1.671D-2\nDELTET/M = ( 6.239996D0 1.99096871D-7 )\n"
        "DELTET/DELTA_AT = ( " + "\n                     ".join(rows) + " )\n\n\\begintext\n"
    )


def write_spice_kernels(
    folder,
    times,
    r_gcrs_m,
    v_gcrs_m_s,
    q_is,
    *,
    body: int = -999,
    name: str = "BORESIGHT-SIM",
    frame: str = "BS_STAR_TRACKER",
    degree: int = 7,
):
    """Write ``naif.tls`` (LSK), ``sc.tsc`` (SCLK), ``sc.tf`` (FK: the star-tracker frame, CK-based),
    ``sc.bsp`` (SPK type 13, Hermite from positions and velocities, J2000 = GCRS axes) and ``sc.bc``
    (CK type 3, the GCRS → star-tracker quaternions) of a pass; returns the paths by role."""
    sp = require_extra("spiceypy")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fid = body * 1000 - 100
    paths = {
        "lsk": folder / "naif.tls",
        "sclk": folder / "sc.tsc",
        "fk": folder / "sc.tf",
        "spk": folder / "sc.bsp",
        "ck": folder / "sc.bc",
    }
    paths["lsk"].write_text(_lsk_text())
    b = abs(body)
    paths["sclk"].write_text(
        "KPL/SCLK\n\nSpacecraft clock written by boresight: 1 count = 1 s of TDB from 1996-01-01.\n\n\\begindata\n\n"
        f"SCLK_KERNEL_ID = ( @1996-01-01/00:00 )\nSCLK_DATA_TYPE_{b} = ( 1 )\nSCLK01_TIME_SYSTEM_{b} = ( 1 )\nSCLK01_N_FIELDS_{b} = ( 2 )\n"
        f"SCLK01_MODULI_{b} = ( 10000000000 100000 )\nSCLK01_OFFSETS_{b} = ( 0 0 )\nSCLK01_OUTPUT_DELIM_{b} = ( 1 )\n"
        f"SCLK_PARTITION_START_{b} = ( 0.0 )\nSCLK_PARTITION_END_{b} = ( 1.0D15 )\nSCLK01_COEFFICIENTS_{b} = ( 0.0 -126230400.0 1.0 )\n\n\\begintext\n"
    )
    paths["fk"].write_text(
        "KPL/FK\n\nThe star-tracker frame of the simulated spacecraft (CK-based).\n\n\\begindata\n\n"
        f"NAIF_BODY_NAME += ( '{name}' )\nNAIF_BODY_CODE += ( {body} )\n"
        f"FRAME_{frame} = {fid}\nFRAME_{fid}_NAME = '{frame}'\nFRAME_{fid}_CLASS = 3\nFRAME_{fid}_CLASS_ID = {fid}\nFRAME_{fid}_CENTER = {body}\n"
        f"CK_{fid}_SCLK = {body}\nCK_{fid}_SPK = {body}\n\n\\begintext\n"
    )
    for p in ("spk", "ck"):
        if paths[p].exists():
            paths[p].unlink()
    with _loaded(sp, [paths["lsk"], paths["sclk"], paths["fk"]]):
        et = np.array([sp.str2et(s) for s in times.utc.isot])
        states = np.hstack([np.asarray(r_gcrs_m, float), np.asarray(v_gcrs_m_s, float)]) / 1e3
        h = sp.spkopn(str(paths["spk"]), "boresight", 0)
        sp.spkw13(
            h,
            body,
            399,
            "J2000",
            float(et[0]),
            float(et[-1]),
            "boresight pass",
            min(degree, 2 * et.size - 1) | 1,
            et.size,
            states.tolist(),
            et.tolist(),
        )
        sp.spkcls(h)
        A = Rotation.from_quat(np.asarray(q_is, float)).as_matrix().transpose(0, 2, 1)  # GCRS -> star tracker
        quats = np.array([sp.m2q(np.ascontiguousarray(a)) for a in A])
        sclk = np.array([sp.sce2c(body, e) for e in et])
        h = sp.ckopn(str(paths["ck"]), "boresight", 0)
        sp.ckw03(
            h,
            float(sclk[0]),
            float(sclk[-1]),
            fid,
            "J2000",
            False,
            "boresight pass",
            sclk.size,
            sclk.tolist(),
            quats.tolist(),
            np.zeros((sclk.size, 3)).tolist(),
            1,
            [float(sclk[0])],
        )
        sp.ckcls(h)
    return paths
