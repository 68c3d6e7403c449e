#!/usr/bin/python3
"""Runs a procedure file (docs/procedures.md, "Step types": the subset below) on the independent
bench simulator of benchsim.py, with a given truth and seed, and writes what the stand would record.

It is independent of the emulator (fixtures/) and of `fpss-stand simulate`: the gimbal (trapezoid
moves on benchsim's TICK_S clock), the effects on the line of sight and the sensor, the noise and
the whole counts are benchsim.py's own (Gimbal, observe), written from docs/diagnosis.md
("Physical conventions") and the paper's sensor physics (fpss_physics.py). This file only turns
procedure steps into gimbal moves, dwells and recorded slew segments on one clock.

Steps understood (anything else that moves the gimbal is refused; calibrate/check/diagnose are
skipped, they do not touch the bench):
- `home`: move to (0, 0) at the profile rate;
- `move: {pitch_arcsec|pitch_deg, yaw_arcsec|yaw_deg[, rate_arcsec_s|rate_deg_s]}` (an axis not
  given keeps its target);
- `settle: {duration_s}`;
- `sample: {frames: N | duration_s: S[, settle_s][, phase]}`: one dwell (one step) at the current
  target, first frame settle_s after the step starts (its arrival when a move came just before),
  then one frame every 1/SAMPLE_HZ;
- `null_offset_grid: {axes, extent_arcsec|extent_deg, step_arcsec|step_deg, frames|duration_s,
  settle_s, order}` or with `pitch_offsets_arcsec|_deg` / `yaw_offsets_arcsec|_deg` lists: null,
  off1, null, off2, null, ... (each dwell one step; `layout: axes` only, `until` refused);
- `continuous_slew: {axis, amplitude_arcsec|_deg, rate(s)_arcsec_s|_deg_s, directions,
  reversals, sample_period_s, settle_s}`: per rate, per direction (positive first), move to the
  start (the other axis at 0), settle, then one recorded step: reversals + 1 legs, each starting
  the instant the previous one arrives, one sample every sample_period_s of the motion.

Every arrival of a move that moved an axis (a slew's legs included) is an arrival in benchsim's
sense: settling rings from it on the axes that moved, until the next move starts. The session
starts with the gimbal at rest at (0, 0) (homed before the session: time_since_move_s counts from
the session's start until the first arrival). samples.csv always has temperature_c,
time_since_move_s and approach_pitch/approach_yaw (each axis's direction in the last move that
moved the gimbal, 0 if it stood still in it: docs/formats.md), all empty on slew rows.

Truth (truth.json): {"classes": [...], "params": {class: {...}} (benchsim.draw's names),
"temperature": {t0_c, ramp_c_per_s, amplitude_c, period_s[, phase_rad]}, "bench":
{accel_arcsec_s2, profile_rate_arcsec_s}}. The temperature profile runs on lab time: a session
that starts lab_start_s into the lab's day sees the profile from there (temperature_c is what
the bench's thermometer reads); drift counts from each session's time 0 (its own clock).

    benchsim_procedure.py run --procedure P.yaml (--truth TRUTH.json | --cls CLASS[+CLASS]) --seed S
                              --out DIR [--lab-start-s T]
        writes DIR/samples.csv, DIR/model.json (the published model with expected_scatter_arcsec),
        DIR/truth.json (the truth, with the session's seed, lab start and bench time)

Run with /usr/bin/python3 (Debian's, with numpy and python3-yaml).
"""
import argparse
import json
import math
import os
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchsim as bs  # noqa: E402
import fpss_physics as fp  # noqa: E402

PROFILE_RATE_ARCSEC_S = 1800.0   # this bench's move speed when a step names none
MODEL = os.path.join(bs.PUBLISHED, "a-6-fpss1.json")
SKIPPED = {"calibrate", "check", "diagnose"}


def default_truth(classes, rng, size="normal", temperature=None):
    """A truth of the given effect classes, parameters drawn by benchsim.draw."""
    ma, mb = fp.load_coefficients(MODEL)
    params = {c: bs.draw(c, rng, size, ma, mb) for c in classes}
    temp = temperature or {"t0_c": 20.0, "ramp_c_per_s": 0.02, "amplitude_c": 1.5,
                           "period_s": float(rng.uniform(50, 80))}
    return {"classes": list(classes), "params": params, "temperature": temp,
            "bench": {"accel_arcsec_s2": float(rng.uniform(2500, 4000)), "profile_rate_arcsec_s": PROFILE_RATE_ARCSEC_S}}


# ------------------------------------------------------------------ procedure steps

def load_steps(path_or_text):
    """The procedure's steps as (type, fields) pairs, from a file name or YAML text."""
    if os.path.exists(path_or_text):
        with open(path_or_text) as f:
            doc = yaml.safe_load(f)
    else:
        doc = yaml.safe_load(path_or_text)
    out = []
    for st in doc["steps"]:
        if isinstance(st, str):
            out.append((st, {}))
        elif isinstance(st, dict) and len(st) == 1:
            (k, v), = st.items()
            out.append((k, v or {}))
        else:
            raise ValueError(f"a step is a name or a one-key map: {st!r}")
    return out


def arcsec(fields, name, default=None):
    """fields[name_arcsec] or fields[name_deg] in arcsec (default when neither)."""
    if name + "_arcsec" in fields:
        return float(fields[name + "_arcsec"])
    if name + "_deg" in fields:
        return float(fields[name + "_deg"]) * 3600.0
    return default


def grid_offsets(fields):
    """The null_offset_grid's offsets in visiting order: [(axis, offset_arcsec), ...]."""
    if fields.get("layout", "axes") != "axes":
        raise ValueError("null_offset_grid: only layout: axes is simulated")
    if "until" in fields:
        raise ValueError("null_offset_grid: an adaptive stop (until) needs the run's live fit; not simulated")
    listed = [(a, name) for a, name in ((0, "pitch_offsets"), (1, "yaw_offsets"))
              if name + "_arcsec" in fields or name + "_deg" in fields]
    if listed:
        out = []
        for a, name in listed:
            vals = fields.get(name + "_arcsec")
            vals = [float(v) for v in vals] if vals is not None else [3600.0 * float(v) for v in fields[name + "_deg"]]
            out += [(a, v) for v in vals]
        return out
    e, s = arcsec(fields, "extent"), arcsec(fields, "step")
    ks = list(range(1, int(math.floor(e / s + 1e-9)) + 1))
    order = fields.get("order", "outward")
    if order == "outward":
        offs = [sg * k * s for k in ks for sg in (1, -1)]
    elif order == "ascending":
        offs = [-k * s for k in reversed(ks)] + [k * s for k in ks]
    elif order == "descending":
        offs = [k * s for k in reversed(ks)] + [-k * s for k in ks]
    elif order == "spread":
        # +e, -e, then the offset nearest the middle of the widest gap left (zero counts as taken).
        left = [sg * k * s for k in ks for sg in (1, -1)]
        offs = [max(left), min(left)]
        left = [o for o in left if o not in offs]
        while left:
            taken = sorted(offs + [0.0])
            gaps = [(b - a, (a + b) / 2, a, b) for a, b in zip(taken, taken[1:]) if any(a < o < b for o in left)]
            _, mid, a_, b_ = max(gaps)
            best = min((o for o in left if a_ < o < b_), key=lambda o: abs(o - mid))
            offs.append(best)
            left.remove(best)
    else:
        raise ValueError(f"null_offset_grid: order {order!r}")
    axes = fields.get("axes", ["pitch", "yaw"])
    return [({"pitch": 0, "yaw": 1}[ax], o) for ax in axes for o in offs]


class Session:
    """One recording session: the procedure's steps run on benchsim's gimbal, one clock."""

    def __init__(self, bench, rng):
        self.g = bs.Gimbal(bench["accel_arcsec_s2"])
        self.g._log()
        self.profile_rate = bench.get("profile_rate_arcsec_s", PROFILE_RATE_ARCSEC_S)
        self.dt = 1.0 / bs.SAMPLE_HZ
        self.rng = rng
        self.target = [0.0, 0.0]
        self.step = 0
        self.samples, self.arrivals, self.slew_steps = [], [], set()
        # Each axis's direction in the last move that moved the gimbal, 0 when it stood still in it
        # (approach_pitch/yaw, docs/formats.md).
        self.side = [0.0, 0.0]
        self.sides = {}  # dwell step -> the sides when it was sampled

    # -- the gimbal
    def move(self, target, rate=None):
        """A move to target; an arrival when an axis moved (the axes that moved, their directions)."""
        target = [float(target[0]), float(target[1])]
        x0 = self.g.x.copy()
        moved = self.g.move(target, rate or self.profile_rate)
        d = np.sign(np.asarray(target) - x0)
        went = [abs(target[a] - x0[a]) > 2.0 for a in range(2)]
        if any(went):  # a move that moves no axis is none: the last real one stands
            self.side = [float(d[a]) if went[a] else 0.0 for a in range(2)]
        if np.any(moved):
            self.arrivals.append((self.g.t, moved & (d != 0), d))
        self.target = target

    def dwell(self, frames, settle_s, phase=None):
        """One step of `frames` samples at the current target, the first settle_s from now."""
        self.g.hold(settle_s)
        self.step += 1
        self.sides[self.step] = list(self.side)
        phase = phase or ("null" if self.target == [0.0, 0.0] else "offset")
        t0 = self.g.t
        for k in range(frames):
            self.samples.append((t0 + k * self.dt, self.step, phase))
        self.g.hold(frames * self.dt)  # the last frame's integration ends one period later

    def frames_of(self, fields):
        if "frames" in fields:
            return int(fields["frames"])
        return max(1, int(round(float(fields["duration_s"]) / self.dt)))

    # -- the steps
    def run(self, steps):
        for kind, f in steps:
            if kind == "home":
                self.move([0.0, 0.0])
            elif kind == "move":
                tgt = [arcsec(f, "pitch", self.target[0]), arcsec(f, "yaw", self.target[1])]
                rate = f.get("rate_arcsec_s", 3600.0 * f["rate_deg_s"] if "rate_deg_s" in f else None)
                self.move(tgt, rate)
            elif kind == "settle":
                self.g.hold(float(f["duration_s"]))
            elif kind == "sample":
                self.dwell(self.frames_of(f), float(f.get("settle_s", 0.0)), f.get("phase"))
            elif kind == "null_offset_grid":
                self.grid(f)
            elif kind == "continuous_slew":
                self.slews(f)
            elif kind in SKIPPED:
                continue
            else:
                raise ValueError(f"step {kind!r} is not simulated here")
        return self

    def grid(self, f):
        frames, settle = self.frames_of(f), float(f.get("settle_s", 0.5))
        self.move([0.0, 0.0])
        self.dwell(frames, settle)
        for axis, o in grid_offsets(f):
            p = [0.0, 0.0]
            p[axis] = o
            self.move(p)
            self.dwell(frames, settle)
            self.move([0.0, 0.0])
            self.dwell(frames, settle)

    def slews(self, f):
        axis = {"pitch": 0, "yaw": 1}[f["axis"]]
        amp = arcsec(f, "amplitude")
        if "rates_arcsec_s" in f or "rates_deg_s" in f:
            rates = [float(r) for r in f["rates_arcsec_s"]] if "rates_arcsec_s" in f else [3600.0 * float(r) for r in f["rates_deg_s"]]
        else:
            rates = [float(f["rate_arcsec_s"]) if "rate_arcsec_s" in f else 3600.0 * float(f["rate_deg_s"])]
        signs = {"both": (1.0, -1.0), "positive": (1.0,), "negative": (-1.0,)}[f.get("directions", "both")]
        period = max(float(f["sample_period_s"]), self.dt)
        reversals = int(f.get("reversals", 0))
        for rate in rates:
            for sg in signs:
                start, far = [0.0, 0.0], [0.0, 0.0]
                start[axis], far[axis] = -sg * amp, sg * amp
                self.move(start)
                self.g.hold(float(f.get("settle_s", 0.5)))
                self.step += 1
                self.slew_steps.add(self.step)
                t0 = self.g.t
                for leg in range(reversals + 1):
                    self.move(far if leg % 2 == 0 else start, rate)
                t1 = self.g.t
                t = t0 + float(self.rng.uniform(0, period))  # the frame clock's phase
                while t <= t1 + 1e-9:
                    self.samples.append((t, self.step, "slew"))
                    t += period


# ------------------------------------------------------------------ a session's recording

def run_procedure(steps, truth, seed, lab_start_s=0.0):
    """Runs `steps` on the truth's bench: (rows for samples.csv, bench seconds)."""
    rng = np.random.default_rng(seed)
    ma, mb = fp.load_coefficients(MODEL)
    params = truth["params"]
    ta = np.asarray(params["coefficients"]["alpha"]) if "coefficients" in params else ma
    tb = np.asarray(params["coefficients"]["beta"]) if "coefficients" in params else mb
    s = Session(truth["bench"], rng).run(steps)
    if not s.samples:
        raise ValueError("the procedure records nothing")
    profile = bs.temperature_profile(truth["temperature"])
    rows = bs.observe(s.g, s.samples, s.arrivals, [x[2] for x in s.samples], params, ta, tb, ma,
                      lambda t: profile(np.asarray(t) + lab_start_s), truth["temperature"]["t0_c"], True, True, rng)
    since = rows["time_since_move_s"]
    moving = np.isin(rows["step"], sorted(s.slew_steps))
    since[moving] = np.nan
    before = ~moving & np.isnan(since)       # no arrival yet: at rest since the session started
    since[before] = rows["time_s"][before]
    for a, name in enumerate(("approach_pitch", "approach_yaw")):
        rows[name] = np.array([s.sides[k][a] if k in s.sides else np.nan for k in rows["step"]])
    return rows, s.g.t


def write_session(out, rows, truth, seed, lab_start_s, bench_s):
    os.makedirs(out, exist_ok=True)
    ma, _ = fp.load_coefficients(MODEL)
    bs.write_model(MODEL, bs.expected_scatter(ma), os.path.join(out, "model.json"))
    bs.write_samples(rows, list(rows.keys()), os.path.join(out, "samples.csv"))
    with open(os.path.join(out, "truth.json"), "w") as f:
        json.dump(dict(truth, seed=seed, lab_start_s=lab_start_s, bench_s=bench_s), f, indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--procedure", required=True)
    r.add_argument("--truth", help="truth.json (classes, params, temperature, bench)")
    r.add_argument("--cls", help="CLASS[+CLASS]: parameters drawn by benchsim.draw from --seed")
    r.add_argument("--size", default="normal", choices=["normal", "small"])
    r.add_argument("--seed", type=int, default=1)
    r.add_argument("--lab-start-s", type=float, default=0.0)
    r.add_argument("--out", required=True)
    a = ap.parse_args()
    if a.truth:
        with open(a.truth) as f:
            truth = json.load(f)
    else:
        classes = [] if not a.cls or a.cls == "none" else a.cls.split("+")
        truth = default_truth(classes, np.random.default_rng([a.seed, 1]), a.size)
    rows, bench_s = run_procedure(load_steps(a.procedure), truth, a.seed, a.lab_start_s)
    write_session(a.out, rows, truth, a.seed, a.lab_start_s, bench_s)
    print(json.dumps({"rows": int(len(rows["time_s"])), "steps": int(rows["step"].max()), "bench_s": round(bench_s, 3)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
