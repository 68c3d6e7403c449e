#!/usr/bin/python3
"""The investigation loop (diagnose, design a follow-up, run it, diagnose jointly) on recordings of
the independent bench simulator: the confusable cases, where a first run cannot tell the true
effect from a look-alike or cannot see it at all, and unambiguous ones.

Independent of the emulator (fixtures/) and of `fpss-stand simulate`: every recording, the first
run's and each follow-up's, is made by benchsim_procedure.py (benchsim.py's gimbal, effects and
sensor) from a procedure file; `fpss-stand` is used only for `diagnose` and `design`. A follow-up
runs on the same truth (same bench, same effect and parameters) with a different seed, later in
lab time (the temperature profile goes on; each recording has its own clock).

Kinds of case (parameters drawn per case from the seed):
- skew_dwells: a time skew of 2-8 ms behind a dwells-only first run (a null-offset grid on both
  axes, no slews);
- skew_dwells_from_arrival: a time skew of 10-100 ms, the sensor ahead of the reference in even
  cases and behind it in odd ones, behind a dwells-only grid whose dwells are sampled from their
  arrival (settle_s 0): a lagging sensor's first frames of each dwell still see the end of the
  move (it looks like a fast settling until slews pin the lag), a leading sensor's last frames
  already see the next one;
- settling_slews: settling (0.3-2 arcsec, tau 0.2-1.5 s) behind a slews-only first run (slews on
  both axes at 300 and 600 arcsec/s plus two null dwells);
- backlash_settling_one_side: backlash (1-6 arcsec) or a long-tau settling (1-3 arcsec, tau 3-10 s),
  alternately, behind a grid whose every point is approached from below on both axes, in
  ascending order (built from move/sample steps);
- skew_backlash_slews: a time skew (2-10 ms) or backlash (1-6 arcsec), alternately, behind slews at
  a single rate (300 arcsec/s) plus two null dwells;
- temperature_sine: a slow temperature sine (2 deg C, period 400-1200 s, 1 arcsec/deg C on each axis,
  signs drawn) behind a dwells-only grid (it looks like a drift);
- coefficients_narrow: an ageing of the transfer function (both sinusoids of each axis changed by
  2-8 % in amplitude and 0.02-0.08 rad in phase, signs drawn) behind a narrow grid about the null
  (+-0.05 deg at 0.01 deg steps), over which it is nearly a bias and a scale factor; judged by
  the RMS over +-1500 arcsec of fitted minus true angle against the RMS of the change (within 10 %);
- unambiguous: one catalogued effect at a time (benchsim.draw, "normal" size) behind the full
  first run procedures/sim_to_real.yaml;
- backlash_settling_one_side_marked (only with --kinds): the one-sided grid with a 5-frame dwell
  where each approach starts (overshoot 250 arcsec), so the recording shows the approach's side.

Per case: run the first procedure, `diagnose --partial`; then up to two rounds: when GAP.json has
ambiguous sets or candidates whose status is unbounded or ambiguous, `design --discriminate GAP
--observe GAP --emulate --out FUP.yaml --json --max-bench-s B` (B: the investigation's budget, half the
first run's bench time and at most what is left of 1.0x it), stop when it exits 1, otherwise
run FUP.yaml and diagnose all recordings so far jointly. Recorded: the true effect named in
`causes` with its main parameter within 10 %, the follow-ups run, their bench time over the first
run's (GAP.json recordings[].time_span_s), and for unambiguous cases whether it stopped after the
first run.

    benchsim_investigate.py eval --fpss-stand BIN --cases N --seed S [--work DIR] [--kinds K,K]
                                 [--jobs J] [--json PATH] [--assert] [--budget-x X]

N cases per kind. Prints one line per case, a table per kind, the totals and the three figures:
named within 10 % after <= 2 follow-ups (target >= 95 %), unambiguous cases stopping after the
first run (target >= 95 %), follow-up bench time <= 1.0x the first run's (max and mean). Exit 1
with --assert when a target is missed. --budget-x X (exploration, not the issue's figures) gives
design --max-bench-s X times the first run's bench time in each round instead of its default.

Run with /usr/bin/python3 (Debian's, with numpy and python3-yaml).
"""
import argparse
import concurrent.futures
import json
import os
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchsim as bs  # noqa: E402
import benchsim_procedure as bp  # noqa: E402
import fpss_physics as fp  # noqa: E402

SIM_TO_REAL = os.path.join(bs.SRC, "procedures", "sim_to_real.yaml")
MAX_FOLLOWUPS = 2
LAB_GAP_S = 60.0      # lab time between the end of one session and the start of the next
TOLERANCE = 0.10      # the main parameter's relative error for "named"
TARGETS = {"named": 0.95, "stopped": 0.95, "fup_ratio_max": 1.0}

# The main parameter(s) of each effect, compared within TOLERANCE (all of them).
MAIN = {"bias": ["pitch_arcsec", "yaw_arcsec"], "drift": ["pitch_arcsec_per_s", "yaw_arcsec_per_s"],
        "scale_factor": ["pitch_ppm", "yaw_ppm"], "boresight_roll": ["roll_arcsec"],
        "axis_nonorthogonality": ["skew_arcsec"], "backlash": ["width_arcsec"],
        "settling": ["amplitude_arcsec"], "time_skew": ["skew_s"],
        "temperature": ["pitch_arcsec_per_c", "yaw_arcsec_per_c"], "coefficients": []}


# ------------------------------------------------------------------ first procedures

GRID = ("  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.42, step_deg: 0.06, frames: 25, "
        "settle_s: 0.2}\n")


def slews(axis, rates):
    return (f"  - continuous_slew: {{axis: {axis}, amplitude_arcsec: 1500, rates_arcsec_s: [{', '.join(str(r) for r in rates)}], "
            "directions: both, reversals: 1, sample_period_s: 0.02, settle_s: 0.5}\n")


def dwells_only(settle_s=0.2):
    return "name: dwells_only\nsteps:\n  - home\n" + GRID.replace("settle_s: 0.2", f"settle_s: {settle_s:g}")


def slews_only(rates):
    return ("name: slews_only\nsteps:\n  - home\n  - sample: {frames: 25, settle_s: 0.2}\n" + slews("pitch", rates)
            + slews("yaw", rates) + "  - move: {pitch_arcsec: 0, yaw_arcsec: 0}\n  - sample: {frames: 25, settle_s: 0.2}\n")


def one_sided_grid(overshoot=300.0, marked=False):
    """The paper's grid points (null between offsets), each approached from below on both axes,
    the offsets of each axis in ascending order. The approach's start is not recorded (the
    diagnosis reads directions from the recorded reference alone, so it sees the jumps between
    dwells instead), unless `marked`: then a 5-frame dwell where each approach starts records
    its side, as the designer's own approaches do."""
    offs = [k * 216.0 for k in range(-7, 8) if k]
    t = "name: one_sided_grid\nsteps:\n  - home\n  - sample: {frames: 25, settle_s: 0.2}\n"
    for axis in (0, 1):
        pts = []
        for o in offs:
            p = [0.0, 0.0]
            p[axis] = o
            pts += [p, [0.0, 0.0]]
        for p in pts:
            t += f"  - move: {{pitch_arcsec: {p[0] - overshoot:g}, yaw_arcsec: {p[1] - overshoot:g}}}\n"
            if marked:
                t += "  - sample: {frames: 5}\n"
            t += f"  - move: {{pitch_arcsec: {p[0]:g}, yaw_arcsec: {p[1]:g}}}\n"
            t += "  - sample: {frames: 25, settle_s: 0.2}\n"
    return t


def narrow_grid():
    return ("name: narrow_grid\nsteps:\n  - home\n  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.05, "
            "step_deg: 0.01, frames: 25, settle_s: 0.2}\n")


def sim_to_real():
    with open(SIM_TO_REAL) as f:
        return f.read()


# ------------------------------------------------------------------ truths

def base_truth(rng, classes, params, temperature=None):
    truth = bp.default_truth([], rng, temperature=temperature)
    truth.update(classes=list(classes), params=params)
    return truth


def case_truth(kind, k, rng):
    u = rng.uniform
    if kind == "skew_dwells":
        return base_truth(rng, ["time_skew"], {"time_skew": {"skew_s": u(0.002, 0.008)}})
    if kind == "skew_dwells_from_arrival":  # the sensor ahead of the reference in even cases
        return base_truth(rng, ["time_skew"], {"time_skew": {"skew_s": (-1 if k % 2 == 0 else 1) * u(0.010, 0.100)}})
    if kind == "settling_slews":
        return base_truth(rng, ["settling"], {"settling": {"amplitude_arcsec": u(0.3, 2.0), "tau_s": u(0.2, 1.5)}})
    if kind in ("backlash_settling_one_side", "backlash_settling_one_side_marked"):
        if k % 2 == 0:
            return base_truth(rng, ["backlash"], {"backlash": {"width_arcsec": u(1, 6)}})
        return base_truth(rng, ["settling"], {"settling": {"amplitude_arcsec": u(1, 3), "tau_s": u(3, 10)}})
    if kind == "skew_backlash_slews":
        if k % 2 == 0:
            return base_truth(rng, ["time_skew"], {"time_skew": {"skew_s": u(0.002, 0.010)}})
        return base_truth(rng, ["backlash"], {"backlash": {"width_arcsec": u(1, 6)}})
    if kind == "temperature_sine":
        sg = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
        temp = {"t0_c": 20.0, "ramp_c_per_s": 0.0, "amplitude_c": 2.0, "period_s": u(400, 1200),
                "phase_rad": u(0, 2 * np.pi)}
        return base_truth(rng, ["temperature"], {"temperature": {"pitch_arcsec_per_c": sg(), "yaw_arcsec_per_c": sg()}},
                          temperature=temp)
    if kind == "coefficients_narrow":
        ma, mb = fp.load_coefficients(bp.MODEL)
        sg = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
        aged = {}
        for name, c in (("alpha", ma), ("beta", mb)):
            c = c.copy()
            c[2] *= 1 + sg() * u(0.02, 0.08)
            c[4] += sg() * u(0.02, 0.08)
            c[5] *= 1 + sg() * u(0.02, 0.08)
            c[7] += sg() * u(0.02, 0.08)
            aged[name] = [float(v) for v in c]
        return base_truth(rng, ["coefficients"], {"coefficients": aged})
    if kind == "unambiguous":
        cls = bs.CATALOGUE[k % len(bs.CATALOGUE)]
        return bp.default_truth([cls], rng)
    raise ValueError(kind)


KINDS = {"skew_dwells": dwells_only, "skew_dwells_from_arrival": lambda: dwells_only(0.0), "settling_slews": lambda: slews_only([300, 600]),
         "backlash_settling_one_side": one_sided_grid, "skew_backlash_slews": lambda: slews_only([300]),
         "temperature_sine": dwells_only, "coefficients_narrow": narrow_grid, "unambiguous": sim_to_real,
         # not in the default set (not one of the cases): the one-sided grid with each
         # approach's start recorded
         "backlash_settling_one_side_marked": lambda: one_sided_grid(250.0, marked=True)}
DEFAULT_KINDS = [k for k in KINDS if k != "backlash_settling_one_side_marked"]


# ------------------------------------------------------------------ fpss-stand

def call(cmd, ok=(0,)):
    """Runs cmd; retries while the binary is being replaced (missing, busy, not executable)."""
    for attempt in range(20):
        try:
            p = subprocess.run(cmd, capture_output=True, text=True)
        except OSError:  # ENOENT / ETXTBSY while it is rebuilt
            time.sleep(3)
            continue
        if p.returncode in (126, 127):
            time.sleep(3)
            continue
        return p
    raise RuntimeError(f"{cmd[0]} could not be run")


def diagnose(binary, model, datas, out):
    cmd = [binary, "diagnose", "--model", model, "--out", out, "--partial"]
    for d in datas:
        cmd += ["--data", d]
    p = call(cmd)
    if p.returncode != 0 or not os.path.exists(out):
        raise RuntimeError(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr.strip()}")
    with open(out) as f:
        return json.load(f)


def design(binary, gap_path, out, max_bench_s=None):
    """(design's --json or None when it exits 1 with nothing within the budget, the --json of a
    failed design, the stderr)."""
    if os.path.exists(out):
        os.remove(out)
    cmd = [binary, "design", "--discriminate", gap_path, "--observe", gap_path, "--emulate", "--out", out, "--json"]
    if max_bench_s:
        cmd += ["--max-bench-s", f"{max_bench_s:.3f}"]
    p = call(cmd)
    if p.returncode == 1 and not os.path.exists(out):
        try:
            j = json.loads(p.stdout)
        except ValueError:
            j = {}
        return None, j, p.stderr.strip()
    if p.returncode != 0 or not os.path.exists(out):
        raise RuntimeError(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr.strip()}")
    return json.loads(p.stdout), None, p.stderr.strip()


def needs_followup(gap):
    return bool(gap.get("ambiguous")) or any(c.get("status") in ("unbounded", "ambiguous") for c in gap.get("candidates", []))


# ------------------------------------------------------------------ one case

COEFF_RANGE_ARCSEC = 1500.0  # the calibrated range a change of coefficients is judged over


def transfer_error(fitted, truth, model):
    """RMS over +-COEFF_RANGE_ARCSEC of fitted - true angle, over the RMS of true - model angle."""
    t = np.asarray(truth, float)
    lo, hi = fp.counts_for_angle(t, np.array([-1.0, 1.0]) * COEFF_RANGE_ARCSEC / fp.ARCSEC_PER_RAD)
    n = np.linspace(lo, hi, 401)
    e = fp.angle_rad(np.asarray(fitted, float), n) - fp.angle_rad(t, n)
    d = fp.angle_rad(t, n) - fp.angle_rad(np.asarray(model, float), n)
    return float(np.sqrt(np.sum(e * e) / max(np.sum(d * d), 1e-30)))


def param_error(truth, gap):
    """(named, the largest relative error of the main parameters or None)."""
    cls = truth["classes"][0]
    named = [c["name"] for c in gap["causes"]]
    if cls not in named:
        return False, None
    fitted = gap["causes"][named.index(cls)]["params"]
    if cls == "coefficients":
        model = fp.load_coefficients(bp.MODEL)
        return True, max(transfer_error(fitted[a], truth["params"]["coefficients"][a], model[i])
                         for i, a in enumerate(("alpha", "beta")))
    errs = [abs(fitted[key] - truth["params"][cls][key]) / abs(truth["params"][cls][key]) for key in MAIN[cls]
            if key in fitted]
    return True, (max(errs) if errs else 0.0)


def gap_summary(gap):
    return {"verdict": gap["verdict"], "causes": [{"name": c["name"], "params": c.get("params")} for c in gap["causes"]],
            "ambiguous": [s.get("members") for s in gap.get("ambiguous", [])],
            "open": {c["name"]: c["status"] for c in gap.get("candidates", []) if c.get("status") in ("unbounded", "ambiguous")}}


def run_case(binary, work, kind, k, seed, budget_x=None):
    case_seed = seed * 100003 + list(KINDS).index(kind) * 1000 + k
    rng = np.random.default_rng(case_seed)
    truth = case_truth(kind, k, rng)
    d = os.path.join(work, f"{kind}-{k}")
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    first_yaml = os.path.join(d, "first.yaml")
    with open(first_yaml, "w") as f:
        f.write(KINDS[kind]())
    r = {"kind": kind, "k": k, "seed": case_seed, "dir": d, "truth": {"classes": truth["classes"], "params": truth["params"]},
         "rounds": [], "followups": 0, "error": None}
    try:
        rows, bench_s = bp.run_procedure(bp.load_steps(first_yaml), truth, case_seed, 0.0)
        bp.write_session(os.path.join(d, "first"), rows, truth, case_seed, 0.0, bench_s)
        lab = bench_s + LAB_GAP_S
        model = os.path.join(d, "first", "model.json")
        datas = [os.path.join(d, "first", "samples.csv")]
        gap_path = os.path.join(d, "gap0.json")
        gap = diagnose(binary, model, datas, gap_path)
        r["first"] = gap_summary(gap)
        for rnd in range(1, MAX_FOLLOWUPS + 1):
            if not needs_followup(gap):
                break
            fup_yaml = os.path.join(d, f"fup{rnd}.yaml")
            spans = [g["time_span_s"][1] - g["time_span_s"][0] for g in gap["recordings"]]
            first_s, used_s = spans[0], sum(spans[1:])
            # The investigation's budget (docs/diagnosis.md, "fpss-stand investigate"): each follow-up
            # at most half the first run's bench time, all of them at most the first run's.
            budget = budget_x * first_s if budget_x else min(0.5 * first_s, first_s - used_s)
            if budget <= 1.0:
                r["rounds"].append({"round": rnd, "designed": False, "design": "budget spent"})
                break
            dj, failed, err = design(binary, gap_path, fup_yaml, budget)
            rec = {"round": rnd, "designed": dj is not None}
            if dj is None:
                rec.update(design=failed, stderr=err)
                r["rounds"].append(rec)
                break
            rec["design"] = {key: dj.get(key) for key in ("found", "useful", "moves", "bench_s", "budget_s", "pairs", "unreachable")}
            rec["design"]["bounds"] = [b for b in dj.get("bounds", []) if not b.get("bounded")]
            s = case_seed + 7919 * rnd
            rows, bench_s = bp.run_procedure(bp.load_steps(fup_yaml), truth, s, lab)
            bp.write_session(os.path.join(d, f"fup{rnd}"), rows, truth, s, lab, bench_s)
            lab += bench_s + LAB_GAP_S
            datas.append(os.path.join(d, f"fup{rnd}", "samples.csv"))
            gap_path = os.path.join(d, f"gap{rnd}.json")
            gap = diagnose(binary, model, datas, gap_path)
            rec["gap"] = gap_summary(gap)
            r["rounds"].append(rec)
            r["followups"] = rnd
        spans = [rc["time_span_s"][1] - rc["time_span_s"][0] for rc in gap["recordings"]]
        r["first_bench_s"] = spans[0]
        r["fup_bench_s"] = sum(spans[1:])
        r["fup_ratio"] = sum(spans[1:]) / spans[0]
        r["named"], r["param_err"] = param_error(truth, gap)
        r["named10"] = r["named"] and r["param_err"] <= TOLERANCE
        r["final"] = gap_summary(gap)
        r["stopped_after_first"] = r["followups"] == 0
    except Exception as e:  # noqa: BLE001 - a case that cannot run is reported, not fatal
        r["error"] = f"{type(e).__name__}: {e}"
        r.update(named=False, named10=False, param_err=None, fup_ratio=0.0, stopped_after_first=False)
    return r


# ------------------------------------------------------------------ report

def line(r):
    t = r["truth"]
    cls = t["classes"][0]
    main = ", ".join(f"{key} {t['params'][cls][key]:.4g}" for key in (MAIN[cls] or [])) or "-"
    if r["error"]:
        return f"{r['kind']:27s} {r['k']:3d} {cls:22s} ERROR {r['error']}"
    causes = "+".join(c["name"] for c in r["final"]["causes"]) or "none"
    err = "-" if r["param_err"] is None else f"{100 * r['param_err']:.1f}%"
    moves = " | ".join("; ".join(rd["design"]["moves"]) if rd["designed"] else "design: nothing" for rd in r["rounds"])
    return (f"{r['kind']:27s} {r['k']:3d} {cls:22s} ({main}) first {'+'.join(c['name'] for c in r['first']['causes']) or 'none'}"
            f" -> {causes} err {err} {'OK ' if r['named10'] else 'MISS'} fups {r['followups']} x{r['fup_ratio']:.2f}"
            + (f" [{moves}]" if moves else ""))


def summarise(res):
    kinds = {}
    for r in res:
        kinds.setdefault(r["kind"], []).append(r)
    table = {}
    for kind, rs in kinds.items():
        ratios = [r["fup_ratio"] for r in rs]
        table[kind] = {"cases": len(rs), "named10": sum(r["named10"] for r in rs) / len(rs),
                       "named_any": sum(bool(r["named"]) for r in rs) / len(rs),
                       "followups_mean": float(np.mean([r["followups"] for r in rs])),
                       "stopped_after_first": sum(r["stopped_after_first"] for r in rs) / len(rs),
                       "fup_ratio_max": max(ratios), "fup_ratio_mean": float(np.mean(ratios)),
                       "errors": sum(1 for r in rs if r["error"])}
    with_fup = [r["fup_ratio"] for r in res if r["followups"]]
    unamb = [r for r in res if r["kind"] == "unambiguous"]
    figs = {"cases": len(res),
            "named10": sum(r["named10"] for r in res) / len(res),
            "named10_confusable": (sum(r["named10"] for r in res if r["kind"] != "unambiguous")
                                   / max(1, sum(1 for r in res if r["kind"] != "unambiguous"))),
            "stopped": (sum(r["stopped_after_first"] for r in unamb) / len(unamb)) if unamb else None,
            "fup_ratio_max": max([r["fup_ratio"] for r in res] or [0.0]),
            "fup_ratio_mean_with_followups": float(np.mean(with_fup)) if with_fup else 0.0,
            "fup_ratio_mean_all": float(np.mean([r["fup_ratio"] for r in res])),
            "errors": sum(1 for r in res if r["error"])}
    return table, figs


def print_report(table, figs, res):
    print(f"\n{'kind':27s} {'cases':>5s} {'named10':>8s} {'named':>6s} {'fups':>5s} {'stop1':>6s} {'ratio max':>9s} {'mean':>6s} {'err':>4s}")
    for kind, t in table.items():
        print(f"{kind:27s} {t['cases']:5d} {100 * t['named10']:7.0f}% {100 * t['named_any']:5.0f}% {t['followups_mean']:5.2f} "
              f"{100 * t['stopped_after_first']:5.0f}% {t['fup_ratio_max']:9.2f} {t['fup_ratio_mean']:6.2f} {t['errors']:4d}")
    print(f"{'total':27s} {figs['cases']:5d} {100 * figs['named10']:7.0f}%")
    print("\nfigures of the issue:")
    print(f"  named within 10 % after <= {MAX_FOLLOWUPS} follow-ups: {100 * figs['named10']:.1f} % "
          f"(confusable kinds {100 * figs['named10_confusable']:.1f} %; target >= {100 * TARGETS['named']:.0f} %)")
    if figs["stopped"] is not None:
        print(f"  unambiguous cases stopping after the first run: {100 * figs['stopped']:.1f} % (target >= {100 * TARGETS['stopped']:.0f} %)")
    print(f"  follow-up bench time / first run's: max {figs['fup_ratio_max']:.2f}x, mean {figs['fup_ratio_mean_with_followups']:.2f}x "
          f"over cases with a follow-up, {figs['fup_ratio_mean_all']:.2f}x over all (target <= {TARGETS['fup_ratio_max']:.1f}x)")
    missed = [r for r in res if not r["named10"] or (r["kind"] == "unambiguous" and not r["stopped_after_first"])]
    if missed:
        print("\ncases missed:")
        for r in missed:
            print("  " + line(r))
            for rd in r["rounds"]:
                if not rd["designed"]:
                    print(f"      round {rd['round']}: design exit 1: {rd['stderr'][:300]}")
            fin = r.get("final") or {}
            if fin:
                print(f"      final: verdict {fin['verdict']}, causes {json.dumps(fin['causes'])[:400]}, ambiguous {fin['ambiguous']}, "
                      f"open {fin['open']}")


def evaluate(a):
    work = a.work or f"/tmp/benchsim-investigate-{a.seed}"
    os.makedirs(work, exist_ok=True)
    kinds = a.kinds.split(",") if a.kinds else DEFAULT_KINDS
    jobs = [(kind, k) for kind in kinds for k in range(a.cases)]
    res = []
    with concurrent.futures.ProcessPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        futs = [ex.submit(run_case, a.fpss_stand, work, kind, k, a.seed, a.budget_x) for kind, k in jobs]
        for f in futs:
            r = f.result()
            res.append(r)
            print(line(r), file=sys.stderr, flush=True)
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("eval")
    e.add_argument("--fpss-stand", required=True)
    e.add_argument("--cases", type=int, default=4, help="cases per kind")
    e.add_argument("--seed", type=int, default=1)
    e.add_argument("--work")
    e.add_argument("--kinds", help="comma-separated subset of: " + ", ".join(KINDS))
    e.add_argument("--jobs", type=int, default=1, help="cases run at once")
    e.add_argument("--json", dest="json_out", help="write the per-case results here")
    e.add_argument("--budget-x", type=float, help="exploration only: design --max-bench-s this many times the first "
                                                  "run's bench time, each round (default: design's own budget)")
    e.add_argument("--assert", dest="check", action="store_true", help="exit 1 when a target is missed")
    a = ap.parse_args()
    st = os.stat(a.fpss_stand)
    binary = {"path": a.fpss_stand, "mtime": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(st.st_mtime)), "size": st.st_size}
    res = evaluate(a)
    table, figs = summarise(res)
    figs["binary"] = binary
    if os.stat(a.fpss_stand).st_mtime != st.st_mtime:
        figs["binary_changed_during_run"] = True
        print("warning: the fpss-stand binary was replaced during the run: the figures mix two builds", file=sys.stderr)
    print(f"fpss-stand: {binary['path']} of {binary['mtime']}")
    print_report(table, figs, res)
    if a.json_out:
        with open(a.json_out, "w") as f:
            json.dump({"figures": figs, "kinds": table, "cases": res}, f, indent=1, default=float)
    if a.check:
        missed = []
        if figs["named10"] < TARGETS["named"]:
            missed.append(f"named within 10 % {figs['named10']:.3f} < {TARGETS['named']}")
        if figs["stopped"] is not None and figs["stopped"] < TARGETS["stopped"]:
            missed.append(f"stopped after the first run {figs['stopped']:.3f} < {TARGETS['stopped']}")
        if figs["fup_ratio_max"] > TARGETS["fup_ratio_max"]:
            missed.append(f"follow-up bench time {figs['fup_ratio_max']:.2f}x > {TARGETS['fup_ratio_max']}x")
        if figs["errors"]:
            missed.append(f"{figs['errors']} case(s) could not run")
        if missed:
            print("targets missed: " + "; ".join(missed), file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
