"""Shared fixtures: the fpss-stand binary and a recording it made (simulate), calibrated by the command."""
import json
import os
import shutil
import subprocess

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.environ.get("FPSS_SOURCE_DIR", os.path.abspath(os.path.join(HERE, "..", "..")))


def _binary():
    b = os.environ.get("FPSS_STAND_BIN") or os.path.join(SOURCE_DIR, "build", "stand", "fpss-stand")
    if not os.access(b, os.X_OK):
        b = shutil.which("fpss-stand") or b
    return b


@pytest.fixture(scope="session")
def fpss():
    """Runs fpss-stand with arguments; returns the completed process (check=True)."""
    binary = _binary()
    assert os.access(binary, os.X_OK), f"no fpss-stand binary at {binary} (set FPSS_STAND_BIN)"

    def run(*args, cwd=None):
        return subprocess.run([binary, *map(str, args)], check=True, capture_output=True, text=True, cwd=cwd)
    run.binary = binary
    return run


@pytest.fixture(scope="session")
def source_dir():
    return SOURCE_DIR


@pytest.fixture(scope="session")
def recording(fpss, tmp_path_factory):
    """A simulated null-to-offset recording (samples.csv) with the default truth (a-6-fpss1)."""
    d = tmp_path_factory.mktemp("recording")
    path = d / "samples.csv"
    fpss("simulate", "--out", path, "--seed", 7)
    return str(path)


@pytest.fixture(scope="session")
def cli_calibration(fpss, recording, tmp_path_factory):
    """(calibration.json's text, its content) as `fpss-stand calibrate --data RECORDING` writes it."""
    out = tmp_path_factory.mktemp("cli") / "calibration.json"
    fpss("calibrate", "--data", recording, "--out", out)
    text = out.read_text()
    return text, json.loads(text)


SHORT_CALIBRATION = """name: short_calibration
description: a short null-to-offset grid on both axes, then a fit, for the Python package's tests
steps:
  - home
  - null_offset_grid:
      axes: [pitch, yaw]
      extent_deg: 0.42
      step_deg: 0.06
      settle_s: 0.2
      frames: 3
      order: outward
  - calibrate:
      method: differences
"""


@pytest.fixture(scope="session")
def short_calibration(tmp_path_factory):
    """A procedure file: a short grid (both axes, +-0.42 deg in 0.06 deg steps, 3 frames) and a fit."""
    d = tmp_path_factory.mktemp("procedures")
    path = d / "short_calibration.yaml"
    path.write_text(SHORT_CALIBRATION)
    return path


@pytest.fixture(scope="session")
def run_dir(fpss, short_calibration, tmp_path_factory):
    """A run folder the command made: `fpss-stand run SHORT_CALIBRATION --emulate` (one unit)."""
    runs = tmp_path_factory.mktemp("run") / "runs"
    fpss("run", short_calibration, "--emulate", "--speed", 100, "--runs-dir", runs, "--quiet", "--no-progress")
    (folder,) = [p for p in runs.iterdir() if (p / "run.json").exists()]
    return folder
