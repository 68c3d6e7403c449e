"""fpss_stand: fpss-stand's calibrator, diagnosis, experiment design, catalogue, run folders and
web console for analysts.

The numbers come from the same C++ libraries as the ``fpss-stand`` command (the native module
``_fpss_stand``); there is no second implementation. Samples may be a samples CSV path, a pandas
DataFrame or a dict of numpy arrays with the columns of samples.csv (docs/formats.md). Angles are
arcsec, coefficients C1..C8 radians (rad/count), as in the coefficient files. See docs/python.md.
"""
import os
import re
import tempfile
from contextlib import contextmanager

import numpy as np

from . import _fpss_stand as _native

__all__ = [
    "InputError", "DataError", "CatalogueUnavailable", "Calibration", "Catalogue",
    "transfer_function", "inverse_transfer_function", "calibrate", "diagnose", "design", "dwells",
    "residuals", "compare", "read_samples", "load_coefficients", "save_coefficients",
    "published_names", "load_published", "REQUIRED_COLUMNS",
    "open_run", "Run", "RunFile", "read_run_file", "Acceptance", "Gap", "Console", "ConsoleError",
]

# A copy of the published coefficient sets installed next to the package (scripts/python) is used
# when the checkout the module was built from is not there.
_data = os.path.join(os.path.dirname(__file__), "data")
if "FPSS_DATA_DIR" not in os.environ and os.path.isdir(os.path.join(_data, "published")):
    os.environ["FPSS_DATA_DIR"] = _data

InputError = _native.InputError  # a ValueError: the message names the file, line/row or key
DataError = _native.DataError  # an InputError: the data cannot answer (too few points, ...)
CatalogueUnavailable = _native.CatalogueUnavailable

REQUIRED_COLUMNS = ("time_s", "phase", "step", "ref_pitch_arcsec", "ref_yaw_arcsec", "counts_alpha", "counts_beta")


def _is_path(x):
    return isinstance(x, (str, bytes, os.PathLike))


@contextmanager
def _samples_file(samples, name=None):
    """(path, label) of a samples CSV: the path itself, or a DataFrame's/arrays' columns written by
    the stand's own SampleTable writer to a temporary samples.csv, so every function reads samples
    one way (the command's reader, with its checks)."""
    if _is_path(samples):
        path = os.fspath(samples)
        yield path, path
        return
    if hasattr(samples, "columns") and hasattr(samples, "to_numpy"):  # a pandas DataFrame
        columns = {str(c): samples[c].to_numpy() for c in samples.columns}
        label = name or "DataFrame"
    elif isinstance(samples, dict):
        columns = {str(k): np.asarray(v) for k, v in samples.items()}
        label = name or "arrays"
    else:
        raise TypeError("samples: expected a path, a pandas DataFrame or a dict of numpy arrays, got "
                        f"{type(samples).__name__}")
    if "phase" in columns:
        # pandas.read_csv reads the phase "null" as a missing value (NaN) by default: it is "null".
        columns["phase"] = ["null" if p is None or (isinstance(p, float) and np.isnan(p)) else str(p)
                            for p in columns["phase"]]
    with tempfile.TemporaryDirectory(prefix="fpss_stand-") as d:
        path = os.path.join(d, "samples.csv")
        _native.write_samples(path, columns, label)
        try:
            yield path, label
        except InputError as e:
            # The reader names lines of the file written ("DataFrame:LINE:", the header line 1): name the row.
            message = re.sub(re.escape(label) + r":(\d+):", lambda m: f"{label}: row {int(m.group(1)) - 2}:", str(e))
            raise type(e)(message) from None


def _coefficients_arg(c):
    """A coefficient set as the native side takes it: a path (str), a dict, or a Calibration."""
    if isinstance(c, Calibration):
        return c.json
    if isinstance(c, os.PathLike):
        return os.fspath(c)
    return c


def _axis(coeffs):
    c = np.asarray(coeffs, dtype=float).ravel()
    if c.size != 8:
        raise ValueError(f"coeffs: expected C1..C8 (8 numbers), got {c.size}")
    return [float(v) for v in c]


def transfer_function(coeffs, counts):
    """Angle in arcsec for counts under one axis's C1..C8 (paper eq. 1:
    C1 + C2 N + C3 sin(C4 N + C5) + C6 sin(C7 N + C8), radians). Scalars give a float."""
    out = _native.transfer_function(_axis(coeffs), np.asarray(counts, dtype=float))
    return float(out) if np.ndim(counts) == 0 else out


def inverse_transfer_function(coeffs, angle_arcsec, lo_counts=-32768.0, hi_counts=32767.0):
    """Counts whose angle is angle_arcsec, over [lo_counts, hi_counts] where the transfer function
    must be monotonic (ValueError naming the count where it is not, or an angle not reached)."""
    out = _native.inverse_transfer_function(_axis(coeffs), np.asarray(angle_arcsec, dtype=float),
                                            float(lo_counts), float(hi_counts))
    return float(out) if np.ndim(angle_arcsec) == 0 else out


class Calibration:
    """A coefficient set: ``json`` is the coefficient file's content (calibration.json's, for a fit)
    as a dict; ``alpha``/``beta`` C1..C8 (radians) as arrays; ``summary`` the command's printed
    Table-1 summary (fits only: a fit's whole summary, a fitted coefficient file's head of it, its
    first line, Table 1 and the coefficients with their 1-sigma; "" for a published set)."""

    def __init__(self, json, summary=""):
        self.json = json
        self.summary = summary

    unit = property(lambda self: self.json.get("unit", ""))
    alpha = property(lambda self: np.array(self.json["alpha"], dtype=float))
    beta = property(lambda self: np.array(self.json["beta"], dtype=float))
    residuals = property(lambda self: self.json.get("residuals"))
    uncertainties = property(lambda self: self.json.get("uncertainties"))

    def expanded_uncertainty(self, axis):
        """[(angle_arcsec, U_arcsec)] of one axis ("pitch" or "yaw"): U = k u at 95 %, per listed angle
        (None where the angle is not reached); empty for a set without budgets."""
        u = (self.json.get("uncertainties") or {}).get(axis) or {}
        return [tuple(p) for p in u.get("angle_expanded_uncertainty_arcsec", [])]

    def budget(self, axis):
        """The uncertainty budget of one axis at its largest U: [{source, type, u_arcsec, ...}]
        (docs/calibration.md), with coverage_factor and the angle in ``uncertainties``."""
        u = (self.json.get("uncertainties") or {}).get(axis) or {}
        return list(u.get("budget", []))

    def pitch_arcsec(self, counts_alpha):
        """Pitch angle (arcsec) from counts_alpha."""
        return transfer_function(self.alpha, counts_alpha)

    def yaw_arcsec(self, counts_beta):
        """Yaw angle (arcsec) from counts_beta."""
        return transfer_function(self.beta, counts_beta)

    def save(self, path):
        """Write it as a coefficient file (the stand's checked, atomic writer)."""
        _native.save_coefficients(os.fspath(path), self.json)

    def __getitem__(self, key):
        return self.json[key]

    def __repr__(self):
        return f"Calibration(unit={self.unit!r}, method={self.json.get('method')!r})"


def load_coefficients(path):
    """A coefficient file, read and checked as the commands read it; a fit's ``summary`` is its Table 1."""
    j = _native.load_coefficients(os.fspath(path))
    return Calibration(j, _native.calibration_summary(j))


def save_coefficients(path, coefficients):
    _native.save_coefficients(os.fspath(path), _coefficients_arg(coefficients))


def published_names():
    """The 14 coefficient sets of the paper's Tables A-1..A-7 ("a-1-fpss1", ...)."""
    return list(_native.published_names())


def load_published(name):
    return Calibration(_native.load_published(name))


def calibrate(samples, *, method="differences", init=None, truth=None, count_noise_counts=None, unit=None,
              out=None, name=None):
    """Fit both axes' transfer functions: what ``fpss-stand calibrate --data SAMPLES --out OUT`` does,
    with the same functions (calibrate_csv, then the coefficient file), so the result equals the
    command's calibration.json to the last digit (``calibrated_at`` aside). ``init``/``truth``: a
    coefficient file path, dict or Calibration (--init, --truth); ``out``: also write the file.
    For a DataFrame, ``source`` is ``name`` (default "DataFrame")."""
    with _samples_file(samples, name) as (path, label):
        j, text = _native.calibrate_file(path, label, method, _coefficients_arg(init), _coefficients_arg(truth),
                                         count_noise_counts, unit or "", os.fspath(out) if out else "")
    return Calibration(j, text)


def diagnose(model, samples, *, settle_s=0.0, max_skew_s=0.25, name=None):
    """Where the sim-to-real gap lies: GAP.json's content as ``fpss-stand diagnose --model MODEL
    --data SAMPLES`` writes it (a dict; ``model`` names the model file, or "model" for a dict)."""
    model_arg = _coefficients_arg(model)
    model_name = model_arg if isinstance(model_arg, str) else "model"
    with _samples_file(samples, name) as (path, label):
        return _native.diagnose_file(model_arg, model_name, path, label, float(settle_s), float(max_skew_s))


def design(target_sigma_arcsec, *, prior="a-6-fpss1", also_for="published", **inputs):
    """The cheapest null-to-offset calibration reaching ``target_sigma_arcsec`` (calib/design.h).
    ``prior``: a published set's name, a coefficient file, dict or Calibration; ``also_for``:
    "published" (every trustworthy published set, as ``fpss-stand design`` does), None, or a list.
    Other keyword arguments are DesignInputs' fields: extent_deg, candidate_step_deg, rate_deg_s,
    accel_deg_s2, settle_s, frame_rate_hz, count_noise_counts, ref_noise_arcsec, samples_choices,
    max_offsets_per_axis. Returns the dict ``fpss-stand design --json`` prints: ``offsets`` (how
    many), ``offsets_deg`` (each {axis, angle_deg}, in recording order), ``inputs`` and ``paper_grid``
    (the shipped grid on the same bench, for comparison)."""
    known = {"extent_deg", "candidate_step_deg", "rate_deg_s", "accel_deg_s2", "settle_s", "frame_rate_hz",
             "count_noise_counts", "ref_noise_arcsec", "samples_choices", "max_offsets_per_axis"}
    unknown = set(inputs) - known
    if unknown:
        raise TypeError(f"design: unknown argument(s) {sorted(unknown)}; known: {sorted(known)}")

    def resolve(c):
        if isinstance(c, str) and c in _native.published_names():
            return _native.load_published(c)
        return _coefficients_arg(c)

    if also_for == "published":
        sets = []
        for n in _native.published_names():
            s = _native.load_published(n)
            if "suspect" not in s:
                s["unit"] = n
                sets.append(s)
    else:
        sets = [resolve(c) for c in (also_for or [])]
    kw = dict(inputs, target_sigma_arcsec=float(target_sigma_arcsec))
    return _native.design(resolve(prior), sets, kw)


def _frame(columns):
    import pandas as pd
    return pd.DataFrame(columns)


def read_samples(path):
    """A samples CSV as a DataFrame, read by the stand's reader (the same checks and messages)."""
    return _frame(_native.read_samples(os.fspath(path)))


def dwells(samples, *, calibration=None, count_noise_counts=None, reject_outliers=True, name=None):
    """The one reduction (calib/reduction.h): a DataFrame of the null and offset dwells (means,
    scatters, frames kept and rejected). With ``calibration``, the reduction its fit was made on
    (its outlier rule's noise). ``.attrs["outliers"]`` holds the outlier counts."""
    with _samples_file(samples, name) as (path, label):
        r = _native.reduce_file(path, label, _coefficients_arg(calibration), count_noise_counts, reject_outliers)
    df = _frame(r["dwells"])
    df.attrs["outliers"] = r["outliers"]
    return df


def residuals(calibration, samples, *, name=None):
    """Per dwell of the calibration's own reduction: the model's angles from the dwell's mean counts
    and their residual against the reference (``res_pitch_arcsec`` = pitch(counts_alpha) -
    ref_pitch_arcsec, likewise yaw). The differences method fixes angles up to one reference level
    per axis: compare residuals with each other (or less their median), not with zero."""
    cal = calibration if isinstance(calibration, Calibration) else Calibration(
        _native.load_coefficients(os.fspath(calibration)) if _is_path(calibration)
        else _native.check_coefficients(calibration, "calibration"))
    df = dwells(samples, calibration=cal, name=name)
    df["pitch_arcsec"] = cal.pitch_arcsec(df["counts_alpha"].to_numpy())
    df["yaw_arcsec"] = cal.yaw_arcsec(df["counts_beta"].to_numpy())
    df["res_pitch_arcsec"] = df["pitch_arcsec"] - df["ref_pitch_arcsec"]
    df["res_yaw_arcsec"] = df["yaw_arcsec"] - df["ref_yaw_arcsec"]
    return df


def compare(a, b, *, range_deg=0.35):
    """B - A at equal counts over A's +-range_deg (the paper's Figures 1-2; ``fpss-stand compare``):
    ``summary`` (max, rms, mean, shape change per axis) and ``alpha``/``beta`` curves (counts,
    angle_a_arcsec, diff_arcsec as arrays). a, b: published names, paths, dicts or Calibrations."""
    def resolve(c):
        if isinstance(c, str) and c in _native.published_names():
            return _native.load_published(c)
        return _coefficients_arg(c)
    return _native.compare(resolve(a), resolve(b), float(range_deg))


class Catalogue:
    """The stand's catalogue of units, runs, calibrations and acceptances, read-only: ``sqlite:PATH``
    or a plain PATH, or ``postgresql://USER@HOST[:PORT]/DB?sslmode=...`` (docs/fleet.md). Lists come
    as DataFrames (``as_frame=False``: lists of dicts)."""

    def __init__(self, url):
        self._c = _native.Catalogue(os.fspath(url))

    backend = property(lambda self: self._c.backend)
    location = property(lambda self: self._c.location)
    schema_version = property(lambda self: self._c.schema_version)

    def units(self):
        return list(self._c.units())

    def runs(self, unit=None, limit=0, as_frame=True):
        """Runs, most recent first (``outcome``: running, completed, failed or interrupted)."""
        rows = self._c.runs(unit, int(limit))
        return _frame(rows) if as_frame else rows

    def run(self, run_id):
        """One run as a dict, or None."""
        return self._c.run(run_id)

    def history(self, serial, as_frame=True):
        """The unit's calibrations, oldest first; ``coefficients`` holds each one's file content,
        ``pitch``/``yaw`` its Table-1 residuals."""
        rows = self._c.history(serial)
        return _frame(rows) if as_frame else rows

    def run_calibrations(self, run_id):
        return list(self._c.run_calibrations(run_id))

    def acceptances(self, serial, as_frame=True):
        rows = self._c.acceptances(serial)
        return _frame(rows) if as_frame else rows

    def __repr__(self):
        return f"Catalogue({self.location!r}, backend={self.backend!r})"


# Run folders and the console: after the names they use (read_samples, load_coefficients, InputError).
from .run import Acceptance, Gap, Run, RunFile, open_run, read_run_file  # noqa: E402
from .console import Console, ConsoleError  # noqa: E402
