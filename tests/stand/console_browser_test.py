#!/usr/bin/python3
"""The web console in a real browser (headless Chromium via chromedriver and Selenium) against
`fpss-stand serve --emulate`: load, start procedures/discrete_grid.yaml, watch progress and the
chart, pause (progress stops for 2 s), resume, abort a second run (gimbal at null, run aborted),
open the report, and go through an acceptance answering its prompts. Any JavaScript console error
fails. Screenshots go to OUT_DIR (build/tests/console_browser/). Also writes OUT_DIR/latency.json:
point done (events.jsonl) to the residual chart drawn, ms, for docs/console.md.

usage: console_browser_test.py FPSS_STAND_BINARY OUT_DIR"""
import json
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
os.makedirs(OUT, exist_ok=True)


def wait_for(what, cond, timeout=60.0, step=0.1):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(step)
    raise AssertionError("timed out waiting for " + what)


class Console:
    def __init__(self, runs):
        self.runs = runs
        self.proc = subprocess.Popen([BIN, "serve", "--emulate", "--runs-dir", runs, "--listen", "127.0.0.1:0"],
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


def run_json(runs, run_id):
    with open(os.path.join(runs, run_id, "run.json")) as f:
        return json.load(f)


def main():
    tmp = tempfile.mkdtemp(prefix="fpss-console-browser-")
    runs = os.path.join(tmp, "runs")
    console = Console(runs)
    opts = Options()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1280,1400"):
        opts.add_argument(a)
    opts.binary_location = "/usr/bin/chromium"
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
    errors = []

    def check_console():
        for e in driver.get_log("browser"):
            if e["level"] == "SEVERE":
                errors.append(e["message"])
        assert not errors, "JavaScript console errors: %s" % errors

    def shot(name):
        driver.save_screenshot(os.path.join(OUT, name + ".png"))
        check_console()

    def text(i):
        return driver.find_element(By.ID, i).text

    def progress():
        m = re.match(r"(\d+) / (\d+)", text("live-progress-text"))
        return int(m.group(1)) if m else -1

    def queue(kind, procedure, unit, operator):
        driver.get(console.url + "index.html#start")
        wait_for("procedures", lambda: len(Select(driver.find_element(By.ID, "start-procedure")).options) > 0)
        Select(driver.find_element(By.ID, "start-kind")).select_by_value(kind)
        if procedure:
            Select(driver.find_element(By.ID, "start-procedure")).select_by_visible_text(procedure)
        driver.find_element(By.ID, "start-unit").send_keys(unit)
        driver.find_element(By.ID, "start-operator").send_keys(operator)
        driver.find_element(By.ID, "start-submit").click()
        m = wait_for("the job queued", lambda: re.search(r"queued job (\d+)", text("start-message")))
        return int(m.group(1))

    def live_run_of(job):
        driver.get(console.url + "index.html#live")
        return wait_for("job %d's run" % job, lambda: driver.execute_script(
            "return fetch('/api/jobs/%d').then(r => r.json()).then(j => j.run_id)" % job), timeout=60)

    t0 = time.monotonic()
    try:
        # 1. load the console (the token arrives in the URL's fragment, as serve prints it)
        driver.get(console.url + "#token=" + console.token)
        wait_for("the stand page", lambda: "emulated" in text("stand-table"))
        shot("1-stand")
        # 2. start procedures/discrete_grid.yaml
        job1 = queue("run", "discrete_grid.yaml", "FPSS-B1", "Browser Test")
        shot("2-start")
        run1 = live_run_of(job1)
        driver.get(console.url + "index.html#live/" + run1)
        # 3. progress advances and points appear on the chart
        wait_for("progress", lambda: progress() >= 5)
        p1 = progress()
        wait_for("progress to advance", lambda: progress() > p1)
        # 4. pause: progress stops for 2 s
        driver.find_element(By.ID, "btn-pause").click()
        wait_for("paused", lambda: text("live-state") == "paused")
        held = progress()
        time.sleep(2.0)
        assert progress() == held, "progress moved while paused: %d -> %d" % (held, progress())
        ev = os.path.join(runs, run1, "events.jsonl")
        assert "\"paused\"" in open(ev).read()
        shot("4-paused")
        # 5. resume
        driver.find_element(By.ID, "btn-resume").click()
        wait_for("progress after resume", lambda: progress() > held)
        wait_for("points on the chart", lambda: int(driver.find_element(By.ID, "chart-residual").get_attribute("data-points") or 0) >= 3)
        shot("3-5-running-chart")
        wait_for("run 1 completed", lambda: text("live-state") == "completed", timeout=120)
        wait_for("the report link", lambda: driver.find_element(By.ID, "live-report").is_displayed(), timeout=60)
        shot("5-completed")
        lat = driver.execute_script("return window.fpssLatencies")
        # 6. abort a second run: the gimbal is at null and the run is marked aborted
        job2 = queue("run", "discrete_grid.yaml", "FPSS-B2", "Browser Test")
        run2 = live_run_of(job2)
        driver.get(console.url + "index.html#live/" + run2)
        wait_for("run 2 progress", lambda: progress() >= 3)
        # the stand page while a run holds the bench: connected, position and stream health
        driver.get(console.url + "index.html#stand")
        wait_for("the stand page live", lambda: "connected" in text("stand-table") and "point" in text("stand-table"))
        shot("6-stand-live")
        driver.get(console.url + "index.html#live/" + run2)
        wait_for("run 2 progress again", lambda: progress() >= 3)
        driver.find_element(By.ID, "btn-abort").click()
        wait_for("aborted", lambda: text("live-state") == "aborted", timeout=60)
        st = driver.find_element(By.ID, "live-state")
        assert st.get_attribute("data-safe") == "true", "the gimbal was not returned to null"
        doc = wait_for("run.json's outcome", lambda: (lambda d: d if d.get("outcome") != "running" else None)(run_json(runs, run2)))
        assert doc["stop_cause"] == "aborted" and doc["safe_state"] is True, doc
        stopped = [json.loads(l) for l in open(os.path.join(runs, run2, "events.jsonl")) if '"run_stopped"' in l][-1]
        assert stopped["cause"] == "aborted" and stopped["safe_state"] is True
        driver.get(console.url + "index.html#runs")
        wait_for("aborted in the runs list", lambda: "aborted" in text("runs-table"))
        shot("6-aborted")
        # 7. open the report
        driver.get(console.url + "index.html#runs/" + run1)
        link = wait_for("the report link", lambda: [a for a in driver.find_elements(By.CSS_SELECTOR, "a.run-file") if a.text == "report"])
        shot("7-run")
        driver.get(link[0].get_attribute("href"))
        wait_for("the report page", lambda: "calibration" in driver.page_source.lower())
        assert run1 in driver.page_source or "FPSS-B1" in driver.page_source
        shot("7-report")
        # 8. an acceptance, answering the prompts
        job3 = queue("accept", "", "FPSS-B1", "")
        run3 = live_run_of(job3)
        driver.get(console.url + "index.html#live/" + run3)

        def answer(expect, value=None, yes=False):
            wait_for("prompt: " + expect, lambda: driver.find_element(By.ID, "prompt-box").is_displayed()
                     and expect in text("prompt-text"))
            if yes:
                driver.find_element(By.ID, "prompt-yes").click()
            else:
                box = driver.find_element(By.ID, "prompt-input")
                box.clear()
                box.send_keys(value)
                driver.find_element(By.ID, "prompt-send").click()
            wait_for("prompt answered", lambda: not driver.find_element(By.ID, "prompt-box").is_displayed()
                     or expect not in text("prompt-text") or driver.find_element(By.ID, "prompt-note").text)

        answer("serial", "FPSS-WRONG")
        wait_for("the wrong serial refused", lambda: "not" in text("prompt-note"))
        shot("8-serial-refused")
        answer("serial", "FPSS-B1")
        answer("lamp", yes=True)
        answer("name", "Ada Operator")
        wait_for("acceptance run completed", lambda: text("live-state") == "completed", timeout=120)
        cert = wait_for("acceptance.json", lambda: os.path.exists(os.path.join(runs, run3, "acceptance.json"))
                        and json.load(open(os.path.join(runs, run3, "acceptance.json"))), timeout=60)
        assert cert["operator"] == "Ada Operator" and cert["signed_off_utc"], cert
        assert "Ada Operator" in open(os.path.join(runs, run3, "certificate.txt")).read()
        job = wait_for("the acceptance's exit", lambda: (lambda j: j if j["state"] == "finished" else None)(
            driver.execute_script("return fetch('/api/jobs/%d').then(r => r.json())" % job3)), timeout=60)
        assert job["exit_code"] == 0, job
        hist = driver.execute_script("return fetch('/api/units/FPSS-B1/history').then(r => r.json())")
        assert any(a["operator"] == "Ada Operator" and a["passed"] for a in hist["acceptances"]), hist
        shot("8-acceptance")
        # the unit's history: two calibrations (run 1 and the acceptance) and their difference
        driver.get(console.url + "index.html#units")
        wait_for("the unit's calibrations", lambda: len(driver.find_elements(By.CSS_SELECTOR, "#unit-table tr")) >= 3)
        assert "pass Ada Operator" in text("unit-table")
        driver.find_element(By.ID, "cmp-go").click()
        wait_for("the difference B - A", lambda: "alpha: max" in text("cmp-summary"))
        assert len(driver.find_elements(By.CSS_SELECTOR, "#chart-compare canvas")) == 2
        shot("9-unit-history")
        check_console()
    except BaseException:
        driver.save_screenshot(os.path.join(OUT, "failure.png"))
        with open(os.path.join(OUT, "failure.html"), "w") as f:
            f.write(driver.page_source)
        raise
    finally:
        driver.quit()
        console.stop()
    lat = [x for x in (lat or []) if x is not None]
    out = {"points": len(lat), "median_ms": statistics.median(lat) if lat else None,
           "p99_ms": sorted(lat)[max(0, int(len(lat) * 0.99) - 1)] if lat else None, "all_ms": lat,
           "wall_s": time.monotonic() - t0}
    with open(os.path.join(OUT, "latency.json"), "w") as f:
        json.dump(out, f, indent=1)
    print("point done -> chart: %d points, median %s ms, p99 %s ms; test wall %.1f s" %
          (out["points"], out["median_ms"], out["p99_ms"], out["wall_s"]))
    assert lat, "no point reached the chart"
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
