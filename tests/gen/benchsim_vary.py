"""`benchsim.py --vary`: a stand that makes other choices than ours, drawn per case from a seed.

The targets of docs/diagnosis.md have to hold on recordings from a simulator we never see. Such a
simulator keeps the physics (docs/diagnosis.md, "Physical conventions"; the paper's eq. 1 and 2)
but not our choices, so each of those is drawn here:

- the truth: one of the trustworthy published sets (calib/data/published, those without a
  `suspect` key); the model handed to the diagnosis is that truth;
- the sensor's frame rate (20, 50 or 100 Hz) on a free-running frame clock when the recording
  says each frame's time since the move (otherwise the stand starts sampling settle_s after the
  arrival, the one thing --settle-s can describe);
- the gimbal's acceleration and its speed between dwells;
- the grid: its extent per axis, points per side, a cross or a raster, shuffled or swept in
  order, how often it returns to the null;
- dwell lengths, settle times and the pause after a dwell;
- slews: 1 or 2 per axis (sometimes one more on both axes at once), 150-900 arcsec/s, 0-2
  reversals inside the recorded step, their extent and direction, the other axis held off the
  null, a little rest recorded before the move starts and after it arrives, wherever in the
  session they fall;
- the temperature profile (start, ramp, swing, period, phase);
- optional columns present or absent, extra columns, the column order, step ids that start
  anywhere and skip numbers, a dwell sometimes recorded as two steps, phase labels sometimes
  wrong.

Noise stays what the targets define: 0.3 counts of sensor count noise, 0.05 arcsec of reference
noise.
"""
import json
import math
import os

import numpy as np

PUBLISHED = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "calib", "data", "published"))


def trustworthy_sets():
    """The published coefficient files without a `suspect` key, in name order."""
    out = []
    for name in sorted(os.listdir(PUBLISHED)):
        if not name.endswith(".json"):
            continue
        with open(os.path.join(PUBLISHED, name)) as f:
            if "suspect" not in json.load(f):
                out.append(os.path.join(PUBLISHED, name))
    return out


def draw_setup(rng):
    """Every stand choice of one varied case."""
    s = {"truth": str(rng.choice(trustworthy_sets())),
         "frame_hz": float(rng.choice([20.0, 50.0, 100.0])),
         "accel_arcsec_s2": float(rng.uniform(2000, 8000)),
         "move_rate_arcsec_s": float(rng.uniform(900, 3600)),
         "with_since": bool(rng.uniform() < 0.5),
         "with_temp": bool(rng.uniform() < 0.8),
         "wrong_phases": bool(rng.uniform() < 0.3),
         "extra_columns": bool(rng.uniform() < 0.5),
         "shuffle_columns": bool(rng.uniform() < 0.5),
         "settle_s": float(rng.uniform(0.12, 0.6)),
         "hold_after_s": float(rng.uniform(0.02, 0.3))}
    lo = float(rng.uniform(0.12, 0.4))
    s["settle_range_s"] = [lo, float(rng.uniform(lo, 0.6))]
    fl = int(rng.integers(3, 16))
    s["frames_range"] = [fl, int(rng.integers(fl + 5, 101))]
    s["temperature"] = {"t0_c": float(rng.uniform(15, 30)), "ramp_c_per_s": float(rng.uniform(-0.02, 0.03)),
                        "amplitude_c": float(rng.uniform(0.8, 2.5)), "period_s": float(rng.uniform(40, 150)),
                        "phase_rad": float(rng.uniform(0, 2 * math.pi))}
    s["grid"] = {"extent_arcsec": [float(rng.uniform(900, 1620)), float(rng.uniform(900, 1620))],
                 "per_side": int(rng.integers(3, 9)), "pattern": str(rng.choice(["cross", "cross", "raster"])),
                 "order": str(rng.choice(["shuffled", "shuffled", "sweep"])), "null_every": float(rng.uniform(0, 0.8))}
    s["step_start"] = int(rng.integers(0, 3))
    s["step_gaps"] = bool(rng.uniform() < 0.3)
    return s


def grid_points(rng, g):
    """The dwell positions in visiting order (nulls between them as the setup says)."""
    n = g["per_side"]
    ext = g["extent_arcsec"]
    ks = [k for k in range(-n, n + 1) if k != 0]
    if g["pattern"] == "cross":
        pts = [[k * ext[0] / n, 0.0] for k in ks] + [[0.0, k * ext[1] / n] for k in ks]
    else:
        # A raster's every point is many for 8 a side: a random half of it, the axes kept.
        pts = [[i * ext[0] / n, j * ext[1] / n] for i in range(-n, n + 1) for j in range(-n, n + 1) if (i, j) != (0, 0)]
        keep = rng.uniform(size=len(pts)) < (0.5 if n > 4 else 1.0)
        keep |= np.array([p[0] == 0 or p[1] == 0 for p in pts])
        pts = [p for p, k in zip(pts, keep) if k]
    if g["order"] == "shuffled":
        rng.shuffle(pts)
    else:
        # Swept: up and back down on each axis, so every point is approached from both sides.
        pts = sorted(pts, key=lambda p: (p[1], p[0]))
        pts = pts + pts[::-1]
    out = [[0.0, 0.0]]
    for p in pts:
        out.append(p)
        if rng.uniform() < g["null_every"]:
            out.append([0.0, 0.0])
    return out


def draw_slews(rng, g):
    """Slews: 1 or 2 per axis, sometimes one on both axes at once."""
    slews = []
    plans = [[0]] * int(rng.integers(1, 3)) + [[1]] * int(rng.integers(1, 3))
    if rng.uniform() < 0.2:
        plans.append([0, 1])
    for axes in plans:
        cross = [0.0, 0.0]
        for a in (0, 1):
            if a not in axes and rng.uniform() < 0.3:
                cross[a] = float(rng.uniform(-1, 1) * g["extent_arcsec"][a])
        slews.append({"axes": axes, "rate": float(rng.uniform(150, 900)), "reversals": int(rng.integers(0, 3)),
                      "amp": [float(rng.uniform(800, 1600)) for _ in (0, 1)], "sign": float(rng.choice([-1.0, 1.0])),
                      "cross": cross, "pre_s": float(rng.uniform(0, 0.15)), "post_s": float(rng.uniform(0, 0.15)),
                      "retarget": float(rng.uniform(0.45, 0.9)), "back": float(rng.uniform(0.3, 1.0)),
                      "again": float(rng.uniform(0.2, 1.0))})
    return slews


def plan(rng, setup):
    """The session: dwells over the grid with the slews inserted wherever they fall."""
    items = [("dwell", p) for p in grid_points(rng, setup["grid"])]
    for sl in draw_slews(rng, setup["grid"]):
        items.insert(int(rng.integers(1, len(items) + 1)), ("slew", sl))
    out = []
    fl, fh = setup["frames_range"]
    for kind, it in items:
        if kind == "slew":
            out.append(("slew", it))
            continue
        n = int(rng.integers(fl, fh + 1))
        settle = float(rng.uniform(*setup["settle_range_s"])) if setup["with_since"] else setup["settle_s"]
        split = int(rng.integers(2, n - 1)) if n >= 6 and rng.uniform() < 0.1 else 0
        out.append(("dwell", {"target": it, "frames": n, "settle_s": settle, "split_at": split}))
    return out


class Recorder:
    """Runs the plan on the gimbal and collects the sample times, steps, phases and arrivals."""

    def __init__(self, g, setup, rng):
        self.g, self.setup, self.rng = g, setup, rng
        self.dt = 1.0 / setup["frame_hz"]
        # A free-running frame clock (its phase drawn) when frames carry their own time since
        # the move; otherwise the stand triggers the first frame settle_s after the arrival.
        self.free = setup["with_since"]
        self.phase = float(rng.uniform(0, self.dt))
        self.samples, self.arrivals = [], []
        self.step = setup["step_start"]

    def next_step(self):
        self.step += 1 + (int(self.rng.integers(0, 3)) if self.setup["step_gaps"] else 0)

    def frames_from(self, t):
        """The first frame time at or after t."""
        if not self.free:
            return t
        k = math.ceil((t - self.phase) / self.dt - 1e-9)
        return self.phase + k * self.dt

    def last_dirs(self, since_index):
        """Each axis's last direction of motion in the log from since_index on."""
        v = np.asarray(self.g.log_v[since_index:])
        d = np.zeros(2)
        for a in (0, 1):
            nz = np.flatnonzero(v[:, a])
            d[a] = np.sign(v[nz[-1], a]) if len(nz) else 0.0
        return d

    def dwell(self, it):
        g = self.g
        x0 = g.x.copy()
        moved = g.move(it["target"], self.setup["move_rate_arcsec_s"])
        d = np.sign(np.asarray(it["target"]) - x0)
        if np.any(moved):
            self.arrivals.append((g.t, moved & (d != 0), d))
        t = self.frames_from(g.t + it["settle_s"])
        self.next_step()
        phase = "null" if it["target"] == [0.0, 0.0] else "offset"
        for k in range(it["frames"]):
            if it["split_at"] and k == it["split_at"]:
                self.next_step()  # the same dwell, recorded as a second step
            self.samples.append((t, self.step, phase))
            t += self.dt
        g.hold(t - g.t + self.setup["hold_after_s"])

    def slew(self, sl):
        g = self.g
        start, end, back, again = (list(sl["cross"]) for _ in range(4))
        for a in sl["axes"]:
            start[a] = -sl["sign"] * sl["amp"][a]
            end[a] = sl["sign"] * sl["amp"][a]
            back[a] = -sl["sign"] * sl["amp"][a] * sl["back"]
            again[a] = sl["sign"] * sl["amp"][a] * sl["again"]
        x0 = g.x.copy()
        moved = g.move(start, self.setup["move_rate_arcsec_s"])
        if np.any(moved):
            self.arrivals.append((g.t, moved, np.sign(np.asarray(start) - x0)))
        g.hold(sl["pre_s"] + float(self.rng.uniform(0.05, 0.4)))
        t_rec0 = g.t - sl["pre_s"]
        k0 = len(g.log_v)
        if sl["reversals"] == 0:
            g.move(end, sl["rate"])
        else:
            g.move(end, sl["rate"], retarget=(sl["retarget"], back))
            if sl["reversals"] > 1:
                g.move(again, sl["rate"])
        # The move ends in an arrival: the axes that moved ring, each in its last direction.
        axes = np.array([a in sl["axes"] for a in (0, 1)])
        self.arrivals.append((g.t, axes, self.last_dirs(k0) * axes))
        g.hold(sl["post_s"])
        t_rec1 = g.t
        self.next_step()
        t = self.frames_from(t_rec0)
        while t <= t_rec1 + 1e-9:
            self.samples.append((t, self.step, "slew"))
            t += self.dt
        g.hold(float(self.rng.uniform(0.1, 0.4)))

    def run(self, items):
        for kind, it in items:
            (self.dwell if kind == "dwell" else self.slew)(it)
        return self.samples, self.arrivals


def columns(rows, setup, rng):
    """The column order and any extra columns a stand of this kind writes."""
    if setup["extra_columns"]:
        n = len(rows["time_s"])
        rows["frame"] = np.arange(n) + int(rng.integers(0, 100000))
        rows["status"] = np.full(n, 3)
    cols = list(rows.keys())
    if setup["shuffle_columns"]:
        rng.shuffle(cols)
    return cols
