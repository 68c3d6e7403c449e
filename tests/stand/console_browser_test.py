#!/usr/bin/python3
"""The web console in a real browser (headless Chromium via chromedriver and Selenium) against
`fpss-stand serve --emulate`: load, start procedures/discrete_grid.yaml, watch progress and the
chart, pause (progress stops for 2 s), resume, abort a second run (gimbal at null, run aborted),
open the report, and go through an acceptance answering its prompts. Any JavaScript console error
fails. Screenshots go to OUT_DIR (build/tests/console_browser/). Also writes OUT_DIR/latency.json:
point done (events.jsonl) to the residual chart drawn, ms, for docs/console.md.

usage: console_browser_test.py FPSS_STAND_BINARY OUT_DIR"""
import json
import math
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

BIN, OUT = sys.argv[1], sys.argv[2]
SRC = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
os.makedirs(OUT, exist_ok=True)


def wait_for(what, cond, timeout=60.0, step=0.1):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(step)
    raise AssertionError("timed out waiting for " + what)


# For the abort step: the full grid with dwells of 500 frames (10 s), about 1,800 s of bench time,
# 90 s of wall time at the console's speed-up: still running whenever the browser gets to Abort,
# however loaded the machine (the shipped grids run at their physical minimum, and a slow browser
# can be later than that).
LONG_GRID = open(os.path.join(SRC, "procedures", "full_grid.yaml")).read().replace(
    "name: full_grid", "name: long_grid").replace("frames: 10", "frames: 500")


def procedures_folder(tmp):
    """The shipped procedures and the long grid, for the console's start page."""
    folder = os.path.join(tmp, "procedures")
    os.makedirs(folder)
    for name in os.listdir(os.path.join(SRC, "procedures")):
        if name.endswith(".yaml"):
            shutil.copy(os.path.join(SRC, "procedures", name), folder)
    with open(os.path.join(folder, "long_grid.yaml"), "w") as f:
        f.write(LONG_GRID)
    return folder


class Console:
    def __init__(self, runs, procedures):
        self.runs = runs
        self.proc = subprocess.Popen([BIN, "serve", "--emulate", "--runs-dir", runs, "--listen", "127.0.0.1:0",
                                      "--procedures", procedures],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        first = self.proc.stdout.readline()
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", first)
        assert m, "serve did not print its address: " + first
        self.url = "http://127.0.0.1:%s/" % m.group(1)
        second = self.proc.stdout.readline()
        m = re.search(r"#token=([0-9a-f]+)", self.proc.stdout.readline() + second)
        assert m, "serve did not print the token once"
        self.token = m.group(1)

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait(timeout=20)


def run_dir(runs, run_id):
    """The folder whose run.json names run_id (the catalogue's UUIDv7; folders keep readable names)."""
    for name in os.listdir(runs):
        path = os.path.join(runs, name, "run.json")
        if os.path.isfile(path):
            with open(path) as f:
                if json.load(f).get("run_id") == run_id:
                    return os.path.join(runs, name)
    return os.path.join(runs, run_id)


def run_json(runs, run_id):
    with open(os.path.join(run_dir(runs, run_id), "run.json")) as f:
        return json.load(f)


class Browser:
    """Headless Chromium on the console, with the helpers every step uses."""

    def __init__(self, console):
        self.console = console
        self.runs = console.runs
        opts = Options()
        for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                  "--window-size=1280,1400"):
            opts.add_argument(a)
        opts.binary_location = "/usr/bin/chromium"
        opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        self.driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
        self.errors = []

    def check_console(self):
        for e in self.driver.get_log("browser"):
            if e["level"] == "SEVERE":
                self.errors.append(e["message"])
        assert not self.errors, "JavaScript console errors: %s" % self.errors

    def shot(self, name):
        self.driver.save_screenshot(os.path.join(OUT, name + ".png"))
        self.check_console()

    def go(self, where):
        self.driver.get(self.console.url + where)

    def text(self, i):
        return self.driver.find_element(By.ID, i).text

    def click(self, i):
        self.driver.find_element(By.ID, i).click()

    def fetch(self, path):
        return self.driver.execute_script("return fetch('%s').then(r => r.json())" % path)

    def progress(self):
        m = re.match(r"(\d+) / (\d+)", self.text("live-progress-text"))
        return int(m.group(1)) if m else -1

    def queue(self, kind, procedure, unit, operator):
        d = self.driver
        self.go("index.html#start")
        wait_for("procedures", lambda: len(Select(d.find_element(By.ID, "start-procedure")).options) > 0)
        Select(d.find_element(By.ID, "start-kind")).select_by_value(kind)
        if procedure:
            Select(d.find_element(By.ID, "start-procedure")).select_by_visible_text(procedure)
        for field, value in (("start-unit", unit), ("start-operator", operator)):
            d.find_element(By.ID, field).clear()
            d.find_element(By.ID, field).send_keys(value)
        before = self.text("start-message")  # an earlier submission's "queued job N"
        self.click("start-submit")
        m = wait_for("the job queued", lambda: self.text("start-message") != before
                     and re.search(r"queued job (\d+)", self.text("start-message")))
        return int(m.group(1))

    def watch(self, job):
        """Opens the live page of job's run once it exists; returns the run id."""
        self.go("index.html#live")
        run = wait_for("job %d's run" % job, lambda: self.fetch("/api/jobs/%d" % job).get("run_id"), timeout=60)
        self.go("index.html#live/" + run)
        return run

    def answer(self, expect, value=None, yes=False):
        d = self.driver
        wait_for("prompt: " + expect, lambda: d.find_element(By.ID, "prompt-box").is_displayed()
                 and expect in self.text("prompt-text"))
        if yes:
            self.click("prompt-yes")
        else:
            box = d.find_element(By.ID, "prompt-input")
            box.clear()
            box.send_keys(value)
            self.click("prompt-send")
        wait_for("prompt answered", lambda: not d.find_element(By.ID, "prompt-box").is_displayed()
                 or expect not in self.text("prompt-text") or self.text("prompt-note"))


def first_run(b):
    """Steps 1-5: load, start discrete_grid.yaml, progress and chart, pause 2 s, resume, completion."""
    b.go("#token=" + b.console.token)  # the token arrives in the URL's fragment, as serve prints it
    wait_for("the stand page", lambda: "emulated" in b.text("stand-table"))
    b.shot("1-stand")
    job = b.queue("run", "discrete_grid.yaml", "FPSS-B1", "Browser Test")
    b.shot("2-start")
    run = b.watch(job)
    wait_for("progress", lambda: b.progress() >= 5)
    p1 = b.progress()
    wait_for("progress to advance", lambda: b.progress() > p1)
    b.click("btn-pause")
    wait_for("paused", lambda: b.text("live-state") == "paused")
    held = b.progress()
    time.sleep(2.0)
    assert b.progress() == held, "progress moved while paused: %d -> %d" % (held, b.progress())
    assert '"paused"' in open(os.path.join(run_dir(b.runs, run), "events.jsonl")).read()
    b.shot("4-paused")
    b.click("btn-resume")
    wait_for("progress after resume", lambda: b.progress() > held)
    wait_for("points on the chart",
             lambda: int(b.driver.find_element(By.ID, "chart-residual").get_attribute("data-points") or 0) >= 3)
    b.shot("3-5-running-chart")
    wait_for("run 1 completed", lambda: b.text("live-state") == "completed", timeout=120)
    # The streaming fit's residual and its uncertainty (published with the last point at least).
    fit = wait_for("the live fit's 1-sigma", lambda: re.search(r"1-sigma ([0-9.]+) / ([0-9.]+)", b.text("live-fit")))
    assert 0 < float(fit.group(1)) < 1 and 0 < float(fit.group(2)) < 1, b.text("live-fit")
    wait_for("the report link", lambda: b.driver.find_element(By.ID, "live-report").is_displayed(), timeout=60)
    b.shot("5-completed")
    return run, b.driver.execute_script("return window.fpssLatencies")


def aborted_run(b):
    """Step 6: the stand page during a run; abort: the gimbal is at null and the run is marked aborted."""
    # The long grid (LONG_GRID), and the stand page looked at first, with the run still running.
    run = b.watch(b.queue("run", "long_grid.yaml", "FPSS-B2", "Browser Test"))
    b.go("index.html#stand")
    wait_for("the stand page live", lambda: "connected" in b.text("stand-table") and "point" in b.text("stand-table"))
    b.shot("6-stand-live")
    b.go("index.html#live/" + run)
    wait_for("run 2 progress", lambda: b.progress() >= 3)
    assert b.text("live-state") == "running", "run 2 ended before Abort: " + b.text("live-state")
    b.click("btn-abort")
    wait_for("aborted", lambda: b.text("live-state") == "aborted", timeout=60)
    assert b.driver.find_element(By.ID, "live-state").get_attribute("data-safe") == "true", "gimbal not at null"
    doc = wait_for("run.json's outcome",
                   lambda: (lambda d: d if d.get("outcome") != "running" else None)(run_json(b.runs, run)))
    assert doc["stop_cause"] == "aborted" and doc["safe_state"] is True, doc
    lines = open(os.path.join(run_dir(b.runs, run), "events.jsonl")).read().splitlines()
    stopped = [json.loads(x) for x in lines if '"run_stopped"' in x][-1]
    assert stopped["cause"] == "aborted" and stopped["safe_state"] is True
    b.go("index.html#runs")
    wait_for("aborted in the runs list", lambda: "aborted" in b.text("runs-table"))
    b.shot("6-aborted")


def open_report(b, run):
    """Step 7: the run's page links its report, which opens."""
    b.go("index.html#runs/" + run)
    link = wait_for("the report link", lambda: [a for a in b.driver.find_elements(By.CSS_SELECTOR, "a.run-file")
                                                if a.text == "report"])
    b.shot("7-run")
    b.driver.get(link[0].get_attribute("href"))
    wait_for("the report page", lambda: "calibration" in b.driver.page_source.lower())
    assert run in b.driver.page_source or "FPSS-B1" in b.driver.page_source
    b.shot("7-report")


def several_units(b):
    """Step 7b: a run of two units on one gimbal (the command line, into the console's runs folder):
    the run's page lists each unit with its outcome and its own files."""
    src = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    subprocess.run([BIN, "run", os.path.join(src, "procedures", "discrete_grid.yaml"), "--emulate", "--bench",
                    os.path.join(src, "procedures", "two_unit_bench.yaml"), "--speed", "100", "--runs-dir", b.runs,
                    "--quiet", "--no-progress"], check=True, capture_output=True, timeout=300)
    run = [r for r in b.fetch("/api/runs") if "FPSS2-A6" in r["unit"]][0]["run_id"]
    b.go("index.html#runs/" + run)
    rows = wait_for("the units of the run", lambda: b.driver.find_elements(By.CSS_SELECTOR, "#run-units tr.run-unit"))
    assert len(rows) == 2 and "FPSS2-A6" in rows[1].text and "completed" in rows[1].text, [r.text for r in rows]
    links = rows[1].find_elements(By.CSS_SELECTOR, "a.run-file")
    assert any(a.text == "report" and "/units/FPSS2-A6/report.html" in a.get_attribute("href") for a in links)
    b.shot("7b-units")


def investigations(b):
    """Step 10: an investigation of this runs folder (the command line, one run) is listed on the
    Investigations page with why it stopped and its run, and its report opens."""
    src = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    subprocess.run([BIN, "investigate", "--model", os.path.join(src, "calib", "data", "published", "a-6-fpss1.json"),
                    "--emulate", "--speed", "100", "--max-runs", "1", "--procedure",
                    os.path.join(src, "procedures", "discrete_grid.yaml"), "--runs-dir", b.runs, "--quiet"],
                   check=True, capture_output=True, timeout=300)
    b.go("index.html#investigations")
    rows = wait_for("the investigation's row", lambda: b.driver.find_elements(By.CSS_SELECTOR, "#investigations-table tr.investigation"))
    assert len(rows) == 1 and "investigation-" in rows[0].text, [r.text for r in rows]
    run_links = rows[0].find_elements(By.CSS_SELECTOR, "a[href^='#runs/']")
    assert len(run_links) == 1, rows[0].text
    link = rows[0].find_element(By.CSS_SELECTOR, "a.investigation-report").get_attribute("href")
    b.shot("10-investigations")
    b.driver.get(link)
    wait_for("the investigation's report", lambda: "Sim-to-real investigation" in b.driver.page_source)
    b.shot("10-investigation-report")


def acceptance(b):
    """Step 8: an acceptance answering its prompts (a wrong serial first); then the unit's history."""
    job = b.queue("accept", "", "FPSS-B1", "")
    run = b.watch(job)
    b.answer("serial", "FPSS-WRONG")
    wait_for("the wrong serial refused", lambda: "not" in b.text("prompt-note"))
    b.shot("8-serial-refused")
    b.answer("serial", "FPSS-B1")
    b.answer("lamp", yes=True)
    b.answer("name", "Ada Operator")
    wait_for("acceptance run completed", lambda: b.text("live-state") == "completed", timeout=120)
    done = wait_for("the acceptance's exit", lambda: (lambda j: j if j["state"] == "finished" else None)(
        b.fetch("/api/jobs/%d" % job)), timeout=60)
    assert done["exit_code"] == 0, done
    cert = json.load(open(os.path.join(run_dir(b.runs, run), "acceptance.json")))
    assert cert["operator"] == "Ada Operator" and cert["signed_off_utc"], cert
    assert "Ada Operator" in open(os.path.join(run_dir(b.runs, run), "certificate.txt")).read()
    hist = b.fetch("/api/units/FPSS-B1/history")
    assert any(a["operator"] == "Ada Operator" and a["passed"] for a in hist["acceptances"]), hist
    b.shot("8-acceptance")
    # two calibrations of the unit (run 1 and the acceptance) and their difference over the field
    b.go("index.html#units")
    wait_for("the unit's calibrations", lambda: len(b.driver.find_elements(By.CSS_SELECTOR, "#unit-table tr")) >= 3)
    assert "pass Ada Operator" in b.text("unit-table")
    b.click("cmp-go")
    wait_for("the difference B - A", lambda: "alpha: max" in b.text("cmp-summary"))
    assert len(b.driver.find_elements(By.CSS_SELECTOR, "#chart-compare canvas")) == 2
    b.shot("9-unit-history")
    return run


def fleet(b, acceptance_run):
    """Step 9: the fleet page: each stand's last run, each unit's latest verdict, the last MSA.

    The MSA file is written here (a crossed study needs several stands: tests/stand/msa_fleet_test.cpp
    makes a real one); the page must show what the newest file of RUNS_DIR/msa/ says."""
    os.makedirs(os.path.join(b.runs, "msa"), exist_ok=True)
    with open(os.path.join(b.runs, "msa", "fleet-2026-11.json"), "w") as f:
        json.dump({"format": "fpss-stand msa/1", "units": ["SN-1", "SN-2"], "stands": ["stand-A", "stand-B"], "repeats": 2,
                   "quantities": {"angle_pitch_at_+0.4deg_arcsec": {"grr_percent_tolerance": 9.63, "grr_percent_tv": 0.41,
                                                                     "ndc": 300, "verdict": "acceptable"}}}, f)
    b.go("index.html#fleet")
    wait_for("the stand's last run", lambda: acceptance_run in b.text("fleet-stands"))
    assert "emulator" in b.text("fleet-stands")  # an emulated run without a stand file
    wait_for("the unit's verdict", lambda: "FPSS-B1 pass" in b.text("fleet-units"))
    wait_for("the last MSA", lambda: "angle_pitch_at_+0.4deg_arcsec 9.6 0.4 300 acceptable" in b.text("fleet-msa"))
    assert "2 units x 2 stands (stand-A, stand-B) x 2 repeats" in b.text("fleet-msa-note")
    api = b.fetch("/api/fleet")
    assert api["msa"]["file"] == "fleet-2026-11.json", api
    b.shot("10-fleet")


def stop_runs(runs):
    """Runs outlive their console by design: a failed test must not leave its runs behind, so each
    run process still alive (run.json's pid) is sent SIGTERM (it returns the gimbal to null and stops
    its emulator child)."""
    for name in os.listdir(runs) if os.path.isdir(runs) else []:
        try:
            with open(os.path.join(runs, name, "run.json")) as f:
                doc = json.load(f)
        except (OSError, ValueError):
            continue
        pid = (doc.get("sessions") or [{}])[-1].get("pid")
        if doc.get("outcome") == "running" and isinstance(pid, int) and pid > 0:
            try:
                os.kill(pid, signal.SIGTERM)
            except OSError:
                pass


def main():
    tmp = tempfile.mkdtemp(prefix="fpss-console-browser-")
    console = Console(os.path.join(tmp, "runs"), procedures_folder(tmp))
    b = Browser(console)
    t0 = time.monotonic()
    try:
        run1, lat = first_run(b)
        aborted_run(b)
        open_report(b, run1)
        several_units(b)
        acc_run = acceptance(b)
        fleet(b, acc_run)
        investigations(b)
        b.check_console()
    except BaseException:
        b.driver.save_screenshot(os.path.join(OUT, "failure.png"))
        with open(os.path.join(OUT, "failure.html"), "w") as f:
            f.write(b.driver.page_source)
        raise
    finally:
        b.driver.quit()
        console.stop()
        stop_runs(os.path.join(tmp, "runs"))
    lat = sorted(x for x in (lat or []) if x is not None)
    out = {"points": len(lat), "median_ms": statistics.median(lat) if lat else None,
           "p99_ms": lat[math.ceil(0.99 * len(lat)) - 1] if lat else None, "all_ms": lat,
           "wall_s": time.monotonic() - t0}
    with open(os.path.join(OUT, "latency.json"), "w") as f:
        json.dump(out, f, indent=1)
    print("point done -> chart: %d points, median %s ms, p99 (nearest rank) %s ms; test wall %.1f s" %
          (out["points"], out["median_ms"], out["p99_ms"], out["wall_s"]))
    assert lat, "no point reached the chart"
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
