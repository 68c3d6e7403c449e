"""open_run(RUN_DIR): a run folder's files (docs/formats.md) as DataFrames and typed objects.

Every file is read by the stand's own reader through the native module: run.json by ``RunFile``
(stand/catalogue/run_file.h), events.jsonl by the typed event reader (procedures/events.h),
points.jsonl by the recorder's journal reader, samples.csv by the samples reader, calibration.json
by the coefficient-file reader, acceptance.json and GAP.json by the one bounded JSON reader
(base/json_file.h). A bad file raises InputError naming the file (and the line and key).
"""
import dataclasses
import functools
import os
from dataclasses import dataclass, field
from typing import Any, Optional

from . import _fpss_stand as _native

InputError = _native.InputError


def _frozen(cls):
    return dataclass(frozen=True)(cls)


def _build(cls, d):
    """A dataclass of `cls` from a dict: its fields by name (absent: the field's default), every
    other key kept in ``extra`` when the class has one."""
    d = d or {}
    names = {f.name for f in dataclasses.fields(cls)}
    kw = {k: v for k, v in d.items() if k in names and k != "extra"}
    if "extra" in names:
        kw["extra"] = {k: v for k, v in d.items() if k not in names}
    return cls(**kw)


@_frozen
class Procedure:
    name: str
    sha256: str
    text: str = field(repr=False)
    file: Optional[str] = None


@_frozen
class Points:
    total: int
    completed: int
    skipped: Optional[int] = None


@_frozen
class Files:
    """run.json's ``files``: names of the folder's files (None: not written)."""
    samples: Optional[str] = None
    journal: Optional[str] = None
    events: Optional[str] = None
    event_stream: Optional[str] = None
    calibration: Optional[str] = None
    gap: Optional[str] = None


@_frozen
class Session:
    """One start or resume of the run (run.json ``sessions[]``)."""
    session: int
    started_utc: Optional[str] = None
    ended_utc: Optional[str] = None
    outcome: Optional[str] = None
    reason: Optional[str] = None
    first_point: Optional[int] = None
    pid: Optional[int] = None
    points_completed: Optional[int] = None
    engine: Optional[dict] = None
    sensor_stats: Optional[dict] = None
    emulator: Optional[dict] = None


@_frozen
class RunFile:
    """run.json, as the C++ ``RunFile`` reads it (docs/formats.md "run.json"). ``run_id`` is the
    run id (the folder's name for runs made before ids were UUIDs); ``json`` the file's content as
    RunFile writes it; ``extra`` the keys this version does not know."""
    run_id: str
    unit: str
    emulated: bool
    started_utc: str
    outcome: str
    procedure: Procedure
    points: Points
    sessions: tuple
    files: Files
    format: Optional[str] = None
    software: Optional[dict] = None
    stand: Optional[dict] = None
    sensor_id: Optional[str] = None
    emulator: Optional[dict] = None
    ended_utc: Optional[str] = None
    reason: Optional[str] = None
    stop_cause: Optional[str] = None
    adaptive_stops: Optional[tuple] = None
    safe_state: Optional[bool] = None
    operator: Optional[str] = None
    signed_off_utc: Optional[str] = None
    acceptance: Optional[dict] = None
    units: Optional[tuple] = None  # several units: run.json ``units[]`` as dicts (serial, outcome, files, relative)
    extra: dict = field(default_factory=dict)
    json: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_json(cls, content, run_id):
        d = dict(content)
        d["run_id"] = run_id
        d["procedure"] = _build(Procedure, content["procedure"])
        d["points"] = _build(Points, content["points"])
        d["files"] = _build(Files, content.get("files"))
        d["sessions"] = tuple(_build(Session, s) for s in content.get("sessions", []))
        if "adaptive_stops" in content:
            d["adaptive_stops"] = tuple(content["adaptive_stops"])
        if "units" in content:
            d["units"] = tuple(dict(u) for u in content["units"])
        r = _build(cls, d)
        object.__setattr__(r, "json", content)
        return r


def read_run_file(run_dir):
    """RUN_DIR/run.json as a RunFile (the C++ reader: InputError naming the file and the key)."""
    content, run_id = _native.read_run_file(os.fspath(run_dir))
    return RunFile.from_json(content, run_id)


@_frozen
class Criterion:
    """One acceptance criterion (docs/acceptance.md ``criteria[]``)."""
    id: str
    title: str = ""
    axis: Optional[str] = None
    measured: Optional[float] = None
    uncertainty: Optional[float] = None
    expanded_uncertainty: Optional[float] = None
    coverage_factor: Optional[float] = None
    dof_eff: Optional[float] = None
    budget: tuple = ()
    limit: Optional[float] = None
    acceptance_limit: Optional[float] = None
    relation: str = "<="
    unit: str = ""
    outcome: Optional[str] = None
    outcome_reason: str = ""
    passed: bool = False
    limit_key: Optional[str] = None
    source: Optional[str] = None
    detail: Any = None
    extra: dict = field(default_factory=dict)


@_frozen
class Acceptance:
    """acceptance.json, the acceptance certificate (docs/acceptance.md): ``criteria`` typed,
    ``points`` and the other blocks as written; ``json`` the whole file."""
    verdict: str
    passed: bool
    unit: str
    criteria: tuple
    failed: tuple
    format: Optional[str] = None
    stand: Optional[dict] = None
    software: Optional[dict] = None
    procedure: Optional[dict] = None
    limits: Optional[dict] = None
    run: Optional[dict] = None
    date_utc: Optional[str] = None
    calibration: Optional[str] = None
    calibration_uncertainty: Optional[dict] = None
    decision_rule: Optional[dict] = None
    reference: Optional[dict] = None
    conditional: tuple = ()
    operator: Optional[str] = None
    signed_off_utc: Optional[str] = None
    outliers: Optional[dict] = None
    points: tuple = ()
    extra: dict = field(default_factory=dict)
    json: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_json(cls, content, origin):
        try:
            d = dict(content)
            d["criteria"] = tuple(_build(Criterion, dict(c, budget=tuple(c.get("budget", ()))))
                                  for c in content.get("criteria", []))
            d["failed"] = tuple(content.get("failed", []))
            d["conditional"] = tuple(content.get("conditional", []))
            d["points"] = tuple(content.get("points", []))
            a = _build(cls, d)
        except (TypeError, AttributeError, ValueError) as e:
            raise InputError(f"{origin}: not an acceptance certificate: {e}") from None
        object.__setattr__(a, "json", content)
        return a


@_frozen
class Gap:
    """GAP.json, the sim-to-real diagnosis (docs/diagnosis.md "GAP.json"): the verdict, the cause
    and the figures; the lists and blocks as written; ``json`` the whole file."""
    verdict: str
    verdict_sentence: str = ""
    cause: Optional[str] = None
    source: Optional[str] = None
    model: Optional[str] = None
    causes: tuple = ()
    gap_before_arcsec: Optional[float] = None
    gap_after_arcsec: Optional[float] = None
    gap_after_all_arcsec: Optional[float] = None
    noise_floor_arcsec: Optional[float] = None
    where: tuple = ()
    where_after: tuple = ()
    effects: tuple = ()
    selection: Optional[dict] = None
    not_observable: tuple = ()
    ambiguous_with: tuple = ()
    unexplained: Optional[dict] = None
    within_step_scatter_arcsec: Optional[float] = None
    expected_scatter_arcsec: Optional[float] = None
    excess_scatter: Optional[float] = None
    outliers: Optional[dict] = None
    split: Optional[dict] = None
    recording: Optional[dict] = None
    warnings: tuple = ()
    extra: dict = field(default_factory=dict)
    json: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_json(cls, content, origin):
        try:
            d = {k: tuple(v) if isinstance(v, list) else v for k, v in content.items()}
            g = _build(cls, d)
        except (TypeError, AttributeError, ValueError) as e:
            raise InputError(f"{origin}: not a diagnosis (GAP.json): {e}") from None
        object.__setattr__(g, "json", content)
        return g


def _typed_frame(rows, datetime_columns=("utc",)):
    """A DataFrame of dicts (keys may differ between rows), each column typed by the values the
    rows hold (a key a row lacks is missing there): whole numbers as nullable Int64, other numbers
    float64 (missing: NaN), true/false as nullable boolean, text as pandas' string type; lists and
    objects kept as they are; ``utc`` a UTC time."""
    import pandas as pd
    names = list(dict.fromkeys(k for r in rows for k in r))
    columns = {}
    for name in names:
        raw = [r.get(name) for r in rows]
        values = [v for v in raw if v is not None]
        if name in datetime_columns and all(isinstance(v, str) for v in values):
            # pandas 2 wants to be told the times may differ in precision; 1.5 infers it
            kw = {"format": "ISO8601"} if int(pd.__version__.split(".")[0]) >= 2 else {}
            columns[name] = pd.to_datetime(pd.Series(raw, dtype="object"), utc=True, **kw)
        elif values and all(isinstance(v, bool) for v in values):
            columns[name] = pd.array(raw, dtype="boolean")
        elif values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            columns[name] = pd.array(raw, dtype="Int64")
        elif values and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            columns[name] = pd.array([float("nan") if v is None else float(v) for v in raw], dtype="float64")
        elif values and all(isinstance(v, str) for v in values):
            columns[name] = pd.array(raw, dtype="string")
        else:
            columns[name] = pd.Series(raw, dtype="object")
    return pd.DataFrame({k: pd.Series(v).reset_index(drop=True) for k, v in columns.items()}, index=pd.RangeIndex(len(rows)))


class Run:
    """A run folder (``open_run``): its files, each read when first asked for.

    ``run_file`` (alias ``info``): run.json as a RunFile; ``samples``: samples.csv as a DataFrame
    (``samples_by_unit``: per unit serial); ``points``: the point journal (points.jsonl) as a
    DataFrame (``points_by_unit``); ``events``: events.jsonl, one row per line, typed columns;
    ``calibration``: the run's calibration (the file run.json names) as a Calibration, None without
    one (``calibrations``: every calibration*.json by name); ``acceptance``: acceptance.json as an
    Acceptance or None; ``gap``: GAP.json as a Gap or None."""

    def __init__(self, run_dir):
        self.path = os.path.abspath(os.fspath(run_dir))
        if not os.path.isdir(self.path):
            why = "not a folder" if os.path.exists(self.path) else "no such folder"
            raise InputError(f"{self.path}: not a run folder ({why})")
        if not os.path.isfile(os.path.join(self.path, "run.json")):
            raise InputError(f"{os.path.join(self.path, 'run.json')}: not a run folder (no run.json)")
        self.run_file = read_run_file(self.path)

    info = property(lambda self: self.run_file)
    run_id = property(lambda self: self.run_file.run_id)
    unit = property(lambda self: self.run_file.unit)
    outcome = property(lambda self: self.run_file.outcome)

    def _file(self, name):
        return os.path.join(self.path, name)

    def _unit_dirs(self):
        """{serial: folder}: RUN_DIR/units/<SERIAL>/ for a multi-unit run, else the run's one unit."""
        if self.run_file.units:
            return {u["serial"]: os.path.dirname(os.path.join(self.path, u["samples"]))
                    for u in self.run_file.units if u.get("samples")}
        units = os.path.join(self.path, "units")
        if os.path.isdir(units):
            found = {s: os.path.join(units, s) for s in sorted(os.listdir(units))
                     if os.path.isdir(os.path.join(units, s))}
            if found:
                return found
        return {self.run_file.unit: self.path}

    def _single(self, by_unit, what):
        if len(by_unit) != 1:
            raise InputError(f"{self.path}: a run of {len(by_unit)} units ({', '.join(by_unit)}): "
                             f"use {what}_by_unit[SERIAL]")
        return next(iter(by_unit.values()))

    @functools.cached_property
    def samples_by_unit(self):
        """{unit serial: samples DataFrame}, read by the stand's samples reader."""
        from . import read_samples
        name = "samples.csv" if self.run_file.units else (self.run_file.files.samples or "samples.csv")
        return {serial: read_samples(os.path.join(d, name)) for serial, d in self._unit_dirs().items()}

    @property
    def samples(self):
        """The samples of a single-unit run (samples.csv) as a DataFrame."""
        return self._single(self.samples_by_unit, "samples")

    @functools.cached_property
    def points_by_unit(self):
        """{unit serial: the point journal}: one row per completed point (``point`` 1-based, ``rows``,
        ``bytes``, ``last_time_s``, ``utc``, ``session``, ``attempts``, ``skipped``)."""
        name = self.run_file.files.journal or "points.jsonl"
        out = {}
        for serial, d in self._unit_dirs().items():
            path = os.path.join(self.path if self.run_file.units else d, name)  # several units share the run's journal
            rows = _native.read_journal(path) if os.path.exists(path) else []
            df = _typed_frame(rows)
            if df.empty:
                df = _typed_frame([], ()).reindex(columns=["point", "step", "rows", "bytes", "last_time_s", "utc",
                                                          "session", "attempts", "skipped"])
            out[serial] = df
        return out

    @property
    def points(self):
        """The point journal (points.jsonl) of a single-unit run as a DataFrame."""
        return self._single(self.points_by_unit, "points")

    @functools.cached_property
    def event_lines(self):
        """events.jsonl's lines in their typed form, as dicts (a last line cut short left out)."""
        name = self.run_file.files.event_stream or "events.jsonl"
        path = self._file(name)
        if not os.path.exists(path):
            return []
        return _native.read_event_lines(path)

    @functools.cached_property
    def events(self):
        """events.jsonl, one row per line: ``type``, ``utc`` (a UTC time) and every key of any line
        (missing where a line has none), typed columns (docs/formats.md "events.jsonl")."""
        return _typed_frame(self.event_lines)

    @functools.cached_property
    def calibrations(self):
        """{file name: Calibration} of every calibration*.json in the folder, in the order written."""
        from . import load_coefficients

        def order(n):
            stem = n[:-len(".json")]
            return 1 if stem == "calibration" else int(stem.rsplit("-", 1)[1])
        names = [n for n in os.listdir(self.path) if n.startswith("calibration") and n.endswith(".json")
                 and (n == "calibration.json" or n[len("calibration-"):-len(".json")].isdigit())]
        return {n: load_coefficients(self._file(n)) for n in sorted(names, key=order)}

    @property
    def calibration(self):
        """The run's calibration (run.json ``files.calibration``, else calibration.json), None without one."""
        name = self.run_file.files.calibration or "calibration.json"
        return self.calibrations.get(name)

    @functools.cached_property
    def acceptance(self):
        path = self._file("acceptance.json")
        if not os.path.exists(path):
            return None
        return Acceptance.from_json(_native.read_json_file(path, "acceptance file"), path)

    @functools.cached_property
    def gap(self):
        name = self.run_file.files.gap or "GAP.json"
        path = self._file(name)
        if not os.path.exists(path):
            return None
        return Gap.from_json(_native.read_json_file(path, "diagnosis file"), path)

    def __repr__(self):
        return f"Run({self.path!r}, unit={self.unit!r}, outcome={self.outcome!r})"


def open_run(run_dir):
    """A run folder (docs/formats.md "The run folder"): run.json is read at once (InputError naming
    the file when the folder is not a run folder or the file is torn), every other file when first
    asked for. See Run."""
    return Run(run_dir)
