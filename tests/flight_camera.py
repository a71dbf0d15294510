"""The flight camera the ingestion tests share, defined once: F = 2.2 m, 5.5 µm pixels, a 12 000-pixel
square detector read with +x columns and −y rows, and Brown–Conrady distortion strong enough that a
wrong sign or a missing term shows (imported by name, like ``paths``). ``camera(**distortion)``
is the same detector with other (or no) distortion."""

from orbits.camera import CameraCalibration


def camera(**distortion: float) -> CameraCalibration:
    return CameraCalibration(2.2, (2.2 / 5.5e-6,) * 2, (6000.5, 5999.5), "+x", "-y", **distortion)


CAMERA = camera(k1=-0.05, k2=0.01, k3=0.002, p1=1e-5, p2=-2e-5)
