#!/usr/bin/env python3
"""Real packet loss against the simulator's comm model (issue 24, point 3).

For each loss rate p, runs `edgekf swarm` R times (seeds S, S+1, …) inside a network namespace
whose nftables rule drops p of the mesh's UDP packets (scripts/swarm/lossy-netns.sh), and
`edgekf run --runs 1` of the same scenario with `p_fail = p` for the same seeds. Per run: the
window mean of `est_error` and the consistency mean ε² / mean cov_trace over the window. Prints
the means ± standard errors, their difference in standard errors (Welch), and the loss the
agents measured (network.csv).

    sudo python3 scripts/swarm/study.py --edgekf target/release/edgekf \
        --scenario scenarios/thesis-fig6.2.toml --p 25 50 --runs 10 --steps 10000 --window 5 10

Only the first `rkf-ar` estimator of the scenario is kept, with `p_fail` set to p: the
simulator draws its failures with it; the swarm runs with `--comm-failures network`, so its
losses are the network's alone and `p_fail` is only the filters' model of them. (Until
2026-12-07 the swarm also drew the scenario's failures, so its filters lost 1 − (1 − p)² of the
inputs: 44 % at p = 25 %.)
"""

import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
NETNS = os.path.join(HERE, "lossy-netns.sh")


def scenario_for(text, p, steps):
    """The scenario with one rkf-ar estimator at p_fail = p (in %), and `steps` steps."""
    text = re.sub(r"(?ms)^estimators = \[.*?^\]\n", "", text)
    text = re.sub(r"(?ms)^\[\[plots\]\].*", "", text)
    est = f'estimators = [{{ kind = "rkf-ar", p_fail = {p / 100:.4f}, label = "rkf-ar" }}]\n'
    text = re.sub(r"(?m)^description = .*$", lambda m: m.group(0) + "\n" + est, text, count=1)
    text = re.sub(r"(?m)^steps = \d+", f"steps = {steps}", text)
    text = re.sub(r"(?m)^runs = \d+", "runs = 1", text)
    return text


METRICS = ["est_error", "consistency", "cov_trace"]


def window_stats(metrics_csv, window):
    """(mean est_error, mean ε² / mean cov_trace, mean cov_trace) over the window [t0, t1] of
    one run."""
    err, cov = [], []
    with open(metrics_csv) as f:
        for row in csv.DictReader(f):
            t = float(row["time"])
            if not (window[0] <= t <= window[1]):
                continue
            if row["metric"] == "est_error":
                err.append(float(row["mean"]))
            elif row["metric"] == "cov_trace":
                cov.append(float(row["mean"]))
    e2 = sum(e * e for e in err) / len(err)
    c = sum(cov) / len(cov)
    return sum(err) / len(err), e2 / c, c


def paired(xs, ys):
    """Mean ± standard error over the pairs of 100 (x / y − 1), in %."""
    return mean_se([100.0 * (x / y - 1.0) for x, y in zip(xs, ys)])


def mean_se(xs):
    m = sum(xs) / len(xs)
    v = sum((x - m) ** 2 for x in xs) / (len(xs) - 1)
    return m, math.sqrt(v / len(xs))


def loss_of(network_csv):
    sent = missing = lost = 0
    with open(network_csv) as f:
        for row in csv.DictReader(f):
            if row["channel"] == "input":
                s, r = int(row["sent"]), int(row["received"])
                sent += s
                missing += s - r
                lost += int(row["lost"])
    return sent, missing, lost


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr}")
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--edgekf", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--p", type=int, nargs="+", default=[25, 50])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--steps", type=int, default=10000)
    ap.add_argument("--window", type=float, nargs=2, default=[5.0, 10.0])
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--grace-ms", type=int, default=3)
    ap.add_argument("--json", help="write the numbers here")
    a = ap.parse_args()
    base = open(a.scenario).read()
    tmp = tempfile.mkdtemp(prefix="edgekf-loss-study-")
    results = {}
    for p in a.p:
        sc = os.path.join(tmp, f"p{p}.toml")
        with open(sc, "w") as f:
            f.write(scenario_for(base, p, a.steps))
        # The simulator also at 1 − (1 − p)², the loss of a swarm that drew the scenario's
        # failures on top of the network's: how far the outcomes move with the loss rate.
        p2 = 100.0 * (1.0 - (1.0 - p / 100.0) ** 2)
        sc2 = os.path.join(tmp, f"p{p}-twice.toml")
        with open(sc2, "w") as f:
            f.write(scenario_for(base, p2, a.steps))
        swarm, sim, sim2, tot = [], [], [], [0, 0, 0]
        for r in range(a.runs):
            seed = str(a.seed + r)
            out_s = os.path.join(tmp, f"p{p}-swarm-{r}")
            out_r = os.path.join(tmp, f"p{p}-run-{r}")
            out_2 = os.path.join(tmp, f"p{p}-twice-{r}")
            run([NETNS, str(p), "--", a.edgekf, "swarm", sc, "--out", out_s, "--seed", seed,
                 "--lossy", "--grace-ms", str(a.grace_ms), "--comm-failures", "network",
                 "--after-ready", f"{NETNS} --rule {p}"])
            run([a.edgekf, "run", sc, "--out", out_r, "--seed", seed])
            run([a.edgekf, "run", sc2, "--out", out_2, "--seed", seed])
            swarm.append(window_stats(os.path.join(out_s, "metrics.csv"), a.window))
            sim.append(window_stats(os.path.join(out_r, "metrics.csv"), a.window))
            sim2.append(window_stats(os.path.join(out_2, "metrics.csv"), a.window))
            for i, v in enumerate(loss_of(os.path.join(out_s, "network.csv"))):
                tot[i] += v
            print(f"p = {p} %, run {r}: swarm {swarm[-1]}, simulator {sim[-1]}", file=sys.stderr)
        row = {}
        for i, name in enumerate(METRICS):
            xs, ys, zs = ([x[i] for x in v] for v in (swarm, sim, sim2))
            ms, ss = mean_se(xs)
            mr, sr = mean_se(ys)
            row[name] = {"swarm": [ms, ss], "simulator": [mr, sr], "z": (ms - mr) / math.hypot(ss, sr),
                         "paired_pct": paired(xs, ys), "simulator_at_p2_paired_pct": paired(zs, ys)}
        sent, missing, lost = tot
        q = missing / sent
        row["loss"] = {"sent": sent, "not_received": missing, "lost_to_filters": lost,
                       "rate": q, "binomial_se": math.sqrt(q * (1 - q) / sent), "p2": p2}
        results[str(p)] = row
        print(f"p = {p} %: network loss {100 * q:.2f} ± {100 * row['loss']['binomial_se']:.2f} % "
              f"of {sent} inputs ({lost} lost to the filters)")
        for name in METRICS:
            s, m = row[name]["swarm"], row[name]["simulator"]
            d, d2 = row[name]["paired_pct"], row[name]["simulator_at_p2_paired_pct"]
            print(f"  {name}: swarm {s[0]:.5g} ± {s[1]:.2g}, simulator {m[0]:.5g} ± {m[1]:.2g}, "
                  f"difference {row[name]['z']:+.2f} SE; paired {d[0]:+.3f} ± {d[1]:.3f} %; "
                  f"simulator at {p2:.2f} % against {p} %: {d2[0]:+.3f} ± {d2[1]:.3f} %")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=2)


def departure_main(argv):
    """`--departure`: Li & Rajan S3 with a real crash. The swarm SIGKILLs agent A at t0
    (`--kill A@t0`); the simulator departs it at t0 (`faults.departures`). Per run: the window
    mean of `tracking_error` of each estimator."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--edgekf", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--agent", type=int, default=6)
    ap.add_argument("--at", type=float, default=10.0)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--window", type=float, nargs=2, default=[20.0, 30.0])
    ap.add_argument("--seed", type=int, default=2000)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    text = open(a.scenario).read()
    text = re.sub(r"(?ms)^\[sweep\].*?(?=^\[\[plots|\Z)", "", text)
    text = re.sub(r"(?ms)^\[\[plots\]\].*", "", text)
    text = re.sub(r"(?m)^runs = \d+", "runs = 1", text)
    with_dep = re.sub(r"(?m)^departures = .*$",
                      f"departures = [{{ agent = {a.agent}, at = {a.at} }}]", text)
    without = re.sub(r"(?ms)^\[faults\]\n.*?(?=^\[)", "", text)
    tmp = tempfile.mkdtemp(prefix="edgekf-departure-study-")
    sc_swarm, sc_sim = os.path.join(tmp, "swarm.toml"), os.path.join(tmp, "sim.toml")
    open(sc_swarm, "w").write(without)
    open(sc_sim, "w").write(with_dep)
    per = {}
    for r in range(a.runs):
        seed = str(a.seed + r)
        out_s, out_r = os.path.join(tmp, f"swarm-{r}"), os.path.join(tmp, f"run-{r}")
        run([a.edgekf, "swarm", sc_swarm, "--out", out_s, "--seed", seed,
             "--kill", f"{a.agent}@{a.at}"])
        run([a.edgekf, "run", sc_sim, "--out", out_r, "--seed", seed, "--allow-divergence"])
        for who, out in [("swarm", out_s), ("simulator", out_r)]:
            for est, v in window_metric(os.path.join(out, "metrics.csv"), "tracking_error",
                                        a.window).items():
                per.setdefault(est, {}).setdefault(who, []).append(v)
        print(f"run {r} done", file=sys.stderr)
    results = {}
    for est, d in per.items():
        ms, ss = mean_se(d["swarm"])
        mr, sr = mean_se(d["simulator"])
        z = (ms - mr) / math.hypot(ss, sr) if math.hypot(ss, sr) > 0 else float("nan")
        results[est] = {"swarm": [ms, ss], "simulator": [mr, sr], "z": z}
        print(f"{est}: tracking_error over {a.window[0]:g}–{a.window[1]:g} s: swarm {ms:.4g} ± {ss:.2g}, "
              f"simulator {mr:.4g} ± {sr:.2g}, difference {z:+.2f} SE")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=2)


def window_metric(metrics_csv, metric, window):
    """Per estimator: the window mean of `metric` in one run."""
    acc = {}
    with open(metrics_csv) as f:
        for row in csv.DictReader(f):
            if row["metric"] == metric and window[0] <= float(row["time"]) <= window[1]:
                acc.setdefault(row["estimator"], []).append(float(row["mean"]))
    return {k: sum(v) / len(v) for k, v in acc.items()}


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--departure":
        departure_main(sys.argv[2:])
    else:
        main()
