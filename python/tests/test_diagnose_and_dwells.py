"""diagnose() equals the command's GAP.json; the reduction and the residuals per dwell."""
import json

import numpy as np

import fpss_stand as fs


def test_diagnose_equals_the_command(fpss, recording, tmp_path, source_dir):
    model = f"{source_dir}/calib/data/published/a-6-fpss1.json"
    gap = tmp_path / "GAP.json"
    fpss("diagnose", "--model", model, "--data", recording, "--out", gap, "--partial")
    cli = json.loads(gap.read_text())
    py = fs.diagnose(model, recording)
    assert py == cli
    assert list(py) == list(cli)  # the same keys in the same order
    from_frame = fs.diagnose(fs.load_published("a-6-fpss1"), fs.read_samples(recording))
    assert from_frame["model"] == "model"
    assert from_frame["verdict"] == cli["verdict"]
    assert from_frame["gap_before_arcsec"] == cli["gap_before_arcsec"]


def test_dwells_and_residuals(recording, cli_calibration):
    _, cli = cli_calibration
    d = fs.dwells(recording, calibration=cli)
    assert set(d["phase"]) == {"null", "offset"}
    assert d.attrs["outliers"] == cli["outliers"]  # the reduction the fit was made on
    assert int(d["samples"].sum()) + int(d["outlier_frames"].sum()) == cli["outliers"]["frames"]
    r = fs.residuals(cli, recording)
    # The fit's residuals are small against the simulated truth; a level per axis aside.
    pitch = r["res_pitch_arcsec"] - r["res_pitch_arcsec"].median()
    assert np.percentile(np.abs(pitch), 95) < 1.0
    assert np.allclose(r["pitch_arcsec"], fs.transfer_function(cli["alpha"], r["counts_alpha"]))
