"""CPU time of a run from Python vs the same run by the CLI (same scenario and seed, 1 thread).

    python bench/cost_vs_cli.py [CLI] [RUNS] [STEPS] [REPEATS]

Each measurement is a child process (CPU time user + sys from getrusage), best of REPEATS:
`edgekf run S --out D --threads 1` against `python -c "edgekf.run(S, threads=1).save(D)"`
(interpreter start and `import edgekf` included), plus the time of `edgekf.run` alone, measured
in-process. The scenario has no figures, so both write the same tables.
"""

import os
import pathlib
import resource
import subprocess
import sys
import tempfile

SCENARIO = """
name = "cost"
estimators = ["none", "mle", "rkf", "jrkf", "crkf"]
[framework]
preset = "hexagon"
[sim]
dt = 0.001
steps = {steps}
runs = {runs}
seed = 5
samples_per_step = 10
every = 10
[noise]
sigma_w = 0.001
sigma_v = 0.1
meas_corr = 0.3
"""


def child_cpu(cmd):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    root = pathlib.Path(__file__).resolve().parents[2]
    cli = sys.argv[1] if len(sys.argv) > 1 else str(root / "target" / "release" / "edgekf")
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    steps = int(sys.argv[3]) if len(sys.argv) > 3 else 20000
    repeats = int(sys.argv[4]) if len(sys.argv) > 4 else 3
    with tempfile.TemporaryDirectory() as tmp:
        s = pathlib.Path(tmp) / "cost.toml"
        s.write_text(SCENARIO.format(runs=runs, steps=steps))
        out_cli, out_py = os.path.join(tmp, "cli"), os.path.join(tmp, "py")
        py_code = (
            "import edgekf, time, sys;"
            f"t = time.process_time(); r = edgekf.run({str(s)!r}, threads=1);"
            "sys.stderr.write(repr(time.process_time() - t));"
            f"r.save({out_py!r})"
        )
        c, p, inner = [], [], []
        for _ in range(repeats):
            c.append(child_cpu([cli, "run", str(s), "--out", out_cli, "--threads", "1"]))
            p.append(child_cpu([sys.executable, "-c", py_code]))
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = subprocess.run([sys.executable, "-c", py_code], check=True, capture_output=True,
                               text=True)
            inner.append(float(r.stderr.strip().splitlines()[-1]))
        same = (pathlib.Path(out_cli) / "metrics.csv").read_bytes() == (
            pathlib.Path(out_py) / "metrics.csv"
        ).read_bytes()
    c, p, i = min(c), min(p), min(inner)
    print(f"scenario: hexagon, 5 estimators, {runs} runs x {steps} steps, --threads 1, best of {repeats}")
    print(f"  CLI `edgekf run`:                {c:7.3f} s CPU")
    print(f"  Python process (run + save):     {p:7.3f} s CPU  ({100 * (p / c - 1):+.1f} %)")
    print(f"  edgekf.run alone (in-process):   {i:7.3f} s CPU  ({100 * (i / c - 1):+.1f} % of the CLI process)")
    print(f"  metrics.csv identical: {same}")


if __name__ == "__main__":
    main()
