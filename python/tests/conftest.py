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
