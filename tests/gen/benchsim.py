#!/usr/bin/python3
"""An independent bench simulator for the sim-to-real diagnosis, written from the physical
conventions of docs/diagnosis.md ("Physical conventions") and the paper's sensor physics
(fpss_physics.py), not from the emulator's code (fixtures/).

It records sessions shaped unlike our procedures: nulls and offsets visited in a random order,
dwells of varying sample count, continuous bang-bang slews that reverse direction inside one
recorded step, phase labels sometimes wrong, optional columns sometimes absent. Effects are the
catalogued ten plus effects outside the catalogue (encoder cyclic error, axis wobble, quadratic
field distortion, vibration, sporadic outlier frames).

It is one file (over 600 lines) on purpose: it is read whole against docs/diagnosis.md, and it
imports only its own siblings (fpss_physics.py, benchsim_vary.py), so nothing of the emulator's can
come in by a shared module.

    benchsim.py case --cls CLASS[+CLASS] --seed S --out DIR [--size normal|small]
        writes DIR/samples.csv, DIR/model.json (the sim's coefficient file, with
        expected_scatter_arcsec), DIR/truth.json (classes, parameters, settle_s)
    benchsim.py eval --fpss-stand BIN --set single|small|pairs|ooc|noise --cases N --seed S [--work DIR]
        generates N cases of the set, runs `fpss-stand diagnose` on each and prints the figures
        the targets of docs/diagnosis.md are stated in; exit 1 when --assert and a target is missed.

Run with /usr/bin/python3 (Debian's, with numpy).
"""
import argparse
import itertools
import json
import math
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchsim_vary as bv  # noqa: E402
import fpss_physics as fp  # noqa: E402

SRC = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
PUBLISHED = os.path.join(SRC, "calib", "data", "published")

CATALOGUE = ["bias", "drift", "scale_factor", "boresight_roll", "axis_nonorthogonality", "backlash",
             "settling", "time_skew", "coefficients", "temperature"]
OUTSIDE = ["encoder_cyclic", "axis_wobble", "field_distortion", "vibration", "outliers"]
# The leading `where` factor of the remainder each outside effect should give (None: no single factor).
OUTSIDE_WHERE = {"encoder_cyclic": "angle", "axis_wobble": "cross_angle", "field_distortion": None,
                 "vibration": "within_step", "outliers": "outlier_frames"}

TICK_S = 0.001
COUNT_NOISE = 0.3          # counts, 1 sigma
REF_NOISE_ARCSEC = 0.05    # reference (encoder) noise, 1 sigma
REF_RESOLUTION = 0.001     # arcsec
SAMPLE_HZ = 50.0


# ------------------------------------------------------------------ effect draws

def draw(cls, rng, size, truth_alpha, truth_beta):
    """Parameters of one effect class. size: normal (clearly above noise) or small (near the limits)."""
    sgn = lambda: rng.choice([-1.0, 1.0])  # noqa: E731
    small = size == "small"
    if cls == "bias":
        m = (lambda: 0.5) if small else (lambda: rng.uniform(1, 5))
        return {"pitch_arcsec": sgn() * m(), "yaw_arcsec": sgn() * m()}
    if cls == "drift":
        m = (lambda: 0.001) if small else (lambda: rng.uniform(0.005, 0.05))
        return {"pitch_arcsec_per_s": sgn() * m(), "yaw_arcsec_per_s": sgn() * m()}
    if cls == "scale_factor":
        m = (lambda: 400.0) if small else (lambda: rng.uniform(200, 2000))
        return {"pitch_ppm": sgn() * m(), "yaw_ppm": sgn() * m()}
    if cls == "boresight_roll":
        return {"roll_arcsec": sgn() * (75.0 if small else rng.uniform(60, 600))}
    if cls == "axis_nonorthogonality":
        return {"skew_arcsec": sgn() * (75.0 if small else rng.uniform(60, 600))}
    if cls == "backlash":
        return {"width_arcsec": 0.75 if small else rng.uniform(1, 6)}
    if cls == "settling":
        if small:
            return {"amplitude_arcsec": 1.0, "tau_s": rng.uniform(0.2, 0.6)}
        return {"amplitude_arcsec": rng.uniform(2, 8), "tau_s": rng.uniform(0.3, 2.0)}
    if cls == "time_skew":
        return {"skew_s": 0.005 if small else rng.uniform(0.02, 0.12)}
    if cls == "temperature":
        m = (lambda: 0.1) if small else (lambda: rng.uniform(0.2, 2))
        return {"pitch_arcsec_per_c": sgn() * m(), "yaw_arcsec_per_c": sgn() * m()}
    if cls == "coefficients":
        # Both sinusoids of both axes changed: amplitudes by a fraction, phases by a few 0.1 rad.
        frac = 0.04 if small else rng.uniform(0.05, 0.25)
        out = {}
        for name, c in (("alpha", truth_alpha), ("beta", truth_beta)):
            c = c.copy()
            c[2] *= 1 + sgn() * frac
            c[5] *= 1 + sgn() * frac
            if not small:
                c[4] += sgn() * rng.uniform(0.05, 0.3)
                c[7] += sgn() * rng.uniform(0.05, 0.3)
            out[name] = [float(v) for v in c]
        return out
    # outside the catalogue
    if cls == "encoder_cyclic":  # the gimbal encoder reads true + E sin(2 pi true / P + phi), per axis
        return {"amplitude_arcsec": rng.uniform(1.5, 5), "period_arcsec": rng.uniform(300, 900),
                "phase_rad": rng.uniform(0, 2 * math.pi), "axis": int(rng.integers(0, 2))}
    if cls == "axis_wobble":  # the yaw line of sight wobbles with the pitch axis's rotation
        return {"amplitude_arcsec": rng.uniform(1.5, 5), "period_arcsec": rng.uniform(400, 1200),
                "phase_rad": rng.uniform(0, 2 * math.pi)}
    if cls == "field_distortion":  # quadratic in the field position, both axes
        return {"pitch_arcsec_at_edge": sgn() * rng.uniform(2, 6), "yaw_arcsec_at_edge": sgn() * rng.uniform(2, 6)}
    if cls == "vibration":  # the bench shakes: a sinusoid of the line of sight on both axes
        return {"amplitude_arcsec": rng.uniform(0.25, 1.0), "frequency_hz": rng.uniform(7, 23),
                "phase_rad": rng.uniform(0, 2 * math.pi)}
    if cls == "outliers":  # sporadic frames with a wild count on one axis
        return {"fraction": 0.015, "min_arcsec": 3.0, "max_arcsec": 60.0}
    raise ValueError(cls)


# ------------------------------------------------------------------ gimbal

class Gimbal:
    """Two independent axes, each a double integrator under a bang-bang (trapezoidal) position
    controller; a new target mid-move makes the axis reverse without stopping."""

    def __init__(self, accel):
        self.a = accel
        self.x = np.zeros(2)
        self.v = np.zeros(2)
        self.t = 0.0
        self.log_t, self.log_x, self.log_v = [], [], []

    def _log(self):
        self.log_t.append(self.t)
        self.log_x.append((float(self.x[0]), float(self.x[1])))
        self.log_v.append((float(self.v[0]), float(self.v[1])))

    def hold(self, dt):
        n = int(round(dt / TICK_S))
        if n <= 0:
            return
        ts = self.t + TICK_S * np.arange(1, n + 1)
        self.log_t.extend(ts.tolist())
        self.log_x.extend([(float(self.x[0]), float(self.x[1]))] * n)
        self.log_v.extend([(0.0, 0.0)] * n)
        self.t = float(ts[-1])

    def move(self, target, rate, retarget=None):
        """Moves to target at up to `rate`; retarget = (fraction of the way, new target): once
        that fraction of the way is covered, the target changes (a reversal inside the move).
        Returns which axes moved."""
        tgt = [float(target[0]), float(target[1])]
        start = [float(self.x[0]), float(self.x[1])]
        x, v = start[:], [float(self.v[0]), float(self.v[1])]
        moved = [abs(tgt[i] - x[i]) > 1e-9 for i in range(2)]
        pending = retarget
        a, dv_max, t = self.a, self.a * TICK_S, self.t
        lt, lx, lv = self.log_t, self.log_x, self.log_v
        while True:
            if pending is not None:
                frac, new = pending
                if all(abs(x[i] - start[i]) >= frac * abs(tgt[i] - start[i]) for i in range(2)):
                    tgt = [float(new[0]), float(new[1])]
                    moved = [moved[i] or abs(tgt[i] - x[i]) > 1e-9 for i in range(2)]
                    pending = None
            if all(abs(tgt[i] - x[i]) < 1e-9 and v[i] == 0 for i in range(2)):
                break
            for i in range(2):
                e = tgt[i] - x[i]
                vw = math.copysign(min(rate, math.sqrt(2 * a * abs(e))), e) if e != 0 else 0.0
                v[i] += max(-dv_max, min(dv_max, vw - v[i]))
                st = v[i] * TICK_S
                if abs(st) >= abs(e) or abs(e) < 1e-6:
                    st = e
                    v[i] = 0.0
                x[i] += st
            t += TICK_S
            lt.append(t)
            lx.append((x[0], x[1]))
            lv.append((v[0], v[1]))
        self.t = t
        self.x = np.array(x)
        self.v = np.array(v)
        return np.array(moved)


# ------------------------------------------------------------------ session

def session(rng, with_since):
    """The session's plan: a list of ('dwell', target, n, settle_s) and ('slew', axis, rate, reversals)."""
    offsets = []
    for axis in (0, 1):
        for k in range(1, 8):
            for s in (1, -1):
                p = [0.0, 0.0]
                p[axis] = s * k * 0.06 * 3600
                offsets.append(p)
    rng.shuffle(offsets)
    items = [("dwell", [0.0, 0.0])]
    for p in offsets:
        items.append(("dwell", p))
        if rng.uniform() < 0.6:
            items.append(("dwell", [0.0, 0.0]))
    slews = []
    for axis in (0, 1):
        for rate in (300.0, 600.0):
            slews.append(("slew", axis, rate))
    rng.shuffle(slews)
    at = int(rng.integers(len(items) // 3, len(items)))
    plan = items[:at] + slews + items[at:]
    out = []
    for it in plan:
        if it[0] == "dwell":
            n = int(rng.integers(10, 41))
            settle = float(rng.uniform(0.12, 0.35)) if with_since else 0.2
            out.append(("dwell", it[1], n, settle))
        else:
            out.append(("slew", it[1], it[2], int(rng.integers(1, 3))))
    return out


def record_plain(g, plan, rng):
    """Runs our own session plan: the sample times (t, step, phase) and the arrivals
    (t_arrival, moved[2], direction[2])."""
    samples = []
    arrivals = []
    step = 0
    for it in plan:
        if it[0] == "dwell":
            _, target, n, settle = it
            x0 = g.x.copy()
            moved = g.move(target, 1800.0)
            d = np.sign(np.asarray(target) - x0)
            if np.any(moved):
                arrivals.append((g.t, moved & (d != 0), d))
            g.hold(settle)
            step += 1
            phase = "null" if target == [0.0, 0.0] else "offset"
            for k in range(n):
                if k:
                    g.hold(1.0 / SAMPLE_HZ)
                samples.append((g.t, step, phase))
            g.hold(0.05)
        else:
            _, axis, rate, reversals = it
            amp = 1500.0
            start = [0.0, 0.0]
            start[axis] = -amp
            x0 = g.x.copy()
            moved = g.move(start, 1800.0)
            if np.any(moved):
                arrivals.append((g.t, moved, np.sign(np.asarray(start) - x0)))
            g.hold(0.3)
            step += 1
            t0 = g.t
            end = [0.0, 0.0]
            end[axis] = amp
            back = [0.0, 0.0]
            back[axis] = -amp * rng.uniform(0.3, 1.0)
            g.move(end, rate, retarget=(rng.uniform(0.45, 0.9), back))
            if reversals > 1:
                again = [0.0, 0.0]
                again[axis] = amp * rng.uniform(0.2, 1.0)
                g.move(again, rate)
            t1 = g.t
            # A slew ends in an arrival too (a move with a target): the axis that moved rings.
            d = np.zeros(2)
            d[axis] = np.sign(g.log_v[-2][axis]) if len(g.log_v) > 1 else 0.0
            arrivals.append((t1, np.array([axis == 0, axis == 1]), d))
            for t in np.arange(t0 + 0.02, t1 - 1e-9, 1.0 / SAMPLE_HZ):
                samples.append((float(t), step, "slew"))
            g.hold(0.3)
    return samples, arrivals


def simulate(classes, seed, size="normal", vary=False):
    rng = np.random.default_rng(seed)
    # --vary: every choice of the stand drawn (benchsim_vary.py); otherwise our own session.
    setup = bv.draw_setup(rng) if vary else None
    model_path = setup["truth"] if vary else os.path.join(PUBLISHED, "a-6-fpss1.json")
    ma, mb = fp.load_coefficients(model_path)
    params = {c: draw(c, rng, size, ma, mb) for c in classes}
    ta = np.asarray(params["coefficients"]["alpha"]) if "coefficients" in params else ma
    tb = np.asarray(params["coefficients"]["beta"]) if "coefficients" in params else mb
    if vary:
        with_since = setup["with_since"]
        with_temp = setup["with_temp"] or "temperature" in classes
        wrong_phases = setup["wrong_phases"]
        accel = setup["accel_arcsec_s2"]
        temp = setup["temperature"]
    else:
        with_since = rng.uniform() < 0.5
        with_temp = rng.uniform() < 0.8 or "temperature" in classes
        wrong_phases = rng.uniform() < 0.3
        accel = float(rng.uniform(2500, 4000))
        temp = {"t0_c": 20.0, "ramp_c_per_s": 0.02, "amplitude_c": 1.5, "period_s": float(rng.uniform(50, 80))}

    g = Gimbal(accel)
    g._log()
    # Sampling schedule: (t, step, phase), and each dwell's arrival time and the axes that moved.
    if vary:
        samples, arrivals = bv.Recorder(g, setup, rng).run(bv.plan(rng, setup))
    else:
        samples, arrivals = record_plain(g, session(rng, with_since), rng)

    phases = [s[2] for s in samples]
    if wrong_phases:
        phases = [str(rng.choice(["null", "offset", "slew", "move"])) for _ in phases]
    rows = observe(g, samples, arrivals, phases, params, ta, tb, ma, temperature_profile(temp), temp["t0_c"],
                   with_temp, with_since, rng)
    meta = {"classes": list(classes), "params": params, "seed": seed, "size": size,
            "settle_s": 0.2, "time_since_move_s": with_since, "temperature_c": with_temp,
            "wrong_phases": wrong_phases, "accel_arcsec_s2": accel, "expected_scatter_arcsec": expected_scatter(ma)}
    if vary:
        meta.update(settle_s=setup["settle_s"], vary=setup, columns=bv.columns(rows, setup, rng))
    return rows, meta, model_path


def temperature_profile(temp):
    """The bench temperature (deg C) at times t: t0_c + ramp t + a sine; a varied profile has a
    phase but still starts at t0_c (the effect is zero there)."""
    def temperature(t):
        ph = temp.get("phase_rad", 0.0)
        T = temp["t0_c"] + temp["ramp_c_per_s"] * t + temp["amplitude_c"] * np.sin(2 * math.pi * t / temp["period_s"] + ph)
        return T - temp["amplitude_c"] * math.sin(ph) if ph else T
    return temperature


def expected_scatter(ma):
    """The expected scatter of one sample's residual about its step mean (arcsec): count noise and
    whole-count rounding through the transfer function's slope, and the reference noise."""
    c2 = abs(ma[1]) * fp.ARCSEC_PER_RAD
    return math.sqrt((COUNT_NOISE ** 2 + 1.0 / 12.0) * c2 ** 2 + REF_NOISE_ARCSEC ** 2)


def observe(g, samples, arrivals, phases, params, ta, tb, ma, temperature, t0_c, with_temp, with_since, rng):
    """What the stand records at the sample times of a gimbal's run: the effects of `params` on the
    line of sight and the sensor (docs/diagnosis.md, "Physical conventions"), the sensor's whole
    counts through the true transfer function (ta, tb), the noisy reference; the columns of
    samples.csv as arrays. samples: (t, step, phase) in time order; arrivals: (t, moved[2],
    direction[2]) in time order; temperature(t): the bench temperature, t0_c where the
    temperature effect is zero."""
    T = np.asarray(g.log_t)
    X = np.asarray(g.log_x)  # encoder (servo) positions, arcsec
    V = np.asarray(g.log_v)
    ts = np.array([s[0] for s in samples])
    steps = np.array([s[1] for s in samples])

    moving_any = np.any(V != 0, axis=1)
    # Direction of motion of each axis at every tick (held while at rest), for backlash.
    dirs = np.zeros_like(V)
    for a_ in range(2):
        sg = np.sign(V[:, a_])
        idx_nz = np.where(sg != 0, np.arange(len(sg)), 0)
        np.maximum.accumulate(idx_nz, out=idx_nz)
        dirs[:, a_] = np.where(idx_nz > 0, sg[idx_nz], 0.0) if len(sg) else sg

    def at(t):
        """Mechanical line of sight (pitch, yaw) at times t (array), from the encoder positions."""
        t = np.asarray(t, float)
        x = np.stack([np.interp(t, T, X[:, a]) for a in range(2)], axis=1)
        enc = x.copy()
        if "scale_factor" in params:  # the encoder reads (1 + ppm) x the true angle
            p = params["scale_factor"]
            x[:, 0] /= 1 + 1e-6 * p["pitch_ppm"]
            x[:, 1] /= 1 + 1e-6 * p["yaw_ppm"]
        if "encoder_cyclic" in params:  # the encoder reads true + E sin(2 pi true / P + phi)
            p = params["encoder_cyclic"]
            a = p["axis"]
            x[:, a] -= p["amplitude_arcsec"] * np.sin(2 * math.pi * enc[:, a] / p["period_arcsec"] + p["phase_rad"])
        if "backlash" in params:
            idx = np.clip(np.searchsorted(T, t, side="right") - 1, 0, len(T) - 1)
            x -= dirs[idx] * 0.5 * params["backlash"]["width_arcsec"]
        if "settling" in params:
            # After an arrival, the axes that moved ring, each in its own direction, until the
            # gimbal moves again; nothing rings while moving.
            p = params["settling"]
            for (ta_, moved, d) in arrivals:
                k0 = np.searchsorted(T, ta_ + 0.5 * TICK_S)
                nxt = np.flatnonzero(moving_any[k0:])
                t_end = T[k0 + nxt[0]] - TICK_S if len(nxt) else np.inf
                live = (t >= ta_) & (t < t_end)
                for ax in range(2):
                    if moved[ax]:
                        x[live, ax] += d[ax] * p["amplitude_arcsec"] * np.exp(-(t[live] - ta_) / p["tau_s"])
        if "vibration" in params:
            p = params["vibration"]
            w = np.sin(2 * math.pi * p["frequency_hz"] * t + p["phase_rad"]) * p["amplitude_arcsec"]
            x[:, 0] += w
            x[:, 1] += 0.7 * np.sin(2 * math.pi * p["frequency_hz"] * 1.31 * t + 1.0) * p["amplitude_arcsec"]
        if "axis_wobble" in params:
            p = params["axis_wobble"]
            x[:, 1] += p["amplitude_arcsec"] * np.sin(2 * math.pi * enc[:, 0] / p["period_arcsec"] + p["phase_rad"])
        return x, enc

    skew = params.get("time_skew", {}).get("skew_s", 0.0)
    seen, _ = at(ts - skew)            # the sensor's sample at t shows the sky at t - skew
    _, enc_now = at(ts)
    p_, y_ = seen[:, 0].copy(), seen[:, 1].copy()
    if "boresight_roll" in params:
        phi = params["boresight_roll"]["roll_arcsec"] / fp.ARCSEC_PER_RAD
        p_, y_ = p_ * math.cos(phi) - y_ * math.sin(phi), p_ * math.sin(phi) + y_ * math.cos(phi)
    if "axis_nonorthogonality" in params:
        y_ = y_ + math.sin(params["axis_nonorthogonality"]["skew_arcsec"] / fp.ARCSEC_PER_RAD) * p_
    tsh = ts - skew
    if "bias" in params:
        p_ = p_ + params["bias"]["pitch_arcsec"]
        y_ = y_ + params["bias"]["yaw_arcsec"]
    if "drift" in params:
        p_ = p_ + params["drift"]["pitch_arcsec_per_s"] * tsh
        y_ = y_ + params["drift"]["yaw_arcsec_per_s"] * tsh
    if "temperature" in params:
        dT = temperature(tsh) - t0_c
        p_ = p_ + params["temperature"]["pitch_arcsec_per_c"] * dT
        y_ = y_ + params["temperature"]["yaw_arcsec_per_c"] * dT
    if "field_distortion" in params:
        q = params["field_distortion"]
        r2 = (p_ ** 2 + y_ ** 2) / 1800.0 ** 2
        p_ = p_ + q["pitch_arcsec_at_edge"] * r2
        y_ = y_ + q["yaw_arcsec_at_edge"] * r2

    na = fp.counts_for_angle(ta, p_ / fp.ARCSEC_PER_RAD) + rng.normal(0, COUNT_NOISE, len(ts))
    nb = fp.counts_for_angle(tb, y_ / fp.ARCSEC_PER_RAD) + rng.normal(0, COUNT_NOISE, len(ts))
    if "outliers" in params:
        q = params["outliers"]
        hit = rng.uniform(size=len(ts)) < q["fraction"]
        mag = rng.uniform(q["min_arcsec"], q["max_arcsec"], len(ts)) * rng.choice([-1, 1], len(ts))
        on_a = rng.uniform(size=len(ts)) < 0.5
        c2 = ma[1] * fp.ARCSEC_PER_RAD
        na = na + np.where(hit & on_a, mag / c2, 0.0)
        nb = nb + np.where(hit & ~on_a, mag / c2, 0.0)
    na = np.clip(np.rint(na), fp.COUNTS_MIN, fp.COUNTS_MAX)
    nb = np.clip(np.rint(nb), fp.COUNTS_MIN, fp.COUNTS_MAX)
    ref = enc_now + rng.normal(0, REF_NOISE_ARCSEC, enc_now.shape)
    ref = np.round(ref / REF_RESOLUTION) * REF_RESOLUTION

    # time since the last arrival (an optional column)
    since = np.full(len(ts), np.nan)
    arr_t = np.array([a_[0] for a_ in arrivals])
    k = np.searchsorted(arr_t, ts, side="right") - 1
    ok = k >= 0
    since[ok] = ts[ok] - arr_t[k[ok]]
    rows = {"time_s": ts, "phase": phases, "step": steps, "ref_pitch_arcsec": ref[:, 0], "ref_yaw_arcsec": ref[:, 1],
            "counts_alpha": na, "counts_beta": nb}
    if with_temp:
        rows["temperature_c"] = temperature(ts)
    if with_since:
        rows["time_since_move_s"] = since
    return rows


def write_case(classes, seed, out, size="normal", vary=False):
    rows, meta, model_path = simulate(classes, seed, size, vary)
    os.makedirs(out, exist_ok=True)
    write_model(model_path, meta["expected_scatter_arcsec"], os.path.join(out, "model.json"))
    write_samples(rows, meta.get("columns") or list(rows.keys()), os.path.join(out, "samples.csv"))
    with open(os.path.join(out, "truth.json"), "w") as f:
        json.dump(meta, f, indent=1)
    return meta


def write_model(model_path, expected_scatter_arcsec, out_path):
    """The sim's coefficient file (model.json): the published set with expected_scatter_arcsec."""
    with open(model_path) as f:
        model = json.load(f)
    model["expected_scatter_arcsec"] = expected_scatter_arcsec
    with open(out_path, "w") as f:
        json.dump(model, f, indent=1)


def write_samples(rows, cols, out_path):
    """samples.csv: the columns `cols` of `rows` (NaN written as an empty field)."""
    n = len(rows["time_s"])
    with open(out_path, "w") as f:
        f.write(",".join(cols) + "\n")
        for i in range(n):
            vals = []
            for c in cols:
                v = rows[c][i]
                if c == "phase":
                    vals.append(v)
                elif c in ("step", "frame", "status"):
                    vals.append(str(int(v)))
                elif c in ("counts_alpha", "counts_beta"):
                    vals.append(str(int(v)))
                elif isinstance(v, float) and math.isnan(v):
                    vals.append("")
                else:
                    vals.append(repr(float(v)))
            f.write(",".join(vals) + "\n")


# ------------------------------------------------------------------ evaluation

PARAM_KEYS = {"bias": ["pitch_arcsec", "yaw_arcsec"], "drift": ["pitch_arcsec_per_s", "yaw_arcsec_per_s"],
              "scale_factor": ["pitch_ppm", "yaw_ppm"], "boresight_roll": ["roll_arcsec"],
              "axis_nonorthogonality": ["skew_arcsec"], "backlash": ["width_arcsec"],
              "settling": ["amplitude_arcsec", "tau_s"], "time_skew": ["skew_s"],
              "temperature": ["pitch_arcsec_per_c", "yaw_arcsec_per_c"], "coefficients": []}


def diagnose(binary, case_dir, meta):
    out = os.path.join(case_dir, "gap.json")
    cmd = [binary, "diagnose", "--model", os.path.join(case_dir, "model.json"), "--data",
           os.path.join(case_dir, "samples.csv"), "--out", out, "--settle-s", str(meta["settle_s"])]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode not in (0, 2) or not os.path.exists(out):
        raise RuntimeError(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr}")
    with open(out) as f:
        return json.load(f)


def case_classes(set_name, k, rng):
    if set_name in ("single", "small"):
        return [CATALOGUE[k % len(CATALOGUE)]]
    if set_name == "noise":
        return []
    if set_name == "ooc":
        return [OUTSIDE[k % len(OUTSIDE)]]
    if set_name == "pairs":
        pairs = [p for p in itertools.combinations(CATALOGUE, 2)
                 if not ("coefficients" in p and ("bias" in p or "scale_factor" in p))]
        return list(pairs[k % len(pairs)])
    raise ValueError(set_name)


def evaluate(args):
    rng = np.random.default_rng(args.seed)
    work = args.work or f"/tmp/benchsim-{args.set}-{args.seed}{'-vary' if args.vary else ''}"
    os.makedirs(work, exist_ok=True)
    size = "small" if args.set == "small" else "normal"
    res = []
    for k in range(args.cases):
        classes = case_classes(args.set, k, rng)
        d = os.path.join(work, f"case-{k}")
        meta = write_case(classes, int(args.seed) * 100003 + k, d, size, args.vary)
        gap = diagnose(args.fpss_stand, d, meta)
        named = [c["name"] for c in gap["causes"]]
        nf = gap["noise_floor_arcsec"]
        r = {"k": k, "truth": classes, "causes": named, "verdict": gap["verdict"],
             "shrink": gap["gap_after_all_arcsec"] / nf, "noise_floor": nf,
             "excess_scatter": gap.get("excess_scatter"), "outliers": gap["outliers"]["count"]}
        rem = gap.get("unexplained")
        r["rem_where"] = rem["where"][0]["factor"] if rem and rem["where"] else None
        # parameter errors of catalogued truths that were named
        errs = []
        for c in classes:
            if c in named and c in PARAM_KEYS:
                fitted = gap["causes"][named.index(c)]["params"]
                for key in PARAM_KEYS[c]:
                    t = meta["params"][c][key]
                    errs.append(abs(fitted[key] - t) / max(abs(t), 1e-12))
        r["param_err"] = max(errs) if errs else None
        res.append(r)
        if not args.quiet:
            print(f"case {k:3d} {'+'.join(classes) or 'none':32s} -> {'+'.join(named) or 'none':32s} "
                  f"{gap['verdict']:17s} shrink {r['shrink']:.2f} where {r['rem_where']} "
                  f"excess {r['excess_scatter'] if r['excess_scatter'] is None else round(r['excess_scatter'], 2)}"
                  + (f" [{stand(meta)}]" if args.vary else ""),
                  file=sys.stderr, flush=True)
    return summarise(args.set, res)


def stand(meta):
    """A varied case's stand choices in a few words (the per-case line)."""
    v = meta["vary"]
    return (f"{os.path.basename(v['truth'])[:-5]} {v['frame_hz']:.0f} Hz accel {v['accel_arcsec_s2']:.0f} "
            f"{v['grid']['pattern']}/{v['grid']['order']} since {int(v['with_since'])} temp {int(meta['temperature_c'])}")


def summarise(set_name, res):
    n = len(res)
    figs = {"set": set_name, "cases": n}
    if set_name in ("single", "small"):
        top1 = sum(1 for r in res if r["causes"] and r["causes"][0] == r["truth"][0])
        spurious = sum(1 for r in res if len(r["causes"]) > 1)
        closed = sum(1 for r in res if r["shrink"] <= 1.5)
        figs.update(top1=top1 / n, spurious_second=spurious / n, gap_after_within_1_5=closed / n)
        figs["missed"] = [f"{r['k']}: {r['truth'][0]}->{'+'.join(r['causes']) or 'none'} {r['verdict']} shrink {r['shrink']:.2f}"
                          for r in res if r["causes"] != r["truth"] or r["shrink"] > 1.5]
        per = {}
        for c in CATALOGUE:
            rc = [r for r in res if r["truth"][0] == c]
            if rc:
                per[c] = sum(1 for r in rc if r["causes"] and r["causes"][0] == c) / len(rc)
        figs["top1_per_class"] = per
        pe = [r["param_err"] for r in res if r["param_err"] is not None]
        if pe:
            figs["param_err_median"] = float(np.median(pe))
            figs["param_err_max"] = float(np.max(pe))
    elif set_name == "pairs":
        both = sum(1 for r in res if set(r["truth"]) <= set(r["causes"]))
        closed = sum(1 for r in res if r["shrink"] <= 1.5)
        figs.update(both_named=both / n, gap_after_within_1_5=closed / n)
        figs["missed"] = [f"{r['k']}: " + "+".join(r["truth"]) + "->" + "+".join(r["causes"]) + f" shrink {r['shrink']:.2f}"
                          for r in res if not set(r["truth"]) <= set(r["causes"]) or r["shrink"] > 1.5]
    elif set_name == "ooc":
        flagged = sum(1 for r in res if r["verdict"] in ("partly_explained", "unexplained"))
        where_cases = [r for r in res if OUTSIDE_WHERE[r["truth"][0]] is not None]
        where_ok = sum(1 for r in where_cases if r["rem_where"] == OUTSIDE_WHERE[r["truth"][0]])
        figs.update(flagged=flagged / n, where_right=where_ok / max(1, len(where_cases)))
        figs["per_class"] = {c: [f"{r['verdict']}/{r['rem_where']}" for r in res if r["truth"][0] == c] for c in OUTSIDE}
    elif set_name == "noise":
        figs["no_gap"] = sum(1 for r in res if r["verdict"] == "no_gap") / n
        figs["verdicts"] = [f"{r['k']}: {r['verdict']} {'+'.join(r['causes'])}" for r in res if r["verdict"] != "no_gap"]
    return figs


TARGETS = {"single": {"top1": 0.99, "gap_after_within_1_5": 0.95}, "small": {"top1": 0.95, "gap_after_within_1_5": 0.95},
           "pairs": {"both_named": 0.90, "gap_after_within_1_5": 0.95}, "ooc": {"flagged": 1.0, "where_right": 0.80}, "noise": {"no_gap": 0.97}}
# Figures that must stay at or below their target: a single effect named with a spurious second.
MAXIMA = {"single": {"spurious_second": 0.01}}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("case")
    c.add_argument("--cls", default="none", help="CLASS or CLASS+CLASS (none: noise only)")
    c.add_argument("--seed", type=int, default=1)
    c.add_argument("--out", required=True)
    c.add_argument("--size", default="normal", choices=["normal", "small"])
    c.add_argument("--vary", action="store_true", help="draw the stand's choices too (benchsim_vary.py)")
    e = sub.add_parser("eval")
    e.add_argument("--fpss-stand", required=True)
    e.add_argument("--set", required=True, choices=list(TARGETS))
    e.add_argument("--cases", type=int, default=20)
    e.add_argument("--seed", type=int, default=1)
    e.add_argument("--work")
    e.add_argument("--vary", action="store_true", help="draw the stand's choices per case (benchsim_vary.py)")
    e.add_argument("--quiet", action="store_true")
    e.add_argument("--assert", dest="check", action="store_true", help="exit 1 when a target is missed")
    a = ap.parse_args()
    if a.cmd == "case":
        classes = [] if a.cls == "none" else a.cls.split("+")
        meta = write_case(classes, a.seed, a.out, a.size, a.vary)
        print(json.dumps({"classes": meta["classes"], "rows_written": True}))
        return 0
    figs = evaluate(a)
    print(json.dumps(figs, indent=1))
    if a.check:
        missed = [f"{k} {figs[k]:.3f} < {v}" for k, v in TARGETS[a.set].items() if figs[k] < v]
        missed += [f"{k} {figs[k]:.3f} > {v}" for k, v in MAXIMA.get(a.set, {}).items() if figs[k] > v]
        if missed:
            print("targets missed: " + "; ".join(missed), file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
