"""Console(URL, token) against a real `fpss-stand serve --emulate` on a free loopback port: queue a
run, follow its events to the end, read the run back; pause, resume and abort a second one. Every
wait is on a condition with a deadline."""
import queue
import signal
import subprocess
import threading
import time

import pytest

import fpss_stand as fs

# Long enough (1000 frames a dwell: about 25 s at --speed 100) that it is still running while the test pauses, resumes and aborts it.
LONG_GRID = """name: long_grid
description: a long null-to-offset grid (no fit), for the Python package's console test
steps:
  - home
  - null_offset_grid:
      axes: [pitch, yaw]
      extent_deg: 0.42
      step_deg: 0.03
      settle_s: 0.5
      frames: 1000
      order: outward
"""


def _first_line(stream, timeout_s):
    q = queue.Queue()
    threading.Thread(target=lambda: q.put(stream.readline()), daemon=True).start()
    try:
        return q.get(timeout=timeout_s)
    except queue.Empty:
        return ""


@pytest.fixture(scope="module")
def console(fpss, short_calibration, tmp_path_factory):
    """(Console, runs folder) of `fpss-stand serve --emulate` on 127.0.0.1, port 0 (a free one)."""
    d = tmp_path_factory.mktemp("console")
    procs = d / "procedures"
    procs.mkdir()
    (procs / "short_calibration.yaml").write_text(short_calibration.read_text())
    (procs / "long_grid.yaml").write_text(LONG_GRID)
    runs = d / "runs"
    err = open(d / "serve.err", "w")
    serve = subprocess.Popen([fpss.binary, "serve", "--emulate", "--speed", "100", "--runs-dir", str(runs),
                              "--listen", "127.0.0.1:0", "--procedures", str(procs)],
                             stdout=subprocess.PIPE, stderr=err, text=True)
    try:
        banner = _first_line(serve.stdout, 30)
        assert "console at http://127.0.0.1:" in banner, f"serve said {banner!r}: {(d / 'serve.err').read_text()}"
        url = banner.split("console at ", 1)[1].split()[0]
        c = fs.Console(url, token_file=runs / "console.token")
        yield c, runs
        try:  # a test that failed half-way leaves no run behind: abort it and wait for it to end
            for run_id in c.status()["live_runs"]:
                c.abort(run_id)
            deadline = time.monotonic() + 30
            while c.status()["live_runs"] and time.monotonic() < deadline:
                time.sleep(0.1)
        except fs.ConsoleError:
            pass
    finally:
        serve.send_signal(signal.SIGTERM)
        try:
            serve.wait(20)
        except subprocess.TimeoutExpired:
            serve.kill()
            serve.wait(5)
        err.close()


def test_queue_follow_and_read_a_run(console):
    c, runs = console
    assert c.status()["emulate"] is True
    job = c.queue("short_calibration.yaml", "EMU-PY1", operator="pytest")
    assert job["state"] == "queued"
    run_id = c.wait_for_run(job["id"], timeout_s=60)
    events = list(c.events(run_id, timeout_s=120))
    types = [e["type"] for e in events]
    assert types[0] == "run_started" and types[-1] == "run_stopped", types[-5:]
    assert events[-1]["outcome"] == "completed" and events[-1]["cause"] == "none"
    done = [e for e in events if e["type"] == "point_done"]
    assert len(done) == events[0]["points_total"] == events[-1]["points_done"]
    assert c.wait_for_job(job["id"], timeout_s=60)["exit_code"] == 0
    # The run read back: the API's answer, and open_run on its folder (from the catalogue).
    assert c.run(run_id)["outcome"] == "completed"
    rows = c.runs(unit="EMU-PY1")
    assert list(rows["run_id"]) == [run_id]
    folder = fs.Catalogue(runs / "stand.db").run(run_id)["run_dir"]
    r = fs.open_run(folder)
    assert r.run_id == run_id and r.outcome == "completed" and r.run_file.operator == "pytest"
    assert r.run_file.points.completed == r.run_file.points.total == len(done)
    assert list(r.points["point"]) == [e["point"] for e in done]
    assert r.event_lines == events  # the API's lines, typed, are the folder's lines, typed
    assert r.calibration is not None
    # Following again from an iterator's offset misses no line: mid-chunk, the chunk's start; at the end, nothing.
    it = c.events(run_id)
    first = next(it)
    assert first == events[0] and list(c.events(run_id, start=it.offset)) == events
    assert list(it) == events[1:] and list(c.events(run_id, start=it.offset)) == []


def test_pause_resume_and_abort(console):
    c, _ = console
    job = c.queue("long_grid.yaml", "EMU-PY2")
    run_id = c.wait_for_run(job["id"], timeout_s=60)
    seen = []
    it = c.events(run_id, poll_s=0.05, timeout_s=120)

    def until(pred):
        for e in it:
            seen.append(e)
            if pred(e):
                return e
        pytest.fail(f"the stream ended before: {[e['type'] for e in seen[-5:]]}")

    until(lambda e: e["type"] == "point_done")
    assert c.pause(run_id)["accepted"] is True
    paused = until(lambda e: e["type"] == "paused")
    assert c.resume(run_id)["accepted"] is True
    resumed = until(lambda e: e["type"] == "resumed")
    assert resumed["next_point"] == paused["next_point"]
    assert c.abort(run_id)["accepted"] is True
    stop = until(lambda e: e["type"] == "run_stopped")
    assert stop["outcome"] == "interrupted" and stop["cause"] == "aborted" and stop["safe_state"] is True
    assert list(it) == []  # the iterator ends once the run has ended and everything is read
    assert c.wait_for_job(job["id"], timeout_s=60)["state"] == "finished"
    with pytest.raises(fs.ConsoleError, match="409") as e:
        c.pause(run_id)
    assert e.value.status == 409 and f"/api/runs/{run_id}/control" in str(e.value)


def test_an_investigation_is_queued_and_read_back(console):
    c, runs = console
    job = c.queue("short_calibration.yaml", "", kind="investigate", model="a-6-fpss1")
    name = job["investigation"]
    assert name.startswith("investigation-") and name.endswith("-job%d" % job["id"])
    done = c.wait_for_job(job["id"], timeout_s=240)
    assert done["exit_code"] == 0, done
    listed = [i for i in c.investigations() if i["name"] == name]
    assert len(listed) == 1
    record = c.investigation(name)
    assert record["verdict"] == listed[0]["verdict"]
    assert [r.split("/")[-1] for r in record["runs"]] == listed[0]["runs"]
    assert record["steps"][0]["why"] == "the first run"
    assert (runs / name / "INVESTIGATION.html").is_file()
    frame = c.investigations(as_frame=True)
    assert name in set(frame["name"])
    with pytest.raises(ValueError):
        c.investigation("../stand.db")


def test_errors_name_the_url_and_status(console):
    c, _ = console
    with pytest.raises(fs.ConsoleError, match=r"404.*no such run|/api/runs/nothing.*404"):
        c.run("nothing")
    unauthorised = fs.Console(c.url, "0" * 64)
    with pytest.raises(fs.ConsoleError, match="401") as e:
        unauthorised.queue("short_calibration.yaml", "EMU-PY3")
    assert e.value.url == c.url + "/api/jobs"
    with pytest.raises(fs.ConsoleError, match="no answer"):
        fs.Console("http://127.0.0.1:9", timeout_s=2).status()
    with pytest.raises(ValueError):
        c.run("../x")
