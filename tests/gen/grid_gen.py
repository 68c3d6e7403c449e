#!/usr/bin/python3
"""Independent generator of noise-only null-to-offset grid recordings (samples CSV), for Monte Carlo.

Written from the paper's procedure (Gambardella and Thompson 1980, section 2: the stand is stepped
null -> offset -> null along pitch and along yaw over the field of view) and the sensor physics in
fpss_physics.py (eq. 1, 2, whole-count rounding), not from the C++ bench or emulator.

Per dwell: `samples` frames; each frame's counts are round(N_true + Gaussian count noise), each
frame's reference the true angle plus Gaussian reference noise (with --frames-per-reading K, one
encoder reading serves K consecutive frames: a recorder that reads the gimbal less often than the
sensor sends frames, each frame taking the latest reading). The true angle is the commanded
offset exactly (noise-only recordings: no gimbal dynamics, no misalignment). pitch = alpha(N_alpha),
yaw = beta(N_beta), as the coefficient files define.

Usage:
  /usr/bin/python3 tests/gen/grid_gen.py --truth FILE --out-dir DIR --recordings K --seed S
      [--samples-per-dwell M] [--count-noise-counts 0.3] [--ref-noise-arcsec 0.05]
      [--extent-deg 0.45] [--step-deg 0.03] [--outlier-rate 0] [--frames-per-reading 1]
      [--gimbal-errors REF.json] [--temperature-amplitude-c A --temperature-arcsec-per-c K]
      [--verification]
Writes DIR/rec-0000.csv ... and prints one line per file.

--gimbal-errors: a reference calibration file (docs/formats.md, "Reference calibration file"); for
each recording every term is drawn from N(value, u) and the encoders read the true angle plus
the errors: zero + scale_factor_ppm 1e-6 x own angle + sin(nonorthogonality) x the other axis's
angle + sum of amplitude sin(harmonic x own angle in radians + phase). Written from that text.

--temperature-amplitude-c A (> 0): the sensor's temperature is 20 + A sin(2 pi t / P + phi) C, P
drawn per recording uniformly between 0.5 and 2 times the recording's length and phi uniformly;
each frame carries it (`temperature_c`), and with --temperature-arcsec-per-c K the sensor's line of
sight moves with it: a frame's counts are those of the true angle + K (T - 20) on both axes (a
null shift of the sensor head, docs/calibration.md "temperature").

--verification: after the grid, the same recording goes on with verification dwells between the
grid's offsets (+-(i - 1/2) step along pitch, then yaw, each followed by a null), on the same drawn
gimbal errors: an acceptance's verification (docs/acceptance.md), the grid's steps its calibration.
"""
import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fpss_physics as phys  # noqa: E402

ARCSEC_PER_DEG = 3600.0


def offsets_deg(extent, step):
    """Outward order: +s, -s, +2s, -2s, ... up to +-extent."""
    k = int(math.floor(extent / step + 1e-9))
    out = []
    for i in range(1, k + 1):
        out += [i * step, -i * step]
    return out


def plan(extent, step, verification=False):
    """(phase, pitch_deg, yaw_deg) per dwell: null, off, null, off, ..., null; pitch offsets, then yaw;
    with verification, then the midpoints the same way."""
    dwells = [("null", 0.0, 0.0)]
    for axis in ("pitch", "yaw"):
        for o in offsets_deg(extent, step):
            dwells.append(("offset", o, 0.0) if axis == "pitch" else ("offset", 0.0, o))
            dwells.append(("null", 0.0, 0.0))
    if verification:
        k = int(math.floor(extent / step + 1e-9))
        mids = [s * (i - 0.5) * step for i in range(1, k + 1) for s in (1, -1)]
        for axis in ("pitch", "yaw"):
            for o in mids:
                dwells.append(("offset", o, 0.0) if axis == "pitch" else ("offset", 0.0, o))
                dwells.append(("null", 0.0, 0.0))
    return dwells


def draw_errors(spec, rng):
    """One gimbal's true errors, every term drawn from N(value, u)."""
    draw = lambda t: t["value"] + t["u"] * rng.normal()  # noqa: E731
    out = {}
    for axis in ("pitch", "yaw"):
        a = spec[axis]
        out[axis] = {"ppm": draw(a["scale_factor_ppm"]), "nonorth": draw(a["nonorthogonality_arcsec"]),
                     "zero": draw(a["zero_arcsec"]),
                     "cyclic": [(c["harmonic"], draw(c["amplitude_arcsec"]), draw(c["phase_rad"])) for c in a["cyclic"]]}
    return out


def encoder_error(e, own, other):
    """Reading minus true angle of one axis (arcsec) at its own and the other axis's true angles."""
    err = e["zero"] + 1e-6 * e["ppm"] * own + math.sin(e["nonorth"] / phys.ARCSEC_PER_RAD) * other
    for h, amp, phase in e["cyclic"]:
        err += amp * np.sin(h * own / phys.ARCSEC_PER_RAD + phase)
    return err


def recording(alpha, beta, dwells, m, count_noise, ref_noise, outlier_rate, rng, per_reading=1, errors=None,
              temperature=None):
    rows = []
    n_dw = len(dwells)
    pitch = np.array([d[1] for d in dwells]) * ARCSEC_PER_DEG
    yaw = np.array([d[2] for d in dwells]) * ARCSEC_PER_DEG
    shape = (n_dw, m)
    time = np.arange(n_dw * m, dtype=float).reshape(shape) * 0.1 + np.arange(n_dw)[:, None] * 2.0
    temp_c = None
    if temperature is not None:
        amplitude, per_c = temperature
        length = float(time[-1, -1])
        period = length * rng.uniform(0.5, 2.0)
        phi = rng.uniform(0.0, 2 * math.pi)
        temp_c = 20.0 + amplitude * np.sin(2 * math.pi * time / period + phi)
        shift = per_c * (temp_c - 20.0)
        na = phys.counts_for_angle(alpha, (pitch[:, None] + shift) / phys.ARCSEC_PER_RAD)
        nb = phys.counts_for_angle(beta, (yaw[:, None] + shift) / phys.ARCSEC_PER_RAD)
    else:
        na = phys.counts_for_angle(alpha, pitch / phys.ARCSEC_PER_RAD)[:, None]
        nb = phys.counts_for_angle(beta, yaw / phys.ARCSEC_PER_RAD)[:, None]
    ca = np.clip(np.rint(na + rng.normal(0.0, count_noise, shape)), phys.COUNTS_MIN, phys.COUNTS_MAX)
    cb = np.clip(np.rint(nb + rng.normal(0.0, count_noise, shape)), phys.COUNTS_MIN, phys.COUNTS_MAX)
    if outlier_rate > 0:
        # Isolated spikes: a frame's count off by 20..200 counts (a bit error, a glint).
        hit = rng.random(shape) < outlier_rate
        ca = np.where(hit, ca + rng.choice([-1, 1], shape) * rng.integers(20, 200, shape), ca)
    rp_true, ry_true = pitch, yaw
    if errors is not None:
        rp_true = pitch + encoder_error(errors["pitch"], pitch, yaw)
        ry_true = yaw + encoder_error(errors["yaw"], yaw, pitch)
    rp = rp_true[:, None] + rng.normal(0.0, ref_noise, shape)
    ry = ry_true[:, None] + rng.normal(0.0, ref_noise, shape)
    if per_reading > 1:
        first = (np.arange(m) // per_reading) * per_reading  # each frame's reading: the block's first
        rp, ry = rp[:, first], ry[:, first]
    header = "time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta"
    for k, d in enumerate(dwells):
        for i in range(m):
            row = "%.3f,%s,%d,%.6f,%.6f,%d,%d" % (time[k, i], d[0], k + 1, rp[k, i], ry[k, i], ca[k, i], cb[k, i])
            rows.append(row if temp_c is None else row + ",%.4f" % temp_c[k, i])
    if temp_c is not None:
        header += ",temperature_c"
    return header + "\n" + "\n".join(rows) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truth", required=True)
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--recordings", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--samples-per-dwell", type=int, default=5)
    ap.add_argument("--count-noise-counts", type=float, default=0.3)
    ap.add_argument("--ref-noise-arcsec", type=float, default=0.05)
    ap.add_argument("--extent-deg", type=float, default=0.45)
    ap.add_argument("--step-deg", type=float, default=0.03)
    ap.add_argument("--outlier-rate", type=float, default=0.0)
    ap.add_argument("--frames-per-reading", type=int, default=1)
    ap.add_argument("--gimbal-errors", default="")
    ap.add_argument("--temperature-amplitude-c", type=float, default=0.0)
    ap.add_argument("--temperature-arcsec-per-c", type=float, default=0.0)
    ap.add_argument("--verification", action="store_true")
    a = ap.parse_args()
    spec = json.load(open(a.gimbal_errors)) if a.gimbal_errors else None
    alpha, beta = phys.load_coefficients(a.truth)
    dwells = plan(a.extent_deg, a.step_deg, a.verification)
    rng = np.random.default_rng(a.seed)
    os.makedirs(a.out_dir, exist_ok=True)
    for r in range(a.recordings):
        errors = draw_errors(spec, rng) if spec else None
        temperature = (a.temperature_amplitude_c, a.temperature_arcsec_per_c) if a.temperature_amplitude_c > 0 else None
        text = recording(alpha, beta, dwells, a.samples_per_dwell, a.count_noise_counts, a.ref_noise_arcsec,
                         a.outlier_rate, rng, a.frames_per_reading, errors, temperature)
        path = os.path.join(a.out_dir, "rec-%04d.csv" % r)
        with open(path, "w") as f:
            f.write(text)
        print(path)


if __name__ == "__main__":
    main()
