#!/usr/bin/env python3
"""Every figure the docs quote from a deterministic run, made by one command.

    python3 docs/regenerate.py            # regenerate the files under docs/ in place
    python3 docs/regenerate.py --check    # run again, compare with what is committed (CI)
    python3 docs/regenerate.py --check --only study-p04 readme-report

Runs the release binary (target/release/agglo, built by the README's first command;
--agglo or $AGGLO_BIN to use another). In --check mode the outputs go to a temporary
directory and their deterministic content (statuses, steps, counts, growth — every column
but wall times) must equal the committed files; a change that moves a documented number
fails here until the docs are regenerated with this script (then rewrite the prose that
quotes the moved numbers: docs/studies.md, docs/inverse.md, README.md). Tasks marked slow
run only with --full (their commands are still the source of their files). Last, the
phrases of docs/studies.md and docs/inverse.md that quote these tables are made again
from the committed tables and looked for in the pages.

Standard library only: CI runs it with the machine's python3.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import os
import pathlib
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]

# Columns that hold wall-clock times (or derive from them): never compared.
TIMING_COLUMNS = {"wall_seconds", "wall_min", "wall_max", "seconds", "wall"}


class Task:
    """One documented output: how to make it and which files it leaves under docs/."""

    def __init__(self, name, make, files, slow=False, what="", needs_agglo=True):
        self.name = name
        self.needs_agglo = needs_agglo
        self.make = make  # (agglo, out_dir, check) -> None; writes files under out_dir
        self.files = files  # paths relative to docs/ (and README.md for the report)
        self.slow = slow
        self.what = what


def run(args, cwd=ROOT, **kw):
    """Run a command; its failure stops the script with its output."""
    shown = " ".join(str(a) for a in args)
    print(f"+ {shown}", flush=True)
    done = subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True, **kw)
    if done.returncode != 0:
        sys.stderr.write(done.stdout + done.stderr)
        raise SystemExit(f"failed ({done.returncode}): {shown}")
    return done.stdout


# ---- the tasks -----------------------------------------------------------------------


def study_accuracy(scenario, subdir, extra):
    def make(agglo, out, check):
        # Timed repeats only matter for the wall times, which --check does not compare.
        repeats = ["--repeats", "1"] if check else []
        run([agglo, "study", "accuracy", f"scenarios/{scenario}", "--out",
             out / "study" / subdir, *extra, *[a for a in repeats if "--repeats" not in extra]])
    return make


def study_stability(agglo, out, check):
    run([agglo, "study", "stability", "--out", out / "study" / "stability"])


README_REPORT_SCENARIO = "scenarios/paper2004_best.json"


def readme_report(agglo, out, check):
    text = run([agglo, "run", README_REPORT_SCENARIO])
    (out / "results").mkdir(parents=True, exist_ok=True)
    (out / "results" / "paper2004_best_report.txt").write_text(text)


# The peer clouds of README.md's and docs/speed.md's tables (T = 0.01 s; the 1e6 clouds
# take minutes each and are not here).
PEER_SCENES = ["peer_merge_1000", "peer_merge_10000", "peer_merge_100000",
               "peer_bounce_1000", "peer_bounce_10000"]
PEER_SCENES_SLOW = ["peer_bounce_100000"]


def peers(scenes, name):
    def make(agglo, out, check):
        rows = []
        with tempfile.TemporaryDirectory() as tmp:
            for scene in scenes:
                summary = pathlib.Path(tmp) / f"{scene}.json"
                run([agglo, "run", f"benches/peers/scenes/{scene}.json", "--summary", summary,
                     "-q"])
                import json
                s = json.loads(summary.read_text())
                c = s["counters"]
                rows.append([scene, s["initial_bodies"], s["final_bodies"], c["impacts"],
                             c["bonds"], c["bounces"], s["steps"]])
        (out / "results").mkdir(parents=True, exist_ok=True)
        with open(out / "results" / name, "w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["scene", "initial_bodies", "final_bodies", "impacts", "bonds",
                        "bounces", "steps"])
            w.writerows(rows)
    return make


def scan(args, subdir, stem):
    def make(agglo, out, check):
        target = out / "results" / "inverse" / subdir
        with tempfile.TemporaryDirectory() as tmp:
            run([agglo, "scan", *args, "--out", tmp, "-q"])
            target.mkdir(parents=True, exist_ok=True)
            for ext in ["csv", "png"]:
                shutil.copy(pathlib.Path(tmp) / f"scan.{ext}", target / f"{stem}.{ext}")
    return make


P02_SCAN = ["scenarios/paper2002_inverse.json", "--gene", "box.half_width"]


def readings(args, subdir, keep_runs=True):
    """`agglo study readings ARGS` into docs/study/readings/SUBDIR: the table (readings.md),
    one row per reading (readings.csv), one per run (runs.csv, unless too big to store) and
    the chart when the study draws one."""
    def make(agglo, out, check):
        target = out / "study" / "readings" / subdir
        with tempfile.TemporaryDirectory() as tmp:
            extra = args(agglo) if callable(args) else args
            run([agglo, "study", "readings", *extra, "--out", tmp])
            target.mkdir(parents=True, exist_ok=True)
            for name in ["readings.md", "readings.csv", "runs.csv", "readings.png",
                         "readings.svg"]:
                if name == "runs.csv" and not keep_runs:
                    continue
                if (pathlib.Path(tmp) / name).exists():
                    shutil.copy(pathlib.Path(tmp) / name, target / name)
    return make


def readings_files(subdir, keep_runs=True):
    names = ["readings.md", "readings.csv"] + (["runs.csv"] if keep_runs else [])
    return [f"study/readings/{subdir}/{n}" for n in names]


P04_READINGS = ["scenarios/paper2004_best.json", "--target-growth", "3.23",
                "--max-steps", "2000000"]
P02_READINGS = ["scenarios/paper2002_best.json", "--p02-steps", "200", "--target-growth", "2",
                "--max-steps", "2000000"]
# The D of each P02 readings table: "" is the scenario's own 1e-5 m.
P02_D = {"p02": [], "p02_D1e-6": ["--set", "box.half_width=1e-6"],
         "p02_D1e-4": ["--set", "box.half_width=1e-4"]}


def readings_but(scenario, left_out, args):
    """Every reading `agglo study readings SCENARIO --list` offers except the baseline (always
    run) and LEFT_OUT (which have tables of their own), then ARGS."""
    def choose(agglo):
        with tempfile.TemporaryDirectory() as tmp:
            listed = run([agglo, "study", "readings", scenario, "--out", tmp, "--list"])
        names = [line.split()[0] for line in listed.splitlines() if line.strip()]
        names = [n for n in names if n != "baseline" and n not in left_out]
        return [*args, "--only", ",".join(names)]
    return choose


def optimize(scenario, subdir, extra):
    """`agglo optimize` into docs/results/inverse/SUBDIR: its generations, best strings
    (with the closing check on fresh seeds) and best scenario, and the charts."""
    def make(agglo, out, check):
        target = out / "results" / "inverse" / subdir
        with tempfile.TemporaryDirectory() as tmp:
            run([agglo, "optimize", f"scenarios/{scenario}", "--out", tmp, *extra, "-q"])
            target.mkdir(parents=True, exist_ok=True)
            for name in ["generations.csv", "best.json", "best_scenario.json",
                         "convergence.png", "best_radii.png"]:
                shutil.copy(pathlib.Path(tmp) / name, target / name)
    return make


def optimize_files(subdir):
    return [f"results/inverse/{subdir}/{n}"
            for n in ["generations.csv", "best.json", "best_scenario.json"]]

SECONDS = re.compile(r"in [0-9.]+ s$", re.M)


def tutorial(agglo, out, check):
    """docs/python_tutorial.py with this interpreter (python/test.sh runs it in the
    test environment, where `import agglo` works); its one wall time masked."""
    text = run([sys.executable, "docs/python_tutorial.py"])
    (out / "results").mkdir(parents=True, exist_ok=True)
    (out / "results" / "python_tutorial.txt").write_text(SECONDS.sub("in X s", text))

TASKS = [
    Task("study-accuracy",
         study_accuracy("study_accuracy.json", "accuracy", []),
         ["study/accuracy/accuracy.csv", "study/accuracy/noise.csv"],
         what="docs/studies.md: the study scene's ladder"),
    Task("study-p04",
         study_accuracy("paper2004_best.json", "p04", ["--repeats", "1", "--target-growth", "3.23"]),
         ["study/p04/accuracy.csv", "study/p04/noise.csv"],
         what="docs/studies.md: P04's ladder and its table"),
    Task("study-stability", study_stability,
         ["study/stability/tunnelling_kinematic.csv", "study/stability/tunnelling_runs.csv",
          "study/stability/pair_map.csv", "study/stability/pair_map_softening.csv",
          "study/stability/cooling_map.csv"],
         what="docs/studies.md: missed collisions, pair and cooling maps"),
    Task("readme-report", readme_report, ["results/paper2004_best_report.txt"],
         what="README.md: what a run prints"),
    Task("peers", peers(PEER_SCENES, "peers.csv"), ["results/peers.csv"],
         what="README.md and docs/speed.md: collisions of the peer clouds"),
    Task("peers-slow", peers(PEER_SCENES_SLOW, "peers_slow.csv"), ["results/peers_slow.csv"],
         slow=True, what="docs/speed.md: the 1e5 bounce cloud (≈ 100 s)"),
    Task("scan-p02",
         scan([*P02_SCAN, "--from", "1e-6", "--to", "1e-2", "--points", "25", "--log"],
              "p02_d_sweep", "scan"),
         ["results/inverse/p02_d_sweep/scan.csv"],
         what="docs/inverse.md, docs/results/inverse: b_f/b0 against D"),
    Task("scan-p02-fine",
         scan([*P02_SCAN, "--from", "6e-6", "--to", "1.4e-5", "--points", "17"],
              "p02_d_sweep", "scan_fine"),
         ["results/inverse/p02_d_sweep/scan_fine.csv"],
         what="docs/results/inverse: the fine D grid"),
    *[Task(f"readings-{d.replace('_', '-').lower()}",
           readings(readings_but("scenarios/paper2002_best.json", ["every_contact"],
                                 [*P02_READINGS, "--seeds", "400", *D]), d),
           readings_files(d),
           what=f"docs/study/readings: P02's readings at D = {D[-1].split('=')[1] if D else '1e-5'} m")
      for d, D in P02_D.items()],
    *[Task(f"readings-every-contact-{d.replace('_', '-').lower()}",
           readings([*P02_READINGS, "--seeds", "400", "--only", "every_contact", *D],
                    f"every_contact/{d}"),
           readings_files(f"every_contact/{d}"),
           what="docs/study/readings: every contact of a step, P02")
      for d, D in P02_D.items()],
    *[Task(f"readings-p02-papers-as-printed-d{D}",
           readings([*P02_READINGS, "--seeds", "400", "--only", "papers_as_printed",
                     "--set", f"box.half_width={D}"], f"p02_papers_as_printed/D{D}"),
           readings_files(f"p02_papers_as_printed/D{D}"),
           what=f"docs/study/readings: P02 as printed, further out (D = {D} m)")
      for D in ["2e-4", "4e-4", "1e-3"]],
    Task("readings-p02-combinations",
         readings([*P02_READINGS, "--seeds", "100",
                   "--combine", "pair_hardness_harmonic|pair_hardness_arithmetic|pair_hardness_max",
                   "--combine", "bond_any_iterate",
                   "--combine", "solver_plain|solver_plain_cap_parity",
                   "--combine", "duration_p04", "--combine", "friction_constant",
                   "--combine", "cooling_p02_as_printed"], "p02_combinations", keep_runs=False),
         readings_files("p02_combinations", keep_runs=False),
         what="docs/study/readings: P02's 192 combinations (≈ 1 min)"),
    Task("readings-p04", readings(readings_but("scenarios/paper2004_best.json",
                                ["cooling_explicit", "every_contact"],
                                [*P04_READINGS, "--seeds", "40"]), "p04"), readings_files("p04"),
         slow=True, what="docs/study/readings: P04's readings, 40 seeds (≈ 3 min)"),
    Task("readings-p04-cooling-explicit",
         readings([*P04_READINGS, "--seeds", "2", "--only", "cooling_explicit"],
                  "p04_cooling_explicit"),
         readings_files("p04_cooling_explicit"), slow=True,
         what="docs/study/readings: P04 with explicit cooling (≈ 2 min)"),
    Task("readings-every-contact-p04",
         readings([*P04_READINGS, "--seeds", "40", "--only", "every_contact",
                   "--set", 'time.core="stepped"'], "every_contact/p04"),
         readings_files("every_contact/p04"),
         what="docs/study/readings: every contact of a step, P04 (≈ 25 s)"),
    Task("readings-p04-combinations",
         readings([*P04_READINGS, "--seeds", "12",
                   "--combine", "solver_plain|solver_plain_cap_parity",
                   "--combine", "contact_nearest_neighbour", "--combine", "v_rel_yz_10",
                   "--combine", "mu_as_printed", "--combine", "duration_p02"],
                  "p04_combinations"),
         readings_files("p04_combinations"), slow=True,
         what="docs/study/readings: P04's 48 combinations (≈ 5 min)"),
    Task("inverse-p04", optimize("paper2004_inverse.json", "p04_run", ["--threads", "2"]),
         optimize_files("p04_run"),
         what="docs/inverse.md, docs/results/inverse: P04's GA (≈ 1 min)"),
    Task("inverse-p02", optimize("paper2002_inverse.json", "p02_run", []),
         optimize_files("p02_run"), slow=True,
         what="docs/inverse.md, docs/results/inverse: P02's GA (≈ 2.5 min on one process)"),
    Task("tutorial", tutorial, ["results/python_tutorial.txt"], slow=True, needs_agglo=False,
         what="docs/python.md: what docs/python_tutorial.py prints (needs `import agglo`; "
              "python/test.sh runs it)"),
]


# ---- comparing -----------------------------------------------------------------------


def read_table(path: pathlib.Path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def table_differences(committed: pathlib.Path, fresh: pathlib.Path) -> list[str]:
    """Cells that differ, timing columns aside; every other cell compared as text (the
    tables print floats round-trip exact, so equal text is equal bits)."""
    head_a, rows_a = read_table(committed)
    head_b, rows_b = read_table(fresh)
    if head_a != head_b:
        return [f"columns differ: {head_a} vs {head_b}"]
    if len(rows_a) != len(rows_b):
        return [f"{len(rows_a)} rows committed, {len(rows_b)} now"]
    out = []
    for k, (a, b) in enumerate(zip(rows_a, rows_b)):
        for name, x, y in zip(head_a, a, b):
            if name not in TIMING_COLUMNS and x != y:
                label = a[1] if len(a) > 1 else a[0]
                out.append(f"row {k + 1} ({label}): {name} = {x} committed, {y} now")
    return out


WALL = re.compile(r"[0-9.]+ s wall")


def report_differences(committed: pathlib.Path, fresh: pathlib.Path) -> list[str]:
    """Printed text, its wall time aside."""
    a = WALL.sub("X s wall", committed.read_text())
    b = WALL.sub("X s wall", fresh.read_text())
    if a == b:
        return []
    return ["the report differs:\n--- committed\n" + a + "--- now\n" + b]


def readme_quotes_the_report(report: pathlib.Path) -> list[str]:
    """README.md's 'What a run prints' block is the committed report, wall time aside."""
    readme = (ROOT / "README.md").read_text()
    marker = f"$ agglo run {README_REPORT_SCENARIO}\n"
    if marker not in readme:
        return [f"README.md has no `{marker.strip()}` block"]
    block = readme.split(marker, 1)[1].split("```", 1)[0]
    want = WALL.sub("X s wall", report.read_text())
    have = WALL.sub("X s wall", block)
    if want != have:
        return ["README.md's report is not the run's:\n--- README\n" + have + "--- run\n" + want]
    return []


def pipeline_md_quotes_validate(agglo: pathlib.Path) -> list[str]:
    """docs/pipeline.md's `agglo validate` block is what validate prints (the memory
    line, which depends on the machine, aside)."""
    printed = run([agglo, "validate", README_REPORT_SCENARIO])
    printed = "".join(l + "\n" for l in printed.splitlines() if not l.startswith("memory:"))
    page = (ROOT / "docs" / "pipeline.md").read_text()
    marker = f"$ agglo validate {README_REPORT_SCENARIO}\n"
    if marker not in page:
        return [f"docs/pipeline.md has no `{marker.strip()}` block"]
    block = page.split(marker, 1)[1].split("```", 1)[0]
    if block != printed:
        return ["docs/pipeline.md's validate block is not what validate prints:\n--- page\n"
                + block + "--- now\n" + printed]
    return []


def readme_quotes_the_pandas_slope(agglo: pathlib.Path) -> list[str]:
    """README.md's pandas example prints the slope of log N against log t in the scaling
    regime (N0/10 ≥ N ≥ 100) of ballistic_aggregation; the README quotes it."""
    import math
    with tempfile.TemporaryDirectory() as tmp:
        series = pathlib.Path(tmp) / "series.csv"
        run([agglo, "run", "scenarios/ballistic_aggregation.json", "--series", series, "-q"])
        with open(series, newline="") as f:
            rows = list(csv.DictReader(f))
    n0 = float(rows[0]["bodies"])
    fit = [r for r in rows if 100 <= float(r["bodies"]) <= n0 / 10]
    xs = [math.log(float(r["t"])) for r in fit]
    ys = [math.log(float(r["bodies"])) for r in fit]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    quoted = f"# printed {slope:.2f}"
    readme = (ROOT / "README.md").read_text()
    return [] if quoted in readme else [f"README.md's pandas example should say `{quoted}`"]


def docs_quote_the_peer_counts(table: pathlib.Path) -> list[str]:
    """Each collision count of the peer clouds appears, as README.md and docs/speed.md
    write it (thin-space thousands), in both pages' tables."""
    head, rows = read_table(table)
    col = {n: i for i, n in enumerate(head)}
    out = []
    pages = {p: (ROOT / p).read_text() for p in ["README.md", "docs/speed.md"]}
    for r in rows:
        scene = r[col["scene"]]
        count = r[col["bonds"]] if "merge" in scene else r[col["bounces"]]
        written = f"{int(count):,}".replace(",", " ")
        for page, text in pages.items():
            if page == "README.md" and scene.endswith("100000") and "bounce" in scene:
                continue
            if written not in text:
                out.append(f"{page} does not quote {scene}'s {written}")
    return out


PLUS_MINUS = re.compile(r"(\d+\.\d+) ± (\d+\.\d+)")


def quoted_figures_are_made(page: pathlib.Path, sources: list[pathlib.Path | str]) -> list[str]:
    """Every `a ± b` the page writes is a figure of one of its generated SOURCES (files,
    or text made from them), as printed there or rounded to fewer digits (the page may
    quote 2.56 ± 0.02 for a table's 2.556 ± 0.019): a regenerated table that moves a
    figure fails until the prose follows."""
    made = []
    for src in sources:
        for a, b in PLUS_MINUS.findall(src if isinstance(src, str) else src.read_text()):
            made.append((float(a), float(b)))

    def decimals(text):
        return len(text.split(".")[1])

    out = []
    for a, b in PLUS_MINUS.findall(page.read_text()):
        da, db = decimals(a), decimals(b)
        if not any(abs(round(x, da) - float(a)) < 0.5 * 10 ** -da
                   and abs(round(y, db) - float(b)) < 1.5 * 10 ** -db for x, y in made):
            out.append(f"{page.relative_to(ROOT)} quotes {a} ± {b}, which no table made")
    return out


def compare(task: Task, fresh_docs: pathlib.Path, agglo: pathlib.Path) -> list[str]:
    out = []
    for rel in task.files:
        committed = ROOT / "docs" / rel
        fresh = fresh_docs / rel
        if not committed.exists():
            out.append(f"docs/{rel} is not committed (run docs/regenerate.py)")
            continue
        if rel.endswith(".csv"):
            out += [f"docs/{rel}: {d}" for d in table_differences(committed, fresh)]
        else:
            out += [f"docs/{rel}: {d}" for d in report_differences(committed, fresh)]
    if task.name == "readme-report":
        out += readme_quotes_the_report(ROOT / "docs" / task.files[0])
        out += pipeline_md_quotes_validate(agglo)
        out += readme_quotes_the_pandas_slope(agglo)
    if task.name in ("peers", "peers-slow"):
        out += docs_quote_the_peer_counts(ROOT / "docs" / task.files[0])
    if task.name.startswith("readings-"):
        readings_dir = ROOT / "docs" / "study" / "readings"
        out += quoted_figures_are_made(readings_dir / "README.md",
                                       sorted(readings_dir.rglob("readings.md")))
    if task.name == "tutorial":
        out += python_md_quotes_the_fits(ROOT / "docs" / task.files[0])
    return out


# ---- docs/studies.md's prose, against the committed tables ---------------------------


def dict_rows(path: pathlib.Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def signed(x: float, decimals: int) -> str:
    """+6.8 / −8.5: a signed figure as the pages print it (a real minus sign)."""
    return f"{x:+.{decimals}f}".replace("-", "−")


def thousands(n: int) -> str:
    return f"{n:,}".replace(",", " ")


def studies_md_claims() -> list[str]:
    """The phrases of docs/studies.md that quote a deterministic figure (growth, steps,
    counts, iterations, seed statistics; never a wall time), each made again from the
    committed tables under docs/study/. The page must contain each as written (whitespace
    aside), so a regenerated table that moves a figure fails until the prose follows."""
    study = ROOT / "docs" / "study"
    scenes = {}
    for scene in ("p04", "accuracy"):
        rows = {r["label"]: r for r in dict_rows(study / scene / "accuracy.csv")}
        seeds = [float(r["growth_ratio"]) for r in dict_rows(study / scene / "noise.csv")]
        scenes[scene] = (rows, seeds)
    claims = []

    def growth(scene, label):
        return float(scenes[scene][0][label]["growth_ratio"])

    def change(scene, label):  # relative to the reference seed, in per cent
        return 100 * (growth(scene, label) / growth(scene, "reference") - 1)

    def ensemble(scene, label):
        r = scenes[scene][0][label]
        return f"{float(r['ensemble_growth_mean']):.2f} ± {float(r['ensemble_growth_se']):.2f}"

    # Chaos sets the error floor: the seed-to-seed spread of the resolved run.
    for scene, name in (("p04", "P04's best case"), ("accuracy", "the study scene")):
        rows, seeds = scenes[scene]
        mean, sd = statistics.mean(seeds), statistics.stdev(seeds)
        ref = rows["reference"]
        spread = (f"{len(seeds)} seeds is {mean:.2f} (standard deviation {sd:.2f}, "
                  f"{100 * sd / mean:.1f} %)" if scene == "p04"
                  else f"it is {mean:.2f} (standard deviation {sd:.2f})")
        differs, ks = 100 * float(ref["noise_growth_error"]), float(ref["noise_ks"])
        claims += [spread,
                   f"differs from the reference seed by {differs:.1f} % on average (KS distance "
                   f"of the radii: {ks:.2f})" if scene == "p04" else
                   f"mean difference to the reference seed is {differs:.0f} % (KS {ks:.2f})"]
        if scene == "accuracy":
            top = max(dict_rows(study / scene / "noise.csv"), key=lambda r: float(r["growth_ratio"]))
            claims.append(f"grows to {float(top['growth_ratio']):.2f} with {top['final_bodies']} "
                          "bodies left")
    p04, acc = scenes["p04"][0], scenes["accuracy"][0]
    claims += [
        f"The study scene takes {acc['reference']['steps']} steps",
        f"P04's best case {p04['reference']['steps']} steps",
        f"{growth('p04', 'stepped core c = 1'):.3f} against {growth('p04', 'reference'):.3f} on "
        f"P04's best case ({abs(change('p04', 'stepped core c = 1')):.1f} %)",
        f"{growth('accuracy', 'stepped core c = 1'):.3f} against "
        f"{growth('accuracy', 'reference'):.3f} on the study scene",
        f"takes {p04['stepped core c = 1']['steps']} steps",
        "with errors of " + ", ".join(
            f"{100 * float(p04[f'c = {c}']['growth_error']):.2g} %" for c in (2, 5, 10, 30))
        + f" and {100 * float(p04['c = 100']['growth_error']):.2g} %",
    ]
    # Fixed steps: the scatter of every step but the coarsest (1e-3 s), and the coarsest.
    for scene, decimals in (("p04", 1), ("accuracy", 0)):
        rows = scenes[scene][0]
        fixed = [l for l in rows if rows[l]["family"] == "fixed_dt"]
        coarsest = max(fixed, key=lambda l: float(rows[l]["parameter"]))
        rest = [l for l in fixed if l != coarsest]
        steps = sorted(int(rows[l]["steps"]) for l in rest)
        lo, hi = min(rest, key=lambda l: growth(scene, l)), max(rest, key=lambda l: growth(scene, l))
        between = (f"scatter between {signed(change(scene, lo), decimals)} % and "
                   f"{signed(change(scene, hi), decimals)} % ({growth(scene, lo):.2f}–"
                   f"{growth(scene, hi):.2f})")
        if scene == "p04":
            dts = sorted(float(rows[l]["parameter"]) for l in rest)
            claims.append(f"Δt = {dts[0]:.1e} to {dts[-1]:.1e} s ({thousands(steps[-1])} to "
                          f"{steps[0]} steps) {between}".replace("e-0", "e-"))
        else:
            claims.append(f"{steps[-1]} to {steps[0]} steps {between}")
        claims.append(f"{'(' if scene == 'p04' else ''}{rows[coarsest]['steps']} steps"
                      f"{') gives' if scene == 'p04' else ' give'} "
                      f"{growth(scene, coarsest):.2f} ({signed(change(scene, coarsest), 0)} %)")
    # Cooling: implicit and exact give the plain fixed-step result at the same step (the
    # page says so in words: a table that disagrees contradicts it).
    contradicted = []
    cooled = {}
    for scene in ("accuracy", "p04"):
        rows = scenes[scene][0]
        step = next(l for l in rows if l.startswith("implicit dt = ")).split(" = ", 1)[1]
        cooled[scene] = growth(scene, f"implicit dt = {step}")
        for integrator in ("implicit", "exact"):
            if rows[f"{integrator} dt = {step}"]["growth_ratio"] != rows[f"dt = {step}"]["growth_ratio"]:
                contradicted.append(f"docs/studies.md says {integrator} cooling at dt = {step} "
                                    "gives the plain fixed-Δt result; the table differs")
    claims.append(f"({cooled['accuracy']:.2f} and {cooled['p04']:.2f})")
    # P04's table: one seed, and the mean ± s.e. over the study's seeds where it has one.
    table = {
        "resolved, c = 1 (reference, event core)": "reference",
        "the same on the stepped core": "stepped core c = 1",
        "P04's Δt bounds [1e-8, 1e-3] s, c = 1": "P04 dt bounds [1e-8 1e-3] s c = 1",
        "nearest-neighbour contact rule, c = 1": "nearest-neighbour c = 1",
        "nearest-neighbour rule, fixed Δt = 9.1e-5 s ({steps} steps)": "nearest-neighbour dt = 9.123e-5 s",
        "nearest-neighbour rule, fixed Δt = 2.0e-4 s ({steps} steps)": "nearest-neighbour dt = 2.027e-4 s",
        "fixed Δt = 9.1e-5 s": "dt = 9.123e-5 s",
        "papers' plain iteration at TOL = 5e-4, cap 100 ({unconverged} impacts unconverged)":
            "plain iteration TOL = 5e-4",
        "plain iteration + nearest-neighbour + Δt = 4.1e-5 s": "plain + nearest-neighbour dt = 4.107e-5 s",
        "plain iteration with an odd cap (101)": "plain iteration TOL = 5e-4 odd cap 101",
    }
    seeds = scenes["p04"][1]
    reference_mean = (f"{statistics.mean(seeds):.2f} ± "
                      f"{statistics.stdev(seeds) / len(seeds) ** 0.5:.2f}")
    for written, label in table.items():
        r = p04[label]
        over = (reference_mean if label == "reference"
                else ensemble("p04", label) if r["ensemble_growth_se"] != "NaN" else "")
        claims.append(f"| {written.format(**r)} | {growth('p04', label):.2f} | {over} |")
    papers = p04["all papers' choices dt = 9.123e-5 s"]
    failed_at = re.search(r"at step (\d+)", papers["failure"])
    claims.append(f"| all the papers' choices, including explicit cooling | fails at step "
                  f"{failed_at.group(1) if failed_at and papers['status'] == 'failed' else '?'}")
    plain, odd = "plain iteration TOL = 5e-4", "plain iteration TOL = 5e-4 odd cap 101"
    mean_plain = float(p04[plain]["ensemble_growth_mean"])
    se_plain = float(p04[plain]["ensemble_growth_se"])
    se_ref = statistics.stdev(seeds) / len(seeds) ** 0.5
    claims += [
        f"{ensemble('p04', plain)} against the reference's {reference_mean} "
        f"({signed(100 * (mean_plain / statistics.mean(seeds) - 1), 0)} %, z ≈ "
        f"{(mean_plain - statistics.mean(seeds)) / math.hypot(se_plain, se_ref):.0f})",
        f"its single seed 2004 ({growth('p04', plain):.2f})",
        f"odd cap the same seeds give {ensemble('p04', odd)}",
        f"closest is the plain iteration with an even cap ({ensemble('p04', plain)};",
        "scatter by up to " + signed(max(change("p04", l) for l in p04
                                         if p04[l]["family"] in ("fixed_dt", "papers")
                                         and " dt = " in l and "plain" not in l
                                         and "papers' choices" not in l), 0) + " %",
        f"at the ladder's {p04['dt = 9.123e-5 s']['steps']} steps "
        f"({growth('p04', 'dt = 9.123e-5 s'):.2f})",
    ]
    # The pair solve's maps.
    cells = dict_rows(study / "stability" / "pair_map.csv")

    def at(a0):
        return [c for c in cells if float(c["a0"]) == a0]

    cycle = [c for c in at(0.0) if c["plain_converged"] == "false"]
    speeds = sorted(float(c["speed_over_critical"]) for c in cycle)

    def most_plain(a0):
        return max(int(c["plain_iterations"]) for c in at(a0) if c["plain_converged"] == "true")

    def evaluations(c):
        return int(c["safeguarded_plain_iterations"]) + int(c["safeguarded_fallback_iterations"])

    soft = dict_rows(study / "stability" / "pair_map_softening.csv")
    claims += [
        f"all {len(cycle)} grid speeds from {speeds[0]:.2f} to {speeds[-1]:.2f} × critical",
        f"needs up to {most_plain(0.02)} iterations near the critical speed "
        f"({most_plain(0.1)} at a0 = 0.1, ≤ {most_plain(0.5)} at a0 = 0.5)",
        f"needs at most {max(map(evaluations, cells))} evaluations of G on the whole grid "
        f"({max(map(evaluations, at(0.0)))} at a0 = 0)",
        f"on all {len(cells)} cells",
        f"(≤ {max(int(c['plain_iterations']) for c in soft if c['plain_converged'] == 'true')} "
        "iterations)",
    ]
    page = " ".join((ROOT / "docs" / "studies.md").read_text().split())
    missing = contradicted + [f"docs/studies.md should say `{c}` (made from docs/study/)"
                              for c in claims if " ".join(c.split()) not in page]
    # Its `a ± b` figures: the ladders' seed means and the readings' tables.
    ensembles = [reference_mean] + [
        f"{float(r['ensemble_growth_mean'])} ± {float(r['ensemble_growth_se'])}"
        for rows, _ in scenes.values() for r in rows.values() if r["ensemble_growth_se"] != "NaN"]
    readings = sorted((study / "readings").rglob("readings.md"))
    return missing + quoted_figures_are_made(ROOT / "docs" / "studies.md",
                                             ["\n".join(ensembles), *readings])


def inverse_md_claims() -> list[str]:
    """docs/inverse.md's figures of the shipped GA runs (best.json: the GA's own `top`
    and the closing `check` on fresh seeds) and of P02's control-volume sweep (scan.csv),
    made again from the committed files and looked for in the page as written."""
    import json
    runs = ROOT / "docs" / "results" / "inverse"

    def sci(x: float) -> str:  # 5.4e-4, as the page writes it
        return f"{x:.1e}".replace("e-0", "e-").replace("e+00", "")

    ordinal = ["first", "second", "third", "fourth"]
    claims, contradicted = [], []
    for run, name, fmt in (("p04_run", "Π04", lambda x: f"{x:.3f}"), ("p02_run", "Π02", sci)):
        best = json.loads((runs / run / "best.json").read_text())
        top, fresh = best["top"][0], best["check"]["ranked"]
        claims.append(f"{name} = {fmt(top['cost'])} ± {fmt(top['cost_se'])}")
        first = next(r["rank"] for r in fresh if r["ga_rank"] == 1)
        if run == "p04_run":
            claims += [f"the {len(fresh)} best give {fmt(fresh[0]['cost'])}–{fmt(fresh[-1]['cost'])} "
                       f"± {fmt(max(r['cost_se'] for r in fresh))}".replace("the 4 best", "the four best"),
                       f"the GA's first comes {ordinal[first - 1]}"]
        else:
            last = fresh[-1]
            claims.append(f"comes {'last' if first == len(fresh) else ordinal[first - 1]} on fresh "
                          f"seeds ({sci(last['cost'])} ± {sci(last['cost_se'])})")
            claims.append("all four are within two standard errors of zero")
            if not all(abs(r["cost"]) < 2 * r["cost_se"] for r in fresh):
                contradicted.append("docs/inverse.md says all four P02 strings are within two "
                                    "standard errors of zero; best.json's check says otherwise")
    scan = {float(r["value"]): float(r["growth_ratio"])
            for r in dict_rows(runs / "p02_d_sweep" / "scan.csv")}

    def at(d):
        return scan[min(scan, key=lambda v: abs(math.log(v / d)))]

    near_two = [v for v in scan if v <= 4.7e-5]
    bound = math.ceil(100 * max(abs(scan[v] - 2) for v in near_two)) / 100
    stops = min(v for v in scan if all(scan[w] < 1.0005 for w in scan if w >= v))
    claims += [
        f"within {bound:.2f} of 2 for every D from 1e-6 to about 4.6e-5 m",
        f"({at(1e-6):.2f} at 1e-6 m, {at(1e-5):.2f} at 1e-5 m",
        f"{at(4.64e-5):.2f} at 4.6e-5 m), then falls ({at(6.81e-5):.2f} at 6.8e-5 m, "
        f"{at(1e-4):.2f} at 1e-4 m)",
        f"grains stop bonding at all for D ≳ {sci(stops)} m",
    ]
    page = " ".join((ROOT / "docs" / "inverse.md").read_text().split())
    return contradicted + [f"docs/inverse.md should say `{c}` (made from docs/results/inverse/)"
                           for c in claims if " ".join(c.split()) not in page]


def python_md_quotes_the_fits(printed: pathlib.Path) -> list[str]:
    """docs/python.md quotes the tutorial's fitted exponents line for line."""
    page = (ROOT / "docs" / "python.md").read_text()
    if not printed.exists():
        return []  # reported as not committed
    fits = [line for line in printed.read_text().splitlines() if " ~ t^(" in line]
    if not fits:
        return ["the tutorial printed no fit (`N ~ t^(...)`)"]
    return [f"docs/python.md does not quote the tutorial's `{line.strip()}`"
            for line in fits if line.strip() not in page]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--check", action="store_true",
                   help="compare a fresh run with the committed files instead of writing")
    p.add_argument("--full", action="store_true", help="also the slow tasks")
    p.add_argument("--only", nargs="+", metavar="TASK", help="just these tasks")
    p.add_argument("--agglo", default=os.environ.get("AGGLO_BIN"),
                   help="the agglo binary (default target/release/agglo)")
    p.add_argument("--list", action="store_true", help="list the tasks")
    a = p.parse_args(argv)
    if a.list:
        for t in TASKS:
            print(f"{t.name:<33} {'(slow) ' if t.slow else ''}{t.what}")
        return 0
    names = {t.name for t in TASKS}
    for n in a.only or []:
        if n not in names:
            p.error(f"--only {n}: no such task; the tasks: {', '.join(sorted(names))}")
    tasks = [t for t in TASKS
             if (a.only and t.name in a.only) or (not a.only and (a.full or not t.slow))]
    agglo = pathlib.Path(a.agglo) if a.agglo else ROOT / "target" / "release" / "agglo"
    if any(t.needs_agglo for t in tasks) and not agglo.is_file():
        run(["cargo", "build", "--release", "--bin", "agglo"])
    problems = []
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) if a.check else ROOT / "docs"
        for t in tasks:
            t.make(agglo.resolve(), out, a.check)
            if a.check:
                found = compare(t, out, agglo.resolve())
                print(f"{t.name}: {'ok' if not found else f'{len(found)} differences'}")
                problems += found
    # The studies page's prose against the committed tables (cheap: no run).
    prose = studies_md_claims() + inverse_md_claims()
    print(f"prose of studies.md and inverse.md: {'ok' if not prose else f'{len(prose)} differences'}")
    problems += prose
    if problems:
        print("\n".join(problems), file=sys.stderr)
        print(f"\n{len(problems)} documented figures differ from what the binary makes now: "
              "regenerate with `python3 docs/regenerate.py` and update the prose that quotes "
              "them.", file=sys.stderr)
        return 1
    if not a.check:
        print("regenerated; now update the prose that quotes these figures "
              "(docs/studies.md, docs/inverse.md, README.md) and commit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
