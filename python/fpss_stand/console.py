"""Console(URL, token): a client of `fpss-stand serve`'s JSON API (docs/console.md "JSON API").

Standard library only (urllib): every request has a timeout, every answer is read up to a bound,
and every failure is a ConsoleError naming the method, the URL and the HTTP status with the
console's own ``error`` text. Events come through the stand's typed event reader (the same typed
form as ``open_run(...).event_lines``).
"""
import json
import time
import urllib.error
import urllib.parse
import urllib.request

from . import _fpss_stand as _native

MAX_ANSWER_BYTES = 64 << 20  # an events chunk is at most 256 KiB of lines; a runs list of 5000 runs a few MB


class ConsoleError(ConnectionError):
    """A request to the console failed: ``url``, ``status`` (None when no HTTP answer came) and the
    console's ``error`` text when it gave one."""

    def __init__(self, message, url, status=None, error=None):
        super().__init__(message)
        self.url, self.status, self.error = url, status, error


class Console:
    """The web console of one stand (``fpss-stand serve``), e.g. ``Console("http://127.0.0.1:8080",
    token)``. ``token``: the console's token (RUNS_DIR/console.token), needed to queue and control
    runs, and for reads off loopback; None reads ``token_file`` when given. ``timeout_s`` bounds each
    request."""

    def __init__(self, url, token=None, *, token_file=None, timeout_s=10.0):
        if not url.startswith(("http://", "https://")):
            raise ValueError(f"Console: {url!r}: expected http://HOST:PORT")
        self.url = url.rstrip("/")
        if token is None and token_file is not None:
            with open(token_file, encoding="utf-8") as f:
                token = f.read(4096).strip()
        self.token = token
        self.timeout_s = float(timeout_s)

    # --- one request -----------------------------------------------------------------------------
    def _request(self, method, path, body=None, params=None):
        url = self.url + path
        if params:
            query = {k: v for k, v in params.items() if v is not None}
            if query:
                url += "?" + urllib.parse.urlencode(query)
        headers = {"Accept": "application/json"}
        data = None
        if body is not None:
            data = json.dumps(body).encode("utf-8")
            headers["Content-Type"] = "application/json"
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(url, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s) as resp:
                raw = resp.read(MAX_ANSWER_BYTES + 1)
                status = resp.status
        except urllib.error.HTTPError as e:
            raw = e.read(64 << 10)
            error = None
            try:
                error = json.loads(raw).get("error")
            except (ValueError, AttributeError):
                pass
            why = f": {error}" if error else (f": {e.reason}" if e.reason else "")
            raise ConsoleError(f"{method} {url}: HTTP {e.code}{why}", url, e.code, error) from None
        except (urllib.error.URLError, OSError) as e:
            reason = getattr(e, "reason", e)
            raise ConsoleError(f"{method} {url}: no answer from the console ({reason})", url) from None
        if len(raw) > MAX_ANSWER_BYTES:
            raise ConsoleError(f"{method} {url}: an answer longer than {MAX_ANSWER_BYTES} bytes", url, status)
        try:
            return json.loads(raw)
        except ValueError as e:
            raise ConsoleError(f"{method} {url}: HTTP {status} but not JSON ({e})", url, status) from None

    def _get(self, path, **params):
        return self._request("GET", path, params=params)

    def _post(self, path, body):
        return self._request("POST", path, body=body)

    @staticmethod
    def _name(x, what):
        x = str(x)
        if not x or any(not (c.isascii() and (c.isalnum() or c in "._-")) for c in x):
            raise ValueError(f"{what} {x!r}: expected a name of [A-Za-z0-9._-]")
        return x

    # --- reads -----------------------------------------------------------------------------------
    def status(self):
        """``{"live_runs", "jobs", "emulate", "reads_need_token", "version"}``."""
        return self._get("/api/status")

    def stand(self):
        return self._get("/api/stand")

    def procedures(self):
        return self._get("/api/procedures")

    def runs(self, unit=None, outcome=None, since=None, until=None, limit=None, as_frame=True):
        """The catalogue's runs, most recent first (``outcome`` also ``aborted`` or ``stale``;
        ``since``/``until``: YYYY-MM-DD). A DataFrame (``as_frame=False``: a list of dicts)."""
        rows = self._get("/api/runs", unit=unit, outcome=outcome, to=until, limit=limit, **{"from": since})
        if not as_frame:
            return rows
        import pandas as pd
        return pd.DataFrame(rows)

    def run(self, run_id):
        """run.json's key fields, ``live`` and ``files`` (links)."""
        return self._get(f"/api/runs/{self._name(run_id, 'run id')}")

    def investigations(self, as_frame=False):
        """The runs folder's sim-to-real investigations, most recent first: ``name``,
        ``stop_reason``, ``verdict`` (or ``no_diagnosis``, why none was made), ``cause``, ``causes``,
        ``ambiguous``, ``unbounded``, ``runs``
        (run ids), ``bench_time_s``, ``files`` (links). A list of dicts (``as_frame=True``: a
        DataFrame)."""
        rows = self._get("/api/investigations")
        if not as_frame:
            return rows
        import pandas as pd
        return pd.DataFrame(rows)

    def investigation(self, name):
        """An investigation's INVESTIGATION.json: ``runs``, ``steps`` and the final joint
        diagnosis in GAP.json's fields (``verdict``, ``cause``, ``causes``, ``effects``,
        ``ambiguous``)."""
        return self._get(f"/investigations/{self._name(name, 'investigation')}/INVESTIGATION.json")

    def jobs(self):
        return self._get("/api/jobs")

    def job(self, job_id):
        return self._get(f"/api/jobs/{int(job_id)}")

    # --- the queue -------------------------------------------------------------------------------
    def queue(self, procedure, unit, operator=None, kind="run", model=None):
        """Queues a run (``kind="accept"``: an acceptance; ``kind="investigate"``: an
        investigation, which needs ``model``, a published set's name such as ``"a-6-fpss1"``) of a
        procedure file the console offers; returns the job (``id``, ``state``; an investigation's
        ``investigation``, its folder's name)."""
        body = {"kind": kind, "procedure": procedure, "unit": unit}
        if operator is not None:
            body["operator"] = operator
        if model is not None:
            body["model"] = model
        return self._post("/api/jobs", body)

    def remove_job(self, job_id):
        return self._request("DELETE", f"/api/jobs/{int(job_id)}")

    def move_job(self, job_id, to):
        return self._post(f"/api/jobs/{int(job_id)}/move", {"to": int(to)})

    def wait_for_run(self, job_id, timeout_s=60.0, poll_s=0.2):
        """The run id of a queued job once its run folder exists (TimeoutError after timeout_s;
        ConsoleError when the job failed to start or ended without a run)."""
        deadline = time.monotonic() + timeout_s
        while True:
            j = self.job(job_id)
            if j.get("run_id"):
                return j["run_id"]
            if j.get("state") in ("failed_to_start", "finished"):
                raise ConsoleError(f"job {job_id}: {j.get('state')} without a run (exit code {j.get('exit_code')})",
                                   f"{self.url}/api/jobs/{int(job_id)}")
            if time.monotonic() > deadline:
                raise TimeoutError(f"job {job_id}: no run after {timeout_s} s (state {j.get('state')})")
            time.sleep(poll_s)

    def wait_for_job(self, job_id, timeout_s=300.0, poll_s=0.2):
        """The job once it has ended (``finished`` or ``failed_to_start``: ``exit_code``)."""
        deadline = time.monotonic() + timeout_s
        while True:
            j = self.job(job_id)
            if j.get("state") in ("finished", "failed_to_start"):
                return j
            if time.monotonic() > deadline:
                raise TimeoutError(f"job {job_id}: not ended after {timeout_s} s (state {j.get('state')})")
            time.sleep(poll_s)

    # --- a run's events --------------------------------------------------------------------------
    def events(self, run_id, start=0, poll_s=0.25, timeout_s=None):
        """An iterator over a run's events.jsonl lines as typed dicts (each checked by the stand's
        event reader: ``type``, ``utc`` and the type's keys, docs/formats.md), following the run while
        it is live: it polls ``/events?from=OFFSET`` and ends once the run has ended and every line is
        read. ``timeout_s``: TimeoutError when the run is still live after that long. Its ``offset``
        is where to start again without missing a line (a byte offset of events.jsonl)."""
        return RunEvents(self, self._name(run_id, "run id"), int(start), poll_s, timeout_s)

    # --- control ---------------------------------------------------------------------------------
    def _control(self, run_id, action):
        return self._post(f"/api/runs/{self._name(run_id, 'run id')}/control", {"action": action})

    def pause(self, run_id):
        """Pauses a live run between points (ConsoleError with status 409 when it is not running)."""
        return self._control(run_id, "pause")

    def resume(self, run_id):
        return self._control(run_id, "resume")

    def abort(self, run_id):
        """Stops the run: the gimbal back to null, the run ``interrupted`` with stop cause ``aborted``."""
        return self._control(run_id, "abort")

    def answer(self, run_id, prompt_id, value):
        """Answers an operator prompt of an acceptance (docs/console.md)."""
        return self._post(f"/api/runs/{self._name(run_id, 'run id')}/answer", {"id": prompt_id, "value": value})

    def __repr__(self):
        return f"Console({self.url!r})"


class RunEvents:
    """Console.events' iterator: one ``/events?from=OFFSET`` chunk at a time (up to 256 KiB of lines)."""

    def __init__(self, console, run_id, start, poll_s, timeout_s):
        self._c, self.run_id, self._poll_s = console, run_id, float(poll_s)
        self._path = f"/api/runs/{run_id}/events"
        self._deadline = None if timeout_s is None else time.monotonic() + timeout_s
        self._timeout_s = timeout_s
        self._chunk_start = self._next = int(start)
        self._lines, self._done = [], False

    @property
    def offset(self):
        """The start of the chunk being yielded while some of its lines are not, else its end:
        following again from here misses no line."""
        return self._chunk_start if self._lines else self._next

    def __iter__(self):
        return self

    def _fetch(self):
        chunk = self._c._get(self._path, **{"from": self._next})
        lines, nxt, live = chunk.get("events"), chunk.get("next"), chunk.get("live")
        if not isinstance(lines, list) or not isinstance(nxt, int) or not isinstance(live, bool):
            raise ConsoleError(f"GET {self._c.url}{self._path}: expected {{events, next, live}}", self._c.url + self._path)
        origin = f"{self._c.url}{self._path}?from={self._next}"
        self._lines = [(f"{origin}: line {k + 1}", line) for k, line in enumerate(lines)]
        self._chunk_start, self._next = self._next, nxt
        self._lines.reverse()
        return live

    def __next__(self):
        while not self._lines:
            if self._done:
                raise StopIteration
            live = self._fetch()
            if self._lines:
                break
            # `live` is judged before the lines are read: a run not live then had written them all.
            if not live:
                self._done = True
                raise StopIteration
            if self._deadline is not None and time.monotonic() > self._deadline:
                raise TimeoutError(f"run {self.run_id}: still live after {self._timeout_s} s")
            time.sleep(self._poll_s)
        origin, line = self._lines.pop()
        return _native.event_line(line, origin)
