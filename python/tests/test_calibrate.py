"""calibrate(): the command's calibration.json to the last digit, from a path and from a DataFrame."""
import json

import numpy as np
import pandas as pd
import pytest

import fpss_stand as fs


def without_time(j):
    return {k: v for k, v in j.items() if k != "calibrated_at"}


def test_path_equals_the_command_to_the_last_digit(recording, cli_calibration, tmp_path):
    text, cli = cli_calibration
    out = tmp_path / "calibration.json"
    cal = fs.calibrate(recording, out=out)
    # Key by key, every number equal (Python floats compare exactly), and the files byte for byte
    # but the time stamp.
    assert without_time(cal.json) == without_time(cli)
    assert json.dumps(without_time(cal.json)) == json.dumps(without_time(cli))
    strip = lambda t: "\n".join(l for l in t.splitlines() if '"calibrated_at"' not in l)
    assert strip(out.read_text()) == strip(text)
    assert cal.json["source"] == recording
    assert np.array_equal(cal.alpha, np.array(cli["alpha"]))
    assert "Table 1" in cal.summary or "pitch" in cal.summary
    # The file read back has the fit's summary up to the solver's lines: the same Table 1 and coefficients.
    head = fs.load_coefficients(out).summary
    assert head and cal.summary.startswith(head) and "(radians, N in counts)" in head


def test_the_budget_and_expanded_uncertainty_are_calibration_jsons(recording, cli_calibration):
    _, cli = cli_calibration
    cal = fs.calibrate(recording)
    for axis in ("pitch", "yaw"):
        u = cli["uncertainties"][axis]
        assert cal.expanded_uncertainty(axis) == [tuple(p) for p in u["angle_expanded_uncertainty_arcsec"]]
        assert cal.budget(axis) == u["budget"]
        assert [e["source"] for e in cal.budget(axis)][:4] == ["sensor noise", "quantisation", "reference noise",
                                                              "model and fit"]
        # U = k u at the budget's angle: the root sum of squares of the budget, times k.
        rss = sum(e["u_arcsec"] ** 2 for e in cal.budget(axis)) ** 0.5
        assert abs(u["coverage_factor"] * rss - u["expanded_uncertainty_max_arcsec"]) < 1e-12


def test_dataframe_equals_the_path(recording, cli_calibration):
    _, cli = cli_calibration
    df = fs.read_samples(recording)
    assert list(df.columns[:7]) == list(fs.REQUIRED_COLUMNS)
    cal = fs.calibrate(df)
    assert cal.json["source"] == "DataFrame"
    expected = dict(without_time(cli), source="DataFrame")
    assert without_time(cal.json) == expected
    # pandas' own reader, with round-trip float parsing, gives the same numbers.
    df2 = pd.read_csv(recording, float_precision="round_trip")
    assert without_time(fs.calibrate(df2, name="pandas").json) == dict(expected, source="pandas")


def test_numpy_arrays_equal_the_path(recording, cli_calibration):
    _, cli = cli_calibration
    df = fs.read_samples(recording)
    # The columns the calibration reads: the required ones and the sensor's temperature (its
    # budget entry, docs/calibration.md); without the temperature there is no such entry.
    columns = [c for c in (*fs.REQUIRED_COLUMNS, "temperature_c") if c in df.columns]
    assert "temperature_c" in columns
    cal = fs.calibrate({c: df[c].to_numpy() for c in columns})
    assert without_time(cal.json) == dict(without_time(cli), source="arrays")
    bare = fs.calibrate({c: df[c].to_numpy() for c in fs.REQUIRED_COLUMNS})
    assert bare.json["uncertainties"]["pitch"]["temperature"] is None
    assert cal.json["uncertainties"]["pitch"]["temperature"]["dwells"] > 0


def test_a_bad_file_names_the_file_and_line(tmp_path):
    bad = tmp_path / "broken_samples.csv"
    bad.write_text("time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta\n"
                   "0,null,1,0,0,1,1\n0.1,sideways,1,0,0,1,1\n")
    with pytest.raises(ValueError) as e:
        fs.calibrate(bad)
    assert isinstance(e.value, fs.InputError)
    assert "broken_samples.csv:3:" in str(e.value) and "sideways" in str(e.value)
    with pytest.raises(fs.InputError, match="no_such.csv"):
        fs.calibrate(tmp_path / "no_such.csv")


def test_a_bad_dataframe_names_the_dataframe_and_the_column(recording):
    df = fs.read_samples(recording).head(50)
    with pytest.raises(fs.InputError, match="DataFrame.*counts_beta"):
        fs.calibrate(df.drop(columns=["counts_beta"]))
    df = df.copy()
    df.loc[10, "phase"] = "sideways"
    with pytest.raises(ValueError, match="DataFrame: row 10: phase 'sideways'"):
        fs.calibrate(df)
    df.loc[10, "phase"] = "null"
    df.loc[12, "counts_alpha"] = np.nan
    with pytest.raises(fs.InputError, match="DataFrame: row 12: .*counts_alpha"):
        fs.calibrate(df, name="DataFrame")


def test_too_little_data_is_a_data_error(recording):
    df = fs.read_samples(recording)
    nulls = df[df["phase"] == "null"]
    with pytest.raises(fs.DataError):
        fs.calibrate(nulls)
