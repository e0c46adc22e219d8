#!/usr/bin/env python3
"""Compares two edgekf-format metrics.csv files (e.g. Rust vs the NumPy reference).

- cov_trace is deterministic: maximum relative difference over all common reported steps, and
  over the steady-state window.
- est_error_sq, est_error and procrustes: steady-state means over a time window (default 15-30 s;
  procrustes 25-30 s as in the user guide) and the z-score of the difference.  The two files use
  different random numbers, so they agree only statistically.  Standard error: when file B's
  directory holds the reference's steady.json (per-run time averages over the window, whose spread
  across independent runs is the honest standard error of the windowed mean), that SE is used for
  both files (same model, same number of runs): z = (A - B) / (sqrt(2) SE_B).  Otherwise a
  batch-means SE from each file's per-step means (it underestimates the error of slowly varying
  metrics such as procrustes).
- the consistency ratio mean eps^2 / cov_trace per file.

Several seeds: pass comma-separated lists, e.g. ``compare.py rs1/metrics.csv,rs2/metrics.csv,...
py1/metrics.csv,py2/metrics.csv,...``: the windowed means are averaged over the files of each side
and the standard errors come from the spread across the files (seeds), which needs no assumption
about correlation in time.

Usage: python compare.py RUST/metrics.csv PY/metrics.csv [--t0 15 --t1 30 --batches 10]
"""
from __future__ import annotations

import argparse
import collections
import csv
import math


def load(path):
    d = collections.defaultdict(dict)
    with open(path) as f:
        for r in csv.DictReader(f):
            d[(r["estimator"], r["metric"])][int(r["step"])] = (
                float(r["time"]), float(r["mean"]), float(r["std"]))
    return d


def window(series, t0, t1):
    return [v[1] for k, v in sorted(series.items()) if t0 <= v[0] <= t1]


def batch_mean(vals, nb):
    n = len(vals) // nb
    b = [sum(vals[i * n:(i + 1) * n]) / n for i in range(nb)]
    mu = sum(b) / nb
    se = math.sqrt(sum((x - mu) ** 2 for x in b) / (nb - 1) / nb)
    return mu, se


def steady_se(path):
    import json
    import os
    p = os.path.join(os.path.dirname(os.path.abspath(path)), "steady.json")
    if not os.path.exists(p):
        return None
    with open(p) as f:
        return json.load(f)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--t0", type=float, default=15.0)
    ap.add_argument("--t1", type=float, default=30.0)
    ap.add_argument("--proc-t0", type=float, default=25.0)
    ap.add_argument("--batches", type=int, default=10)
    a = ap.parse_args(argv)
    if "," in a.a or "," in a.b:
        return multi(a)
    A, B = load(a.a), load(a.b)
    SB = steady_se(a.b)
    ests = [e for e, m in A if m == "cov_trace" and (e, m) in B]
    print(f"cov_trace (deterministic): max relative difference, all steps | {a.t0}-{a.t1} s")
    for e in ests:
        sa, sb = A[(e, "cov_trace")], B[(e, "cov_trace")]
        ks = sorted(set(sa) & set(sb))
        rel = [abs(sa[k][1] - sb[k][1]) / abs(sa[k][1]) for k in ks]
        relw = [r for k, r in zip(ks, rel) if a.t0 <= sa[k][0] <= a.t1]
        print(f"  {e:6s} {max(rel):.2e} | {max(relw) if relw else float('nan'):.2e}"
              f"   steady {sum(window(sa, a.t0, a.t1)) / max(1, len(window(sa, a.t0, a.t1))):.6e}")
    for met, t0 in (("est_error_sq", a.t0), ("est_error", a.t0), ("procrustes", a.proc_t0)):
        key = f"{met}@{t0:g}-{a.t1:g}"
        use_runs = SB is not None and all(key in SB.get(e, {}) for e in ests)
        how = "per-run SE of file B for both" if use_runs else "batch-means SE"
        print(f"{met}: steady mean over {t0}-{a.t1} s ({how}), file A | file B | z")
        for e in ests:
            va, vb = window(A[(e, met)], t0, a.t1), window(B[(e, met)], t0, a.t1)
            (ma, sea), (mb, seb) = batch_mean(va, a.batches), batch_mean(vb, a.batches)
            if use_runs:
                sea = seb = SB[e][key][1]
            z = (ma - mb) / math.sqrt(sea ** 2 + seb ** 2)
            print(f"  {e:6s} {ma:.5e} ({sea:.1e}) | {mb:.5e} ({seb:.1e}) | z = {z:+.2f}"
                  f"  (B/A - 1 = {mb / ma - 1:+.2%})")
    print(f"consistency mean eps^2 / cov_trace over {a.t0}-{a.t1} s: file A | file B")
    for e in ests:
        out = []
        for X in (A, B):
            ve = window(X[(e, "est_error_sq")], a.t0, a.t1)
            vc = window(X[(e, "cov_trace")], a.t0, a.t1)
            out.append(sum(ve) / sum(vc))
        print(f"  {e:6s} {out[0]:.4f} | {out[1]:.4f}")


def multi(a):
    fa, fb = a.a.split(","), a.b.split(",")
    As, Bs = [load(f) for f in fa], [load(f) for f in fb]
    ests = [e for e, m in As[0] if m == "cov_trace" and (e, m) in Bs[0]]
    print(f"{len(fa)} file(s) A vs {len(fb)} file(s) B; SE from the spread across files")
    for met, t0 in (("est_error_sq", a.t0), ("est_error", a.t0), ("procrustes", a.proc_t0)):
        print(f"{met}: steady mean over {t0}-{a.t1} s, A | B | z")
        for e in ests:
            va = [sum(window(X[(e, met)], t0, a.t1)) / len(window(X[(e, met)], t0, a.t1)) for X in As]
            vb = [sum(window(X[(e, met)], t0, a.t1)) / len(window(X[(e, met)], t0, a.t1)) for X in Bs]
            ma, mb = sum(va) / len(va), sum(vb) / len(vb)
            var = lambda v, m: sum((x - m) ** 2 for x in v) / (len(v) - 1) / len(v) if len(v) > 1 else 0.0
            sea, seb = math.sqrt(var(va, ma)), math.sqrt(var(vb, mb))
            z = (ma - mb) / math.sqrt(sea ** 2 + seb ** 2)
            print(f"  {e:6s} {ma:.5e} ({sea:.1e}) | {mb:.5e} ({seb:.1e}) | z = {z:+.2f}"
                  f"  (B/A - 1 = {mb / ma - 1:+.2%})")


if __name__ == "__main__":
    main()
