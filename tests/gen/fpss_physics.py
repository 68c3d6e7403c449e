"""The FPSS sensor physics for independent test generators, written from the paper, not from our C++.

Gambardella and Thompson (1980), eq. 1 and 2: per axis
    angle(N) = C1 + C2 N + C3 sin(C4 N + C5) + C6 sin(C7 N + C8)      (radians, N in counts)
A real sensor reports whole counts: the noisy continuous count is rounded to the nearest integer
and clipped to the signed 16-bit range. Generators import this module (run with /usr/bin/python3,
which has Debian's python3-numpy) and add their own bench physics on top.
"""
import json
import math

import numpy as np

ARCSEC_PER_RAD = 180.0 * 3600.0 / math.pi
COUNTS_MIN, COUNTS_MAX = -32768.0, 32767.0


def load_coefficients(path):
    """(alpha[8], beta[8]) as numpy arrays from a coefficient file (calib/data/published format)."""
    with open(path) as f:
        doc = json.load(f)
    return np.asarray(doc["alpha"], float), np.asarray(doc["beta"], float)


def angle_rad(c, n):
    n = np.asarray(n, float)
    return c[0] + c[1] * n + c[2] * np.sin(c[3] * n + c[4]) + c[5] * np.sin(c[6] * n + c[7])


def slope_rad_per_count(c, n):
    n = np.asarray(n, float)
    return c[1] + c[2] * c[3] * np.cos(c[3] * n + c[4]) + c[5] * c[6] * np.cos(c[6] * n + c[7])


def counts_for_angle(c, angle, iterations=60):
    """The continuous count N with angle_rad(c, N) = angle (vectorised bisection, then Newton)."""
    angle = np.asarray(angle, float)
    lo = np.full(angle.shape, COUNTS_MIN)
    hi = np.full(angle.shape, COUNTS_MAX)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        above = angle_rad(c, mid) > angle
        hi = np.where(above, mid, hi)
        lo = np.where(above, lo, mid)
    n = 0.5 * (lo + hi)
    for _ in range(2):
        n = n - (angle_rad(c, n) - angle) / slope_rad_per_count(c, n)
    return n


def read_counts(c, angle, count_noise, rng):
    """What the electronics report for a true angle: continuous count + Gaussian noise, rounded, clipped."""
    n = counts_for_angle(c, angle) + rng.normal(0.0, count_noise, np.shape(angle))
    return np.clip(np.rint(n), COUNTS_MIN, COUNTS_MAX)
