"""Issue 39's Python findings left open after the first pass, one regression test each:
numbers that allocate refused by name before anything is allocated (kernel seeds, a
scene too large for the memory), whole-number arguments of the subgrid front and ids of
``with_bodies`` checked, subgrid inputs refused naming the cell's field, and damaged
kernel files refused naming the file."""

import pathlib
import subprocess
import sys

import numpy as np
import pytest

import agglo
import agglo.kernel
from agglo.subgrid import Coupling

ROOT = pathlib.Path(__file__).resolve().parents[2]
BALLISTIC = ROOT / "scenarios/ballistic_aggregation.json"


def test_kernel_seeds_beyond_the_memory_are_refused_without_killing_the_interpreter(tmp_path):
    """``kernel.measure(seeds=2**32 - 1)`` killed the interpreter allocating 34 GB; it is
    refused naming ``seeds`` with the estimate, and the interpreter carries on."""
    script = f"""
import agglo, agglo.kernel
s = agglo.Scenario.load({str(BALLISTIC)!r})
try:
    agglo.kernel.measure(s, "dustpy:primary,1,7", {str(tmp_path / 'k.npz')!r}, seeds=2**32 - 1)
except agglo.ScenarioError as e:
    print("refused:", e)
print("alive")
"""
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert "refused: kernel: seeds: 4294967295 seeds need about" in result.stdout
    assert result.stdout.rstrip().endswith("alive")
    assert not (tmp_path / "k.npz").exists()


def test_kernel_measure_refuses_bad_counts_and_a_scene_too_large_by_name(tmp_path):
    s = agglo.Scenario.load(BALLISTIC)
    out = tmp_path / "k.npz"
    for seeds in (2**32, 0, 1.5, True):
        with pytest.raises(agglo.ScenarioError, match=r"^seeds: allowed"):
            agglo.kernel.measure(s, "dustpy:primary,1,7", out, seeds=seeds)
    with pytest.raises(agglo.ScenarioError, match=r"^threads: allowed"):
        agglo.kernel.measure(s, "dustpy:primary,1,7", out, threads=10**6)
    # 4e9 bodies (2.6 TB) aborted in the first run; `agglo run` refused them.
    huge = s.set({"cloud.count": 4_000_000_000, "cloud.size_ratio": 0.01})
    with pytest.raises(agglo.AggloError, match=r"cloud\.count: 4000000000 bodies need about"):
        agglo.kernel.measure(huge, "dustpy:primary,1,7", out, seeds=1, threads=1)
    with pytest.raises(agglo.ScenarioError, match=r"ensemble: cloud\.count: 4000000000 bodies"):
        agglo.ensemble(huge, seeds=[1, 2], threads=1)
    assert not out.exists()


def test_subgrid_whole_number_arguments_are_refused_by_name():
    """``cells=[1.5]`` was advanced as cell 1; counts out of range raised a bare
    OverflowError."""
    base = agglo.Scenario.load(BALLISTIC)
    m0 = base.primary_mass
    edges = np.array([0.5, 1.5, 1e9]) * m0
    c = Coupling(base, edges, bodies=50, replicas=1)
    b0, _ = c.primary
    n = 0.02 / (4.0 / 3.0 * np.pi * b0**3)
    cell = dict(number_density=[[n, 0.0]], mass=[[m0, 2 * m0]], velocity=np.zeros((1, 2, 3)),
                temperature=[[300.0, 300.0]], granular_temperature=[[1.0, 1.0]], dt=1e-5)
    cases = [
        (lambda: c.advance_cells(0, [1.5], **cell), "cells"),
        (lambda: c.advance_cells(0, [-1], **cell), "cells"),
        (lambda: c.advance_cells(0, [2**64], **cell), "cells"),
        (lambda: c.advance_cells(-1, [1], **cell), "macro_step"),
        (lambda: c.advance_cells(0.5, [1], **cell), "macro_step"),
        (lambda: c.advance_cells(0, [1], threads=1.5, **cell), "threads"),
        (lambda: c.advance_cells(0, [1], threads=10**6, **cell), "threads"),
        (lambda: Coupling(base, edges, bodies=2.5), "bodies"),
        (lambda: Coupling(base, edges, replicas=2**40), "replicas"),
        (lambda: Coupling(base, edges, bodies=None, max_bodies=-3), "max_bodies"),
        (lambda: base.with_seed(1.5), "seed"),
    ]
    for call, name in cases:
        with pytest.raises(agglo.ScenarioError, match=rf"^{name}: allowed"):
            call()
    # Whole numbers of any integer type still work.
    outs, _ = c.advance_cells(np.uint8(0), [np.int64(7)], threads=np.int32(1), **cell)
    assert outs[0].cell == 7


def test_subgrid_inputs_the_box_would_refuse_name_the_cell_s_field():
    """A speed of 1e5 m/s on every axis, a granular or gas temperature of 1e300 passed the
    cell's check, then failed naming the lifted box's ``cloud.bodies.59.velocity``."""
    base = agglo.Scenario.load(BALLISTIC)
    m0 = base.primary_mass
    c = Coupling(base, np.array([0.5, 1.5, 1e9]) * m0, bodies=50, replicas=1)
    b0, _ = c.primary
    n = 0.02 / (4.0 / 3.0 * np.pi * b0**3)

    def cell(**change):
        d = dict(number_density=[[n, 0.0]], mass=[[m0, 2 * m0]], velocity=np.zeros((1, 2, 3)),
                 temperature=[[300.0, 300.0]], granular_temperature=[[1.0, 1.0]], dt=1e-5)
        d.update(change)
        return d

    fast = np.zeros((1, 2, 3))
    fast[0, 0] = 1e5
    cases = [
        (cell(velocity=fast), r"^cell 4: classes\[0\]\.velocity = \|v\| = 1\.73205080756887"),
        (cell(granular_temperature=[[1e300, 1.0]]), r"^cell 4: classes\[0\]\.granular_temperature = 1e300"),
        (cell(temperature=[[1e300, 300.0]]), r"^cell 4: classes\[0\]\.temperature = 1e300"),
        (cell(gas_temperature=1e300), r"^cell 4: gas\.temperature = 1e300"),
    ]
    for inputs, message in cases:
        with pytest.raises(agglo.ScenarioError, match=message):
            c.advance_cells(0, [4], **inputs)


def test_with_bodies_ids_that_are_not_whole_or_negative_are_refused_by_name():
    """``id=np.arange(n) + 0.5`` was truncated and ``-1`` wrapped to 2^64 − 1; the CSV path
    refuses both."""
    s = agglo.Scenario.load(ROOT / "scenarios/two_body.json")
    n, b0, d = 8, s.primary_radius, s.box.half_width
    assert d / 4 > 2 * b0  # eight bodies in a row, apart
    position = np.array([[-d + (i + 0.5) * d / 4, 0.0, 0.0] for i in range(n)])
    velocity = np.zeros((n, 3))
    for ids, row in [(np.arange(n) + 0.5, 0), (np.arange(n) - 1, 0), ([5, 6, -7, 8, 9, 10, 11, 12], 2),
                     (np.arange(n) * 1e300, 1), ([float("nan")] * n, 0), (["a"] * n, 0)]:
        with pytest.raises(agglo.ScenarioError, match=rf"^with_bodies: id\.{row}: allowed"):
            s.with_bodies(position, velocity, id=ids)
    # Whole numbers of every integer type, and whole floats, are taken as they are.
    for ids in (np.arange(n, dtype=np.int32) + 3, np.arange(n, dtype=np.uint64) + 2**63,
                np.arange(n) * 2.0, [2**64 - 1 - i for i in range(n)]):
        got = s.with_bodies(position, velocity, id=ids).cloud.bodies
        assert [b["id"] for b in got] == [int(i) for i in np.asarray(ids, dtype=object)]


def damaged_kernel_files(good: bytes, tmp_path):
    """A real kernel file cut short, emptied, replaced by text, by a pickle, and with an
    entry missing."""
    files = {
        "cut": good[: len(good) // 2],
        "empty": b"",
        "text": b"units,si\n" * 10,
    }
    paths = {}
    for name, data in files.items():
        paths[name] = tmp_path / f"{name}.npz"
        paths[name].write_bytes(data)
    paths["pickle"] = tmp_path / "pickle.npz"
    np.savez(paths["pickle"], units=np.array([{"a": 1}], dtype=object))
    with np.load(tmp_path / "good.npz") as z:
        arrays = {k: z[k] for k in z.files if k != "array_units"}
    paths["missing"] = tmp_path / "missing.npz"
    np.savez(paths["missing"], **arrays)
    return paths


def test_damaged_kernel_files_are_refused_naming_the_file(tmp_path):
    """``agglo.kernel.load`` raised raw zip, zlib or JSON errors, or numpy's advice to
    load with allow_pickle; now a ValueError naming the file and what is wrong."""
    s = agglo.Scenario.load(BALLISTIC).set({"cloud.count": 40, "time.end": 1e-4})
    good = tmp_path / "good.npz"
    agglo.kernel.measure(s, "dustpy:primary,1,7", good, seeds=1, threads=1)
    reasons = {"cut": "BadZipFile", "empty": "EOFError", "text": "not an .npz archive",
               "pickle": "not an .npz archive", "missing": "missing array_units"}
    for name, path in damaged_kernel_files(good.read_bytes(), tmp_path).items():
        with pytest.raises(ValueError) as e:
            agglo.kernel.load(path)
        message = str(e.value)
        assert message.startswith(f"{path}: not a readable agglo kernel file"), message
        assert reasons[name] in message, message
        assert "allow_pickle" not in message
    with pytest.raises(FileNotFoundError):
        agglo.kernel.load(tmp_path / "absent.npz")
