"""Notebook-style example: run a scenario from Python, look at the numbers, save a figure.

    python examples/error_vs_time.py [OUT_DIR]

Runs a short version of the EUSIPCO study (hexagon, N = 10, 60 directed edges), plots the
estimation error ε_k (thesis eq. 4.34) of each estimator with a ±1 std band across runs, and
saves `error_vs_time.png` in OUT_DIR (default: `edgekf-example`) and the CLI's files of the
study in OUT_DIR/eusipco (a study's folder holds only the files it wrote).
"""

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import edgekf  # noqa: E402

out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "edgekf-example")
root = pathlib.Path(__file__).resolve().parents[2]

# 1. Run: the shipped scenario, fewer runs and steps than the paper.
res = edgekf.run(root / "scenarios" / "eusipco.toml", runs=10, steps=3000, seed=1)
print(res)

# 2. Look: mean ± std of ε_k per estimator.
fig, ax = plt.subplots(figsize=(6, 4))
for est in res.estimators:
    t, mean, std = res.metric(est, "est_error")
    ax.plot(t, mean, label=est)
    ax.fill_between(t, mean - std, mean + std, alpha=0.2)
    print(f"{est:>5}: final ε = {mean[-1]:.4f} ± {std[-1]:.4f}")
ax.set(xscale="log", yscale="log", xlabel="time [s]", ylabel="estimation error ε_k [m]",
       title=f"{res.scenario['name']}: {res.runs} runs")
ax.legend()

# 3. Keep: the figure, and the CLI's files in a folder of their own (outputs never mix: a
# study's folder holds only what the study wrote, so our figure goes beside it, not in it).
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "error_vs_time.png", dpi=100)
res.save(out / "eusipco")
print(f"wrote {out / 'error_vs_time.png'} and the study's files in {out / 'eusipco'}")
