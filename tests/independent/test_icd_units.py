"""Several sensor units on one gimbal in one pass, against devices written from docs/icd.md alone.

icd_devices.py serves its one gimbal and several sensors (--sensor, one pty each, each its own
published truth, mount, serial and noise stream); `fpss-stand run` of the discrete grid with a stand
file listing them under `sensors:` must calibrate every unit into units/<SERIAL>/calibration.json
within 0.1 arcsec of its own truth over +-0.4 deg, and record every unit as completed in run.json
(docs/procedures.md "Several units", docs/formats.md). A unit whose line goes silent mid-run is lost
with `silence` while the other completes, and the run's exit code is not 0. Run by ctest
(tests/independent/CMakeLists.txt) with FPSS_STAND set to the binary.
"""

import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from devices_process import DevicesProcess  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.dirname(os.path.dirname(HERE))
STAND = os.environ.get("FPSS_STAND", os.path.join(SOURCE, "build", "stand", "fpss-stand"))
PROCEDURE = os.path.join(SOURCE, "procedures", "discrete_grid.yaml")
SPEED = 20  # bench seconds per wall second: the grid's ~3 min of bench time in about 10 s
ARCSEC_PER_RAD = 180 * 3600 / math.pi
TOLERANCE_ARCSEC = 0.1
RANGE_ARCSEC = 0.4 * 3600


class Unit:
    """One sensor unit: its serial, its published truth, how it sits on the gimbal. `mount` is the
    device's (which gimbal axis, and sign, each sensor axis sees), `axes` the stand file's (each
    gimbal axis as a signed sensor axis): the same mounting said from the two sides."""

    def __init__(self, serial, truth, mount, axes):
        self.serial, self.truth, self.mount, self.axes = serial, truth, mount, axes

    def coefficients(self):
        with open(os.path.join(SOURCE, "calib", "data", "published", self.truth + ".json")) as f:
            return json.load(f)


UNITS = [
    Unit("FPSS1-IND", "a-6-fpss1", "alpha=pitch,beta=yaw", {"pitch": "alpha", "yaw": "beta"}),
    # The paper's Table 2 mounting: alpha sees -yaw, beta sees pitch.
    Unit("FPSS2-IND", "a-6-fpss2", "alpha=-yaw,beta=pitch", {"pitch": "beta", "yaw": "-alpha"}),
    Unit("FPSS3-IND", "a-7-fpss1", "alpha=-pitch,beta=-yaw", {"pitch": "-alpha", "yaw": "-beta"}),
    Unit("FPSS4-IND", "a-7-fpss2", "alpha=yaw,beta=-pitch", {"pitch": "-beta", "yaw": "alpha"}),
]


class Devices(DevicesProcess):
    """The devices with one sensor per unit."""

    def __init__(self, units, *args):
        sensors = []
        for u in units:
            sensors += ["--sensor", "%s:%s:%s" % (u.serial, u.truth, u.mount)]
        super().__init__(SPEED, *sensors, *args)
        assert [s["serial"] for s in self.info["sensors"]] == [u.serial for u in units]
        assert self.info["sensor_endpoint"] == self.info["sensors"][0]["sensor_endpoint"]


def stand_file(folder, info, units, max_remeasure=3):
    path = os.path.join(folder, "independent_units_stand.yaml")
    entries = ""
    for u, s in zip(units, info["sensors"]):
        entries += (f"  - unit: {u.serial}\n"
                    f"    endpoint: {s['sensor_endpoint']}\n"
                    f"    axes: {{pitch: {u.axes['pitch']}, yaw: {u.axes['yaw']}}}\n"
                    f"    sample_rate_hz: 50\n")
    with open(path, "w") as f:
        f.write(f"""\
# The bench of tests/independent/icd_devices.py (written from docs/icd.md alone), several units.
stand: independent-icd-bench-units
gimbal:
  endpoint: {info['gimbal_endpoint']}
  profile_rate_arcsec_s: 1800     # icd_devices.py's power-up profile speed
  acceleration_arcsec_s2: 100000  # it has none to speak of
  in_position_tolerance_arcsec: 1.0
  timed_moves: true               # it implements holding 13-16 and command 6
sensors:
{entries}soft_limits:
  pitch_deg: [-0.75, 0.75]
  yaw_deg: [-0.75, 0.75]
  max_rate_arcsec_s: 3600
clock:
  sync: shared                    # one bench clock for the gimbal and every unit
  time_scale: {SPEED}
points:
  max_remeasure: {max_remeasure}
""")
    return path


def run(folder, info, units, **stand):
    runs = os.path.join(folder, "runs")
    cmd = [STAND, "run", PROCEDURE, "--stand", stand_file(folder, info, units, **stand),
           "--runs-dir", runs, "--quiet", "--no-progress"]
    started = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=110)
    wall = time.monotonic() - started
    print("run took %.1f s wall, exit %d" % (wall, r.returncode))
    dirs = [os.path.join(runs, d) for d in sorted(os.listdir(runs))
            if os.path.isfile(os.path.join(runs, d, "run.json"))] if os.path.isdir(runs) else []
    assert len(dirs) == 1, (dirs, r.stdout, r.stderr)
    with open(os.path.join(dirs[0], "run.json")) as f:
        run_json = json.load(f)
    return r, dirs[0], run_json, wall


# ---------------------------------------------------------------------------------------------
# The transfer function (paper eq. 1), written here again for the comparison.


def angle_rad(c, n):
    """Eq. 1: angle = C1 + C2 N + C3 sin(C4 N + C5) + C6 sin(C7 N + C8), radians, N counts."""
    n = np.asarray(n, dtype=float)
    return c[0] + c[1] * n + c[2] * np.sin(c[3] * n + c[4]) + c[5] * np.sin(c[6] * n + c[7])


def worst_error_arcsec(fit, truth):
    """The fit's largest distance from the truth, in arcsec, over the counts at which the truth
    sees +-0.4 deg (every count, ends included).

    No constant offset is allowed for: the devices' sensor sees exactly the gimbal's angle (no
    boresight offset, encoders without error), so the truth's angle at the null dwells' counts is
    the bench reference there, 0; the fit's C1 is that null condition (docs/calibration.md, step 7:
    angle(N_null) = ref_null = 0). The published C1 is then the truth's own and both describe the
    same angles, C1 included."""
    n = np.arange(-32768, 32768, dtype=float)
    a = angle_rad(truth, n) * ARCSEC_PER_RAD
    inside = n[np.abs(a) <= RANGE_ARCSEC]
    lo, hi = inside.min() - 1, inside.max() + 1  # the counts just beyond +-0.4 deg too
    counts = np.arange(lo, hi + 1)
    # The truth is monotonic over the i16 counts (icd_devices.py checks it): the range is one piece.
    assert len(counts) == len(inside) + 2, "truth not monotonic over +-0.4 deg"
    err = (angle_rad(fit, counts) - angle_rad(truth, counts)) * ARCSEC_PER_RAD
    return float(np.max(np.abs(err)))


def check_fit(run_dir, unit):
    """units/<SERIAL>/calibration.json against the unit's truth; returns the worst error per axis."""
    with open(os.path.join(run_dir, "units", unit.serial, "calibration.json")) as f:
        cal = json.load(f)
    truth = unit.coefficients()
    worst = {axis: worst_error_arcsec(cal[axis], truth[axis]) for axis in ("alpha", "beta")}
    print("%s (%s, mount %s): worst |fit - truth| over +-0.4 deg: alpha %.4f, beta %.4f arcsec"
          % (unit.serial, unit.truth, unit.mount, worst["alpha"], worst["beta"]))
    for axis, e in worst.items():
        assert e <= TOLERANCE_ARCSEC, (unit.serial, axis, e)
    return worst


def read_rows(run_dir, unit):
    with open(os.path.join(run_dir, "units", unit.serial, "samples.csv")) as f:
        return list(csv.DictReader(f))


def check_rows(run_dir, units, lead):
    """Every unit's dwell rows stand on the lead's gimbal readings (docs/formats.md: the files'
    gimbal_time_s columns share their values) and are in that unit's own sensor frame (its axes)."""
    rows = {u.serial: [r for r in read_rows(run_dir, u) if r["phase"] in ("null", "offset")]
            for u in units}
    lead_times = {}
    for r in rows[lead.serial]:
        lead_times.setdefault(r["step"], set()).add(float(r["gimbal_time_s"]))
    for u in units:
        assert rows[u.serial], u.serial
        for r in rows[u.serial]:
            assert float(r["gimbal_time_s"]) in lead_times.get(r["step"], ()), (u.serial, r)
            gimbal = {"pitch": float(r["gimbal_pitch_arcsec"]), "yaw": float(r["gimbal_yaw_arcsec"])}
            # axes: stand axis -> signed sensor axis; alpha's reference is ref_pitch_arcsec.
            seen = {}
            for stand_axis, sensor_axis in u.axes.items():
                sign = -1.0 if sensor_axis.startswith("-") else 1.0
                seen[sensor_axis.lstrip("+-")] = sign * gimbal[stand_axis]
            assert float(r["ref_pitch_arcsec"]) == pytest.approx(seen["alpha"], abs=1e-6), (u.serial, r)
            assert float(r["ref_yaw_arcsec"]) == pytest.approx(seen["beta"], abs=1e-6), (u.serial, r)
    return {s: len(v) for s, v in rows.items()}


def check_all_completed(r, run_dir, run_json, units, log):
    assert r.returncode == 0, r.stderr + r.stdout + log
    assert run_json["outcome"] == "completed", run_json.get("reason")
    listed = run_json["units"]
    assert [u["serial"] for u in listed] == [u.serial for u in units]
    for entry, u in zip(listed, units):
        assert entry["outcome"] == "completed", entry
        assert entry["sensor_id"].startswith("FPSS,SN=%s," % u.serial), entry
    worst = {u.serial: check_fit(run_dir, u) for u in units}
    print("dwell rows per unit:", check_rows(run_dir, units, units[0]))
    return worst


@pytest.fixture
def folder():
    with tempfile.TemporaryDirectory(prefix="fpss-independent-units-") as d:
        yield d


@pytest.mark.parametrize("count,seed", [(2, "21"), (4, "22")], ids=["two", "four"])
def test_units_each_calibrated_to_its_own_truth(folder, count, seed):
    units = UNITS[:count]
    started = time.monotonic()
    dev = Devices(units, "--seed", seed)
    try:
        r, run_dir, run_json, _ = run(folder, dev.info, units)
    finally:
        log = dev.close()
    check_all_completed(r, run_dir, run_json, units, log)
    print("case took %.1f s wall" % (time.monotonic() - started))


# How a unit is lost mid-run (icd_devices.py): it says nothing more while its line stays open
# (--sensor-silent), or its line goes away (--sensor-unplug: the pty closed, its path gone).
LOSSES = {"silent": "--sensor-silent", "unplugged": "--sensor-unplug"}


@pytest.mark.parametrize("how,lost", [("silent", 2), ("unplugged", 2), ("silent", 1), ("unplugged", 1)],
                         ids=["silent_follower", "unplugged_follower", "silent_lead", "unplugged_lead"])
def test_two_units_one_lost_mid_run_and_the_other_completes(folder, how, lost):
    units = UNITS[:2]
    gone, kept = units[lost - 1], units[2 - lost]
    started = time.monotonic()
    # The unit is lost 90 bench seconds after the run first started its stream: about halfway
    # through the grid's ~185 bench seconds.
    dev = Devices(units, "--seed", "23", LOSSES[how], "%d:90" % lost)
    try:
        r, run_dir, run_json, _ = run(folder, dev.info, units)
    finally:
        log = dev.close()
    assert "sensor %s %s" % (gone.serial, "silent" if how == "silent" else "unplugged") in log, log
    # docs/procedures.md: "The run exits 0 only when every unit completed"; run's codes are 0, 1
    # (failed or interrupted) and 2 (bad input, nothing moved).
    assert r.returncode == 1, r.stderr + r.stdout + log
    print("run.json outcome %r, stop_cause %r, reason %r"
          % (run_json["outcome"], run_json.get("stop_cause"), run_json.get("reason")))
    entries = {u["serial"]: u for u in run_json["units"]}
    assert [u["serial"] for u in run_json["units"]] == [u.serial for u in units]
    g, k = entries[gone.serial], entries[kept.serial]
    print(json.dumps(g, indent=1))
    # Even with --quiet the command line says which unit was lost, why and where.
    assert "unit %s: lost (%s) at point %d: " % (gone.serial, g["loss_cause"], g["lost_at_point"]) in r.stdout, r.stdout
    assert k["outcome"] == "completed", k
    assert g["outcome"] == "lost", g
    # docs/icd.md, several units: a line that stays open but sends nothing is `silence`; a line
    # gone mid-run whose reopens fail is `link_failed`.
    assert g["loss_cause"] == ("silence" if how == "silent" else "link_failed"), g
    assert g.get("reason"), g
    total = run_json["points"]["total"]
    assert 1 < g["lost_at_point"] < total, (g["lost_at_point"], total)
    # The other unit completed and is calibrated to its truth; the lost one is not calibrated.
    check_fit(run_dir, kept)
    assert not os.path.exists(os.path.join(run_dir, "units", gone.serial, "calibration.json"))
    assert not g.get("calibration"), g
    # A fault event at that point names the lost unit (docs/procedures.md, "A unit that fails") by
    # its serial ("unit 2 (FPSS2-IND) lost (silence): ...").
    with open(os.path.join(run_dir, "events.jsonl")) as f:
        events = [json.loads(line) for line in f if line.strip()]
    faults = [e for e in events if e["type"] == "fault"]
    print("fault events:", json.dumps(faults, indent=1))
    named = [e for e in faults if g["loss_cause"] in e["message"]
             and gone.serial in e["message"]]
    assert len(named) == 1 and named[0]["point"] == g["lost_at_point"], faults
    # The lost unit's recording stops before the point it was lost at; the other unit's has every
    # point (a lost lead's point measured afresh by the next lead).
    steps = {u.serial: {int(row["step"]) for row in read_rows(run_dir, u)} for u in units}
    assert max(steps[gone.serial]) < g["lost_at_point"], sorted(steps[gone.serial])[-5:]
    assert steps[kept.serial] == set(range(1, total + 1)), set(range(1, total + 1)) - steps[kept.serial]
    print("case took %.1f s wall" % (time.monotonic() - started))
