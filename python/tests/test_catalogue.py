"""Catalogue(URL) on a real SQLite catalogue made by the command: a run and a unit's history."""
import pytest

import fpss_stand as fs
from pg_server import PgServer

SHORT_GRID = """name: short_grid
description: a short null-to-offset grid (no fit), for the Python package's tests
steps:
  - home
  - null_offset_grid:
      axes: [pitch, yaw]
      extent_deg: 0.06
      step_deg: 0.03
      settle_s: 0.2
      frames: 3
      order: outward
"""


@pytest.fixture(scope="module")
def catalogue(fpss, source_dir, tmp_path_factory):
    d = tmp_path_factory.mktemp("catalogue")
    proc = d / "short_grid.yaml"
    proc.write_text(SHORT_GRID)
    runs = d / "runs"
    fpss("run", proc, "--emulate", "--runs-dir", runs, "--quiet", "--no-progress")
    pub = f"{source_dir}/calib/data/published"
    fpss("import", f"{pub}/a-5-fpss1.json", "--unit", "EMU-0001", "--date", "1980-06-01", "--runs-dir", runs)
    fpss("import", f"{pub}/a-6-fpss1.json", "--unit", "EMU-0001", "--date", "1980-09-01", "--runs-dir", runs)
    return runs / "stand.db"


def test_runs_and_history(catalogue):
    for url in (str(catalogue), f"sqlite:{catalogue}"):
        cat = fs.Catalogue(url)
        assert cat.backend == "sqlite"
        runs = cat.runs()
        assert len(runs) == 1
        run = runs.iloc[0]
        assert run["procedure"] == "short_grid" and run["outcome"] == "completed" and run["emulated"]
        assert cat.run(run["run_id"])["unit"] == run["unit"]
        assert cat.run("no-such-run") is None
        h = cat.history("EMU-0001")
        assert list(h["date_utc"].str[:10]) == ["1980-06-01", "1980-09-01"]
        assert list(h["source"]) == ["import", "import"]
        assert h.iloc[1]["coefficients"]["alpha"] == fs.load_published("a-6-fpss1").json["alpha"]
        assert cat.history("NOBODY").empty
        assert "EMU-0001" in cat.units()


def test_a_bad_url_is_an_error_naming_it(tmp_path):
    with pytest.raises(Exception, match="nowhere"):
        fs.Catalogue(str(tmp_path / "nowhere" / "stand.db"))


@pytest.fixture(scope="module")
def postgres(fpss, catalogue):
    """A PostgreSQL catalogue holding what the SQLite one holds (`fpss-stand catalogue copy`)."""
    server = PgServer()
    try:
        fpss("catalogue", "copy", "--from", f"sqlite:{catalogue}", "--to", server.url)
        yield server.url
    finally:
        server.stop()


def test_postgresql_holds_the_same_runs_and_history(catalogue, postgres):
    lite, pg = fs.Catalogue(str(catalogue)), fs.Catalogue(postgres)
    assert pg.backend == "postgresql" and "fpss@127.0.0.1" in pg.location
    keys = ["run_id", "unit", "procedure", "started_utc", "ended_utc", "outcome"]
    assert pg.runs()[keys].to_dict("records") == lite.runs()[keys].to_dict("records")
    keys = ["unit", "source", "date_utc", "method", "label", "coefficients"]
    assert pg.history("EMU-0001")[keys].to_dict("records") == lite.history("EMU-0001")[keys].to_dict("records")
