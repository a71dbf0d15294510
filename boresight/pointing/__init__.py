"""Gimbal and platform pointing calibration (USV sea-sky, Tang 2014, Tang 2015 seeds)."""
