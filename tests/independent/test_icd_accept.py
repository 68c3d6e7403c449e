"""`fpss-stand accept` against devices written from docs/icd.md alone (icd_devices.py).

A good unit must be accepted (exit 0); a unit sending glitch frames must fail on `outlier_frames`
and nothing else (exit 3), with one set of residual numbers in calibration.json, the certificate
and the report's Table 1. Run by ctest (tests/independent/CMakeLists.txt) with FPSS_STAND set to
the binary.
"""

import json
import os
import subprocess
import sys
import tempfile
import time

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from devices_process import DevicesProcess  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
STAND = os.environ.get("FPSS_STAND", os.path.join(HERE, "..", "..", "build", "stand", "fpss-stand"))
SERIAL = "FPSS1-IND"
SPEED = 20  # bench seconds per wall second: the shipped acceptance's 5 min in about 15 s


class Devices(DevicesProcess):
    """The two devices, one sensor of serial SERIAL."""

    def __init__(self, *args):
        super().__init__(SPEED, "--serial", SERIAL, *args)


def stand_file(folder, info):
    path = os.path.join(folder, "independent_stand.yaml")
    with open(path, "w") as f:
        f.write(f"""\
# The bench of tests/independent/icd_devices.py (written from docs/icd.md alone).
stand: independent-icd-bench
unit: {SERIAL}
gimbal:
  endpoint: {info['gimbal_endpoint']}
  profile_rate_arcsec_s: 1800     # icd_devices.py's power-up profile speed
  acceleration_arcsec_s2: 100000  # it has none to speak of (for the dry-run estimate only)
  in_position_tolerance_arcsec: 1.0
  timed_moves: true               # it implements holding 13-16 and command 6
sensor:
  endpoint: {info['sensor_endpoint']}
  sample_rate_hz: 50
soft_limits:
  pitch_deg: [-0.75, 0.75]
  yaw_deg: [-0.75, 0.75]
  max_rate_arcsec_s: 3600
axes:                             # icd_devices.py's default --mount
  pitch: alpha
  yaw: beta
clock:
  sync: shared                    # one bench clock for both devices
  time_scale: {SPEED}
""")
    return path


def accept(folder, info):
    runs = os.path.join(folder, "runs")
    cmd = [STAND, "accept", "--stand", stand_file(folder, info), "--unit", SERIAL,
           "--runs-dir", runs, "--json", "--quiet", "--no-progress"]
    started = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    print("accept took %.1f s wall" % (time.monotonic() - started))
    return r


def by_id(cert):
    return {c["id"]: c for c in cert["criteria"]}


def figures(cert):
    c = by_id(cert)
    return {k: round(v["measured"], 4) for k, v in c.items() if v["measured"] is not None}


@pytest.fixture
def folder():
    with tempfile.TemporaryDirectory(prefix="fpss-independent-") as d:
        yield d


def test_good_unit_is_accepted(folder):
    dev = Devices("--seed", "11")
    try:
        r = accept(folder, dev.info)
    finally:
        log = dev.close()
    assert r.returncode == 0, r.stderr + r.stdout + log
    cert = json.loads(r.stdout)
    print(json.dumps(figures(cert), indent=1))
    assert cert["verdict"] == "pass" and cert["failed"] == []
    assert cert["outliers"]["outlier_frames"] == 0


def test_glitching_unit_fails_by_name_on_outlier_frames_with_one_set_of_numbers(folder):
    dev = Devices("--seed", "5", "--sensor-glitch-rate", "0.004", "--sensor-glitch-counts", "400")
    try:
        r = accept(folder, dev.info)
    finally:
        log = dev.close()
    assert r.returncode == 3, r.stderr + r.stdout + log
    cert = json.loads(r.stdout)
    print(json.dumps(figures(cert), indent=1))
    print(json.dumps(cert["outliers"], indent=1))
    assert cert["failed"] == ["outlier_frames"]
    crit = by_id(cert)
    o = cert["outliers"]
    n = o["outlier_frames"]
    assert 4 <= n <= 25  # 0.4 % of about 2,400 dwell frames
    assert o["pitch"]["outlier_frames"] + o["yaw"]["outlier_frames"] == n
    assert crit["outlier_frames"]["measured"] == pytest.approx(
        max(o["pitch"]["share"], o["yaw"]["share"]), abs=1e-12)
    for axis in ("pitch", "yaw"):
        for kind in ("3sigma", "worst_point", "centre"):
            assert crit[f"accuracy_{kind}_{axis}"]["measured"] < 0.5, (kind, axis)

    run = cert["run"]["dir"]
    with open(os.path.join(run, "calibration.json")) as f:
        cal = json.load(f)
    with open(os.path.join(run, "report.html")) as f:
        html = f.read()
    with open(os.path.join(run, "certificate.txt")) as f:
        text = f.read()
    # The certificate names the outlier frames with their count.
    assert "outlier_frames" in text
    assert f"{n} of {o['frames']} dwell frames" in text, text
    # One set of numbers: calibration.json's residuals = the certificate's = the report's Table 1.
    assert "differs from the residuals" not in html
    for axis in ("pitch", "yaw"):
        res = cal["residuals"][axis]
        assert crit[f"residual_mean_{axis}"]["measured"] == res["mean_abs_arcsec"]
        assert crit[f"residual_max_{axis}"]["measured"] == res["max_abs_arcsec"]
        row = "%.2f &plusmn; %.2f</td><td>%.2f</td>" % (
            res["mean_abs_arcsec"], res["sd_arcsec"], res["max_abs_arcsec"])
        assert row in html, axis
        assert res["max_abs_arcsec"] < 0.5, axis  # the glitches are not in the fit
    cal_n = cal["outliers"]["outlier_frames"]
    assert cal_n <= n
    assert f"Outlier frames: {cal_n} of " in html
