"""Ensembles: one scenario over many seeds, on Rust threads (the task farm of
``agglo optimize``), with the GIL released.

The numbers are the same for any thread count, and the same as ``agglo run --seed k``
for each seed k.
"""

from __future__ import annotations

import json
from typing import Any, Dict, Iterable, List, Sequence

import numpy as np

from . import _agglo
from ._args import MAX_SEED, MAX_THREADS, whole
from .scenario import Scenario
from .table import Table, units_of


class Ensemble:
    """The runs of an ensemble: :attr:`summary` (one row per seed), :attr:`summaries`
    (each run's full summary dict), and :attr:`tables` (each table asked for, the runs
    stacked with a ``seed`` column first)."""

    def __init__(self, seeds: Sequence[int], summaries: List[Dict[str, Any]], tables: Dict[str, Table]):
        self.seeds = list(seeds)
        self.summaries = summaries
        self.tables = tables
        rows = [_flatten(s) for s in summaries]
        keys = [k for k in rows[0] if all(k in r for r in rows)]
        columns = {"seed": np.asarray(self.seeds, dtype=np.uint64)}
        for k in keys:
            columns[k] = np.asarray([r[k] for r in rows])
        self.summary = Table("ensemble", columns, {"seed": "-"})

    def __getitem__(self, table: str) -> Table:
        return self.tables[table]

    def __repr__(self) -> str:
        return f"<agglo.Ensemble of {len(self.seeds)} seeds; tables: {', '.join(self.tables) or 'none'}>"


def _flatten(d: Dict[str, Any], prefix: str = "") -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out[key] = v
    return out


def ensemble(
    scenario: Scenario,
    seeds: Iterable[int] = range(8),
    *,
    threads: int = 0,
    tables: Iterable[str] = (),
) -> Ensemble:
    """Run ``scenario`` once per seed on ``threads`` Rust threads (0: one per core).

    ``tables`` names the tables to keep for every run — any table ``Simulation.run``
    takes: series, sizes, snapshots (sampled on the scenario's ``output.sampling``),
    collisions, and the per-step tables such as impact_speeds; they are returned
    stacked, with a ``seed`` column. The scenario's own output files are not written.
    """
    seeds = [whole("seeds", s, 0, MAX_SEED) for s in seeds]
    tables = list(tables)
    results = _agglo.ensemble(scenario._inner, seeds, whole("threads", threads, 0, MAX_THREADS), tables)
    summaries = [json.loads(text) for text, _ in results]
    stacked: Dict[str, Table] = {}
    for name in tables:
        parts = [cols[name] for _, cols in results]
        columns: Dict[str, Any] = {
            "seed": np.concatenate(
                [np.full(len(next(iter(p.values()))), seed, dtype=np.uint64) for seed, p in zip(seeds, parts)]
            )
        }
        for col in parts[0]:
            values = [p[col] for p in parts]
            if isinstance(values[0], list):
                columns[col] = [x for v in values for x in v]
            else:
                columns[col] = np.concatenate(values)
        stacked[name] = Table(name, columns, {"seed": "-", **units_of(name)})
    return Ensemble(seeds, summaries, stacked)
