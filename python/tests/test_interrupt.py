"""Ctrl-C at any moment of a run's life ends it within 2 s: a few hundred SIGINTs at random
moments of short runs and saves (set-up, simulation, writing) in two interpreters at once, and
a few during the interpreter's start and `import edgekf`. Each check waits on a condition (the
signal sent, the child's end), never on a fixed sleep; the randomness has a fixed seed."""

import json
import os
import random
import signal
import subprocess
import sys
import time

STRESS = r"""
import json, os, random, signal, sys, threading, time
import edgekf

small, root, cases = sys.argv[1], sys.argv[2], int(sys.argv[3])
random.seed(int(sys.argv[4]))
kw = dict(runs=4, steps=400, every=4, threads=1)
t = time.perf_counter()
edgekf.run(small, **kw).save(os.path.join(root, "reference"))
life = time.perf_counter() - t
worst, seen = 0.0, {"finished": 0, "interrupted": 0, "nothing on disk": 0, "all on disk": 0}
for i in range(cases):
    out = os.path.join(root, f"o{i}")
    sent = []
    def fire():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)
    timer = threading.Timer(random.uniform(0.0, 1.2 * life), fire)
    try:
        timer.start()
        edgekf.run(small, **kw).save(out)
        seen["finished"] += 1
        # The run ended first: wait for the signal to land here (within the overall limit).
        deadline = time.perf_counter() + 5.0
        while time.perf_counter() < deadline:
            time.sleep(0.0005)
        raise SystemExit(f"case {i}: no KeyboardInterrupt within 5 s of the end")
    except KeyboardInterrupt:
        latency = time.perf_counter() - sent[0]
        worst = max(worst, latency)
        if latency > 2.0:
            raise SystemExit(f"case {i}: KeyboardInterrupt {latency:.2f} s after the SIGINT")
    finally:
        timer.join()
    seen["interrupted"] += 1
    # What is on disk is nothing or the whole study (the save is atomic).
    files = sorted(f for f in os.listdir(out)) if os.path.isdir(out) else []
    if any(f.startswith(".") for f in files):
        raise SystemExit(f"case {i}: temporaries left: {files}")
    if files:
        with open(os.path.join(out, "provenance.json")) as f:
            listed = json.load(f)["files"]
        if listed != files:
            raise SystemExit(f"case {i}: {files} on disk, {listed} listed")
        seen["all on disk"] += 1
    else:
        seen["nothing on disk"] += 1
print(json.dumps({"worst": worst, "life": life, "seen": seen}))
"""


def test_ctrl_c_at_random_moments_of_runs_and_saves(small, tmp_path):
    # Two interpreters at once, half the cases each (each runs one thread): the suite's
    # longest test took 21 s alone.
    cases = int(os.environ.get("EDGEKF_INTERRUPT_CASES", "240"))
    halves = [cases // 2, cases - cases // 2]
    procs = []
    for k, n in enumerate(halves):
        root = tmp_path / f"interpreter{k}"
        root.mkdir()
        procs.append(subprocess.Popen(
            [sys.executable, "-c", STRESS, str(small), str(root), str(n), str(2026 + k)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        ))
    seen = {}
    try:
        for p, n in zip(procs, halves):
            out, err = p.communicate(timeout=600)
            assert p.returncode == 0, out + err
            r = json.loads(out.strip().splitlines()[-1])
            assert r["seen"]["interrupted"] == n, r
            assert r["worst"] < 2.0, r
            for key, count in r["seen"].items():
                seen[key] = seen.get(key, 0) + count
    finally:
        # A failed check leaves no interpreter running.
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.communicate()
    # The signals landed before and after the files were written.
    assert seen["nothing on disk"] > 0 and seen["all on disk"] > 0, seen


def test_ctrl_c_while_the_interpreter_starts_and_imports(small):
    """SIGINT during start-up and `import edgekf` (a KeyboardInterrupt there, or the default
    action before Python installs its handler): the child ends within 2 s every time."""
    code = (
        "import edgekf; "
        f"edgekf.run({str(small)!r}, runs=4, steps=200_000, every=1000, threads=1)"
    )
    # How long the start and import take here (the signals fall in 0..1.5× of it).
    t = time.monotonic()
    subprocess.run([sys.executable, "-c", "import edgekf"], check=True)
    start = time.monotonic() - t
    rng = random.Random(7)
    for _ in range(int(os.environ.get("EDGEKF_INTERRUPT_STARTS", "16"))):
        p = subprocess.Popen(
            [sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        delay = rng.uniform(0.0, 1.5 * start)
        deadline = time.monotonic() + delay
        while time.monotonic() < deadline and p.poll() is None:
            time.sleep(0.001)
        p.send_signal(signal.SIGINT)
        sent = time.monotonic()
        try:
            _, err = p.communicate(timeout=2.0)
        except subprocess.TimeoutExpired as e:
            # The one window no package can close: CPython dropped the KeyboardInterrupt in
            # an import's weakref callback before `import edgekf` began (the report is on
            # stderr). A user presses Ctrl-C again: that one must end the child. What
            # `communicate` read before its timeout is in the exception, the rest still in
            # the pipe (reading only the pipe missed the report once, in CI under load).
            err = (e.stderr or b"") + _stderr_so_far(p)
            if not _dropped_by_cpython(err):
                p.kill()
                p.communicate()
                raise AssertionError(
                    f"not ended within 2 s of a SIGINT {delay:.3f} s into its start: {err!r}"
                )
            p.send_signal(signal.SIGINT)
            sent = time.monotonic()
            try:
                p.communicate(timeout=2.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.communicate()
                raise AssertionError(f"a second SIGINT did not end it either: {err!r}")
        assert time.monotonic() - sent < 2.0
        assert p.returncode in (1, -signal.SIGINT), (p.returncode, err)


def _stderr_so_far(p):
    """What the child has written to stderr until now (it is still running)."""
    os.set_blocking(p.stderr.fileno(), False)
    try:
        return p.stderr.read() or b""
    finally:
        os.set_blocking(p.stderr.fileno(), True)


def _dropped_by_cpython(err):
    return b"Exception ignored in" in err and b"KeyboardInterrupt" in err


# A SIGINT whose KeyboardInterrupt is raised inside a weakref callback: CPython prints it
# ("Exception ignored in: ...") and drops it; the main loop then runs on.
DROPPED = r"""
import os, signal, sys, time, weakref
if sys.argv[1] == "with":
    import edgekf
class Thing:
    pass
thing = Thing()
ref = weakref.ref(thing, lambda _: os.kill(os.getpid(), signal.SIGINT))
try:
    del thing
    end = time.monotonic() + 3.0
    while time.monotonic() < end:
        pass
    print("dropped")
except KeyboardInterrupt:
    print("raised again")
"""


def test_a_ctrl_c_that_cpython_drops_is_raised_again_once_edgekf_is_imported():
    """Without edgekf the interpreter drops the interrupt (the case is real); with it imported,
    the KeyboardInterrupt reaches the main code, and the interpreter's report is kept."""
    for arm, expected in (("without", "dropped"), ("with", "raised again")):
        p = subprocess.run(
            [sys.executable, "-c", DROPPED, arm], capture_output=True, timeout=60
        )
        assert p.returncode == 0, (arm, p.stdout, p.stderr)
        assert p.stdout.decode().strip() == expected, (arm, p.stdout, p.stderr)
        assert _dropped_by_cpython(p.stderr), (arm, p.stderr)
