#!/usr/bin/env python3
"""An independent two-way crossed ANOVA gauge R&R (AIAG MSA 4th ed.) of an MSA.json's `values`.

Written from the AIAG formulas, not from calib/msa.cpp: prints, per quantity, JSON with ev, av,
interaction, grr, pv, tv, grr_percent_tv and grr_percent_tolerance (6 GRR / tolerance)."""
import json
import sys

import numpy as np


def gauge(y, tolerance):
    y = np.asarray(y, dtype=float)  # parts x appraisers x repeats
    p, o, r = y.shape
    grand = y.mean()
    part_means = y.mean(axis=(1, 2))
    appr_means = y.mean(axis=(0, 2))
    cell_means = y.mean(axis=2)
    ss_p = o * r * ((part_means - grand) ** 2).sum()
    ss_o = p * r * ((appr_means - grand) ** 2).sum()
    ss_cells = r * ((cell_means - grand) ** 2).sum()
    ss_po = ss_cells - ss_p - ss_o
    ss_e = ((y - cell_means[:, :, None]) ** 2).sum()
    ms_p, ms_o = ss_p / (p - 1), ss_o / (o - 1)
    ms_po, ms_e = ss_po / ((p - 1) * (o - 1)), ss_e / (p * o * (r - 1))
    var_e = ms_e
    var_po = max(0.0, (ms_po - ms_e) / r)
    var_o = max(0.0, (ms_o - ms_po) / (p * r))
    var_p = max(0.0, (ms_p - ms_po) / (o * r))
    grr = np.sqrt(var_e + var_o + var_po)
    tv = np.sqrt(grr ** 2 + var_p)
    out = {"ev": float(np.sqrt(var_e)), "av": float(np.sqrt(var_o)), "interaction": float(np.sqrt(var_po)),
           "grr": float(grr), "pv": float(np.sqrt(var_p)), "tv": float(tv),
           "grr_percent_tv": float(100 * grr / tv) if tv > 0 else 0.0}
    out["grr_percent_tolerance"] = float(600 * grr / tolerance) if tolerance else None
    return out


def main():
    msa = json.load(open(sys.argv[1]))
    print(json.dumps({name: gauge(q["values"], q["tolerance"]) for name, q in msa["quantities"].items()}))


if __name__ == "__main__":
    main()
