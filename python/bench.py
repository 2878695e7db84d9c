"""The Python front's speed figures (docs/python.md, README): a benchmark script, not a test.

    cargo build --release && pip install ./python && python python/bench.py [--quick]

Prints, each as the median of REPEATS runs on this machine:
1. the same scene and seed from Python and from `agglo run`: the stepping time (the
   summary's wall_seconds: wall time inside the engine's steps) and the CPU time of the
   whole run (scene built, run, outputs: the CLI process's, less its start-up measured
   on a 2-body scene; a fresh interpreter's process time around `Simulation(...)` and
   `run()`), each with the Python/CLI ratio. On a shared machine the CPU ratio is the
   one to trust.
2. `import agglo`, in a fresh interpreter;
3. `sim.bodies()` at N = 10⁶ against the engine's own read of the bodies;
4. two simulations on two Python threads against the same two in series;
5. `Scenario.with_bodies` with 10⁶ bodies.
"""

import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

import agglo

ROOT = pathlib.Path(__file__).resolve().parents[1]
BIN = pathlib.Path(os.environ.get("AGGLO_BIN", ROOT / "target/release/agglo"))
QUICK = "--quick" in sys.argv
REPEATS = 3 if QUICK else 5

SCENES = [
    ("quick_demo", ROOT / "scenarios/quick_demo.json", {}),
    ("ballistic_aggregation 1e4", ROOT / "scenarios/ballistic_aggregation.json", {}),
    ("peer_bounce_10000", ROOT / "benches/peers/scenes/peer_bounce_10000.json", {}),
    ("peer_merge_100000", ROOT / "benches/peers/scenes/peer_merge_100000.json", {}),
]


def median(xs):
    return statistics.median(xs)


def child_cpu():
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def cli_run(path, settings):
    with tempfile.TemporaryDirectory() as d:
        summary = pathlib.Path(d) / "s.json"
        args = [str(BIN), "run", str(path), "-q", "--summary", str(summary)]
        for k, v in settings.items():
            args += ["--set", f"{k}={json.dumps(v)}"]
        start = child_cpu()
        subprocess.run(args, check=True, stdout=subprocess.DEVNULL)
        cpu = child_cpu() - start
        return json.loads(summary.read_text())["wall_seconds"], cpu


PYTHON_RUN = """
import json, sys, time
import agglo
path, settings = sys.argv[1], json.loads(sys.argv[2])
scenario = agglo.Scenario.load(path)
if settings:
    scenario = scenario.set(settings)
start = time.process_time()
sim = agglo.Simulation(scenario)
sim.run()
cpu = time.process_time() - start
print(json.dumps([sim.summary()["wall_seconds"], cpu]))
"""


def python_run(path, settings):
    """In a fresh interpreter, as the CLI runs in a fresh process: a long-lived process
    that had spawned the CLI ran the same scenes 1.3-1.45x slower with identical
    instruction counts (its memory, not the engine's work, differed)."""
    out = subprocess.run([sys.executable, "-c", PYTHON_RUN, str(path), json.dumps(settings)],
                         check=True, capture_output=True, text=True)
    return tuple(json.loads(out.stdout))


def cli_startup():
    """CPU seconds of an `agglo run` of a 2-body scene: the process's own start-up."""
    costs = []
    for _ in range(REPEATS):
        start = child_cpu()
        subprocess.run([str(BIN), "run", str(ROOT / "scenarios/two_body.json"), "-q"], check=True,
                       stdout=subprocess.DEVNULL)
        costs.append(child_cpu() - start)
    return median(costs)


def stepping():
    startup = cli_startup()
    print("1. the same scene from Python and from the CLI (median of", REPEATS, "interleaved pairs;"
          f" CLI start-up {startup * 1e3:.0f} ms of CPU subtracted)")
    print(f"   {'scene':28} {'CLI step s':>10} {'Py step s':>10} {'ratio':>6}   {'CLI cpu':>8} {'Py cpu':>8} {'ratio':>6}")
    for name, path, settings in SCENES:
        if QUICK and "100000" in name:
            continue
        cli, py = [], []
        for _ in range(REPEATS):
            cli.append(cli_run(path, settings))
            py.append(python_run(path, settings))
        cs, cw = median([c[0] for c in cli]), median([c[1] - startup for c in cli])
        ps, pw = median([p[0] for p in py]), median([p[1] for p in py])
        print(f"   {name:28} {cs:10.3f} {ps:10.3f} {ps / cs:6.3f}   {cw:8.3f} {pw:8.3f} {pw / cw:6.3f}")


def import_time():
    times = []
    for _ in range(REPEATS):
        out = subprocess.run(
            [sys.executable, "-c", "import time; t = time.perf_counter(); import agglo; print(time.perf_counter() - t)"],
            capture_output=True, text=True, check=True,
        )
        times.append(float(out.stdout))
    print(f"2. import agglo: {median(times) * 1e3:.0f} ms (median of {REPEATS}; max {max(times) * 1e3:.0f} ms)")


def million_bodies_scenario():
    s = agglo.Scenario.load(ROOT / "benches/peers/scenes/peer_merge_1000000.json")
    return s.set({"time.end": 1e-9})


def bodies_read():
    sim = agglo.Simulation(million_bodies_scenario())
    sim.step(1)
    rust, python = [], []
    for _ in range(REPEATS):
        rust.append(sim._sim._time_bodies_read())
        start = time.perf_counter()
        b = sim.bodies()
        python.append(time.perf_counter() - start)
    n = len(b)
    print(f"3. bodies() at N = {n}: {median(python):.3f} s against the engine's own read {median(rust):.3f} s "
          f"(ratio {median(python) / median(rust):.2f})")


def two_threads():
    s = agglo.Scenario.load(ROOT / "scenarios/ballistic_aggregation.json")

    def one(seed):
        agglo.Simulation(s, seed=seed).run()

    serial, parallel = [], []
    for _ in range(REPEATS):
        start = time.perf_counter()
        one(1), one(2)
        serial.append(time.perf_counter() - start)
        start = time.perf_counter()
        threads = [threading.Thread(target=one, args=(seed,)) for seed in (1, 2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        parallel.append(time.perf_counter() - start)
    print(f"4. two simulations (ballistic aggregation 1e4) on two Python threads: {median(parallel):.3f} s "
          f"against {median(serial):.3f} s in series (ratio {median(parallel) / median(serial):.2f}; {os.cpu_count()} cores)")


def with_bodies():
    s = agglo.Scenario.load(ROOT / "benches/peers/scenes/peer_merge_1000000.json")
    n_side = 100
    d = s.box.half_width
    spacing = 2 * d / n_side
    g = (np.arange(n_side) + 0.5) * spacing - d
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    position = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        t = s.with_bodies(position)
        times.append(time.perf_counter() - start)
    print(f"5. with_bodies with {len(position)} bodies: {median(times):.2f} s (checked; {t.cloud.count} bodies)")


if __name__ == "__main__":
    print(f"agglo {agglo.__version__}, {BIN}, {os.cpu_count()} cores")
    import_time()
    stepping()
    bodies_read()
    two_threads()
    with_bodies()
