"""open_run on a run folder the command made: each file as the stand's readers read it, equal to the file."""
import json
import os
import shutil

import pandas as pd
import pytest

import fpss_stand as fs


@pytest.fixture(scope="module")
def run(run_dir):
    return fs.open_run(run_dir)


def test_samples_equal_the_file_read_by_pandas(run, run_dir):
    csv = pd.read_csv(run_dir / "samples.csv", keep_default_na=False, na_values=[""])
    df = run.samples
    assert list(run.samples_by_unit) == [run.unit]
    assert run.samples_by_unit[run.unit] is df
    assert set(df.columns) == set(csv.columns)
    pd.testing.assert_frame_equal(df[list(csv.columns)], csv, check_dtype=False)


def test_run_file_fields_equal_the_file(run, run_dir):
    doc = json.loads((run_dir / "run.json").read_text())
    info = run.run_file
    assert info.run_id == doc["run_id"] and info.unit == doc["unit"] and info.outcome == "completed"
    assert info.emulated is True and info.started_utc == doc["started_utc"] and info.ended_utc == doc["ended_utc"]
    assert info.procedure.name == "short_calibration" and info.procedure.sha256 == doc["procedure"]["sha256"]
    assert info.points.total == doc["points"]["total"] == info.points.completed
    assert info.files.calibration == doc["files"]["calibration"]
    assert [s.session for s in info.sessions] == [s["session"] for s in doc["sessions"]]
    assert info.sessions[0].pid == doc["sessions"][0]["pid"]
    assert info.json == doc  # RunFile writes back what it read, key for key
    with pytest.raises(dataclasses_frozen()):
        info.unit = "other"


def dataclasses_frozen():
    import dataclasses
    return dataclasses.FrozenInstanceError


def test_events_one_row_per_line_typed(run, run_dir):
    lines = [json.loads(l) for l in (run_dir / "events.jsonl").read_text().splitlines()]
    ev = run.events
    assert len(ev) == len(lines)
    assert list(ev["type"]) == [l["type"] for l in lines]
    assert str(ev["utc"].dtype).startswith("datetime64[ns, UTC")
    assert ev["point"].dtype == "Int64" and ev["counts_alpha"].dtype == "float64"
    done = ev[ev["type"] == "point_done"]
    assert len(done) == run.run_file.points.completed
    assert list(done["point"]) == list(range(1, len(done) + 1))
    stop = ev[ev["type"] == "run_stopped"].iloc[-1]
    assert stop["outcome"] == "completed" and stop["cause"] == "none"
    # The typed form written again is the line as written.
    first = next(l for l in lines if l["type"] == "point_done")
    assert run.event_lines[lines.index(first)] == first


def test_points_calibration_and_no_acceptance(run, run_dir):
    pts = run.points
    journal = [json.loads(l) for l in (run_dir / "points.jsonl").read_text().splitlines()]
    assert list(pts["point"]) == [j["point"] for j in journal]
    assert list(pts["bytes"]) == [j["bytes"] for j in journal]
    assert pts["rows"].sum() == len(run.samples)
    cal = run.calibration
    assert cal is not None and cal.json == json.loads((run_dir / "calibration.json").read_text())
    assert list(run.calibrations) == ["calibration.json"]
    assert run.acceptance is None and run.gap is None


def test_the_runs_calibration_has_its_table_1(run, run_dir):
    """The run's calibration.summary: Table 1 from calibration.json's residuals, as the command prints it."""
    cal = run.calibration
    assert cal.summary.startswith("Calibration of ")
    assert "mean residual (arcsec)" in cal.summary and "alpha (pitch) +- 1 sigma" in cal.summary
    pitch = cal.residuals["pitch"]
    row = next(l for l in cal.summary.splitlines() if l.startswith("pitch (alpha)"))
    assert f"{pitch['mean_abs_arcsec']:.2f} +- {pitch['sd_arcsec']:.2f}" in row and row.split()[-1] == str(pitch["points"])
    assert fs.load_published("a-6-fpss1").summary == ""  # no fit, no Table 1


def test_acceptance_and_gap_are_typed(run_dir, tmp_path):
    d = tmp_path / "copy"
    shutil.copytree(run_dir, d)
    (d / "acceptance.json").write_text(json.dumps({
        "format": "fpss-stand acceptance/1", "verdict": "fail", "passed": False, "unit": "EMU-0001",
        "criteria": [{"id": "residual_max_pitch", "title": "max |residual| pitch", "axis": "pitch", "measured": 2.5,
                      "uncertainty": 0.1, "expanded_uncertainty": 0.2, "coverage_factor": 2.0, "dof_eff": None,
                      "budget": [{"source": "sensor noise", "type": "A", "sensitivity": 1.0, "u": 0.1, "dof": 9}],
                      "limit": 2.1, "acceptance_limit": 2.1, "relation": "<=", "unit": "arcsec", "outcome": "fail",
                      "outcome_reason": "", "passed": False,
                      "limit_key": "residual_max_arcsec", "source": "paper", "detail": ""}],
        "failed": ["residual_max_pitch"], "conditional": [], "decision_rule": {"rule": "simple"},
        "calibration_uncertainty": {"pitch": {"expanded_uncertainty_max_arcsec": 0.04}},
        "points": [], "new_key": 1}))
    (d / "GAP.json").write_text(json.dumps({"verdict": "explained", "verdict_sentence": "Explained.",
                                            "cause": "time_skew", "gap_before_arcsec": 9.7, "warnings": ["w"]}))
    r = fs.open_run(d)
    a = r.acceptance
    assert a.verdict == "fail" and not a.passed and a.failed == ("residual_max_pitch",)
    assert a.criteria[0].measured == 2.5 and a.criteria[0].limit == 2.1 and a.extra == {"new_key": 1}
    c = a.criteria[0]
    assert c.expanded_uncertainty == 0.2 and c.coverage_factor == 2.0 and c.outcome == "fail" and c.extra == {}
    assert c.budget[0]["source"] == "sensor noise" and a.decision_rule == {"rule": "simple"} and a.conditional == ()
    assert a.calibration_uncertainty["pitch"]["expanded_uncertainty_max_arcsec"] == 0.04
    g = r.gap
    assert g.verdict == "explained" and g.cause == "time_skew" and g.gap_before_arcsec == 9.7 and g.warnings == ("w",)
    (d / "GAP.json").write_text('{"verdict": "explained", "verdict": "x"}')
    r = fs.open_run(d)
    with pytest.raises(fs.InputError, match="GAP.json"):
        r.gap


def test_not_a_run_folder_or_a_torn_file_names_the_file(run_dir, tmp_path):
    with pytest.raises(fs.InputError, match="run.json"):
        fs.open_run(tmp_path)
    with pytest.raises(fs.InputError, match="no such folder"):
        fs.open_run(tmp_path / "nowhere")
    d = tmp_path / "torn"
    shutil.copytree(run_dir, d)
    text = (d / "run.json").read_text()
    (d / "run.json").write_text(text[: len(text) // 2])
    with pytest.raises(fs.InputError, match=r"torn/run\.json"):
        fs.open_run(d)
    (d / "run.json").write_text(text)
    # A torn events line in the middle is an error naming the file and line; a last line cut short is left out.
    lines = (d / "events.jsonl").read_text().splitlines(keepends=True)
    (d / "events.jsonl").write_text("".join(lines) + lines[1][:20])
    assert len(fs.open_run(d).events) == len(lines)
    (d / "events.jsonl").write_text("".join(lines[:2]) + lines[2][:20] + "\n" + "".join(lines[3:]))
    with pytest.raises(fs.InputError, match=r"events\.jsonl:3"):
        fs.open_run(d).events
    # A key of the wrong type in run.json names the key.
    doc = json.loads(text)
    doc["points"]["total"] = "many"
    (d / "run.json").write_text(json.dumps(doc))
    with pytest.raises(fs.InputError, match="points.total"):
        fs.open_run(d)


def test_a_multi_unit_run_gives_samples_per_unit(fpss, short_calibration, source_dir, tmp_path):
    """A run of two units on one gimbal (`run --emulate --bench procedures/two_unit_bench.yaml`)."""
    runs = tmp_path / "runs"
    fpss("run", short_calibration, "--emulate", "--bench", os.path.join(source_dir, "procedures", "two_unit_bench.yaml"),
         "--speed", 100, "--runs-dir", runs, "--quiet", "--no-progress")
    (d,) = [p for p in runs.iterdir() if (p / "run.json").exists()]
    r = fs.open_run(d)
    assert sorted(r.samples_by_unit) == ["FPSS1-A6", "FPSS2-A6"]
    for serial, df in r.samples_by_unit.items():
        assert len(df) == len(pd.read_csv(d / "units" / serial / "samples.csv"))
    assert [u["outcome"] for u in r.run_file.units] == ["completed", "completed"]
    assert r.run_file.units[1]["relative"]["to"] == "FPSS1-A6"
    assert len(r.points_by_unit["FPSS2-A6"]) == len(r.points_by_unit["FPSS1-A6"]) > 0
    with pytest.raises(fs.InputError, match="samples_by_unit"):
        r.samples
