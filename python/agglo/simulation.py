"""Runs: one scenario advanced by the engine, with the GIL released while it steps.

A :class:`Simulation` runs through the same library code as ``agglo run``: with the
same scenario, seed and outputs it writes the same bytes. Ctrl-C raises
``KeyboardInterrupt`` at a step boundary within about 50 ms; the run stays valid and
:meth:`Simulation.run` continues it to the same bytes as an uninterrupted run.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Dict, Iterable, Mapping, Optional, Union

from . import _agglo
from ._args import MAX_COUNT, MAX_SEED, whole
from .scenario import Scenario
from .table import Table, units_of

TableSpec = Union[Iterable[str], Mapping[str, Optional[Union[str, os.PathLike]]]]

DEFAULT_LIVE_ADDR = "127.0.0.1:8765"


class Carry:
    """A per-body quantity carried through merges and fragmentations by the engine's
    built-in rules, in Rust (docs/extending.md, engine/carried.rs).

    ``init``: one value for every body, or an array of one per body in id order.
    ``combine``: what a merged body carries — "sum" (extensive: charge, a species'
    mass), "mass_weighted", "max" or "min". ``split``: what each of a fragmenting body's
    pieces carries — "by_mass" (value / pieces) or "copy". The values appear as columns of
    ``bodies()`` and the snapshots, named by the dict key, and survive checkpoints and
    pickling.
    """

    def __init__(self, init=0.0, combine: str = "sum", split: str = "by_mass"):
        import numpy as np

        self.init = [float(x) for x in np.atleast_1d(np.asarray(init, dtype=np.float64))]
        self.combine = combine
        self.split = split

    def _spec(self, name: str):
        return (name, self.combine, self.split, self.init)

    def __repr__(self) -> str:
        init = self.init[0] if len(self.init) == 1 else f"<{len(self.init)} values>"
        return f"Carry(init={init}, combine={self.combine!r}, split={self.split!r})"


class Simulation:
    """One run of a scenario with the built-in physics.

    ``Simulation(scenario, seed=None)`` builds the scene at once (a scene that cannot be
    built raises :class:`agglo.ScenarioError`). The outputs — tables, recording, summary,
    final state, live view — are chosen by the first :meth:`run`, before any step.
    """

    def __init__(self, scenario: Scenario, seed: Optional[int] = None, carry: Optional[Mapping[str, "Carry"]] = None):
        if not isinstance(scenario, Scenario):
            raise TypeError("Simulation(scenario): give an agglo.Scenario")
        self._carry = [c._spec(name) for name, c in (carry or {}).items()]
        self._sim = _agglo.Simulation(
            scenario._inner, None if seed is None else whole("seed", seed, 0, MAX_SEED), self._carry
        )
        self._hooks = []

    def __reduce__(self):
        """Pickled through a restart snapshot of now (taken as a checkpoint is: every body
        brought to now), with the hooks; the copy continues as this run does. Output
        files are not carried (they are this run's); a hook that cannot be pickled
        (a lambda, a closure) fails here with pickle's message."""
        return (_unpickle, (self._sim._restart_bytes(), list(self._hooks), list(self._carry)))

    def _add_hook(self, kind, function, every, every_events):
        if every_events is not None:
            every_events = whole("every_events", every_events, 1, MAX_COUNT)
        self._sim.add_hook(kind, function, every, every_events)
        self._hooks.append((kind, function, every, every_events))

    def run(
        self,
        until: Optional[float] = None,
        *,
        tables: Optional[TableSpec] = None,
        sampling: Optional[Mapping[str, Any]] = None,
        recording: Optional[Union[str, os.PathLike]] = None,
        summary: Optional[Union[str, os.PathLike]] = None,
        final_state: Optional[Union[str, os.PathLike]] = None,
        live: Union[bool, str, None] = None,
        progress: bool = False,
        command_line: Optional[str] = None,
        record: Optional[Union[str, os.PathLike]] = None,
    ) -> bool:
        """Advance to ``until`` [s] (the first step boundary at or after it), or to the
        end time T. Returns True once T is reached; the outputs are then finalised.

        Outputs (only before the first step):

        - ``tables``: names to keep in memory (``["series", "sizes"]``, read with
          :meth:`series` etc. once finished), or a dict name → path (written as
          ``agglo run --series PATH`` does; CSV, or Parquet for ``.parquet``) or None;
        - ``sampling``: when tables are sampled, as ``output.sampling`` in a scenario:
          ``{"interval": {"dt": 1e-3}}``, ``{"log": {"per_decade": 10}}``,
          ``{"steps": {"every": 100}}``;
        - ``recording``: an MCAP recording for Foxglove (a layout is written beside it;
          ``agglo run --recording``; ``record`` is its deprecated old name);
        - ``summary``, ``final_state``: files as ``--summary`` and ``--final-state``;
        - ``live``: True or "HOST:PORT" to serve the run to Foxglove live;
        - ``progress``: a progress line on stderr (on a terminal);
        - ``command_line``: the text the recording keeps as its command line (default
          ``python: agglo.Simulation.run``; give ``agglo run``'s to get its exact bytes).
        """
        if record is not None:
            if recording is not None:
                raise TypeError("run: give recording= alone (record= is its old name)")
            warnings.warn("Simulation.run(record=...) is now run(recording=...)",
                          DeprecationWarning, stacklevel=2)
            recording = record
        table_map: Optional[Dict[str, Optional[str]]] = None
        if tables is not None:
            if isinstance(tables, Mapping):
                table_map = {k: (None if v is None else os.fspath(v)) for k, v in tables.items()}
            elif isinstance(tables, str):
                table_map = {tables: None}
            else:
                table_map = {k: None for k in tables}
        if live is True:
            live = DEFAULT_LIVE_ADDR
        elif live is False:
            live = None
        return self._sim.run(
            until=None if until is None else float(until),
            tables=table_map,
            sampling=None if sampling is None else json.dumps(sampling),
            recording=None if recording is None else os.fspath(recording),
            summary=None if summary is None else os.fspath(summary),
            final_state=None if final_state is None else os.fspath(final_state),
            live=live,
            progress=bool(progress),
            command_line=command_line,
        )

    def on_impacts(self, function, *, every: Optional[float] = None, every_events: Optional[int] = None) -> None:
        """Call ``function(batch)`` with the impacts, in batches: every ``every`` [s] of
        simulated time or every ``every_events`` impacts, and at T. ``batch`` is a dict of
        NumPy columns: t, id_a, id_b, mass_a, mass_b, normal_speed, tangential_speed,
        restitution, heat, and outcome (a list of "bounce"/"bond"). Collected in Rust;
        Python runs once per batch. Before the first step."""
        self._add_hook("impacts", function, every, every_events)

    def on_merges(self, function, *, every: Optional[float] = None, every_events: Optional[int] = None) -> None:
        """As :meth:`on_impacts`, for merges: t, parent_a, parent_b, child, mass."""
        self._add_hook("merges", function, every, every_events)

    def on_fragments(self, function, *, every: Optional[float] = None, every_events: Optional[int] = None) -> None:
        """As :meth:`on_impacts`, for fragmentations: t, parent, parent_mass, and children
        (a list of id arrays)."""
        self._add_hook("fragments", function, every, every_events)

    def on_sample(self, function, *, every: float) -> None:
        """Call ``function({"t": t, "bodies": columns})`` every ``every`` [s] of
        simulated time (at the first step boundary at or after each multiple) and at T."""
        self._add_hook("sample", function, every, None)

    def step(self, n: int = 1) -> bool:
        """Advance ``n`` steps (events, on the event core), or to T. True once at T."""
        return self._sim.step(whole("n", n, 0, MAX_COUNT))

    def close(self) -> None:
        """Finalise the outputs now (a recording then says the run stopped here)."""
        self._sim.close()

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return self._sim.t

    @property
    def steps(self) -> int:
        """Steps taken (events, on the event core)."""
        return self._sim.steps

    @property
    def finished(self) -> bool:
        """True once T is reached."""
        return self._sim.finished

    @property
    def scenario(self) -> Scenario:
        """The scenario being run (with the seed it runs with)."""
        return Scenario(self._sim.scenario)

    @property
    def counters(self) -> Dict[str, Any]:
        """Impacts, bonds, bounces, fragmentations, … so far."""
        return json.loads(self._sim.counters_json())

    @property
    def pipeline(self) -> Dict[str, Any]:
        """The core, the systems in order, and why the others are left out."""
        return json.loads(self._sim.pipeline_json())

    def summary(self) -> Dict[str, Any]:
        """The summary ``agglo run --summary`` writes, as a dict (of the run so far, or
        of the finished run)."""
        return json.loads(self._sim.summary_json())

    def bodies(self) -> Table:
        """Every body now, id-sorted: the ``--final-state`` columns as NumPy arrays
        (then any quantity an extension carries)."""
        return Table("bodies", self._sim.bodies(), units_of("final_state"))

    def _table(self, name: str) -> Table:
        return Table(name, self._sim.table(name), units_of(name))

    def series(self) -> Table:
        """The time series kept in memory (``run(tables=["series"])``)."""
        return self._table("series")

    def sizes(self) -> Table:
        """The size distribution n_k(t) kept in memory, long format."""
        return self._table("sizes")

    def snapshots(self) -> Table:
        """Every body at every sample, kept in memory."""
        return self._table("snapshots")

    def collisions(self) -> Table:
        """One row per impact, kept in memory."""
        return self._table("collisions")

    def __repr__(self) -> str:
        state = "finished" if self.finished else "running"
        return f"<agglo.Simulation {self.scenario.name!r}: t = {self.t:.6g} s, {self.steps} steps, {state}>"


def _unpickle(state: bytes, hooks, carry) -> Simulation:
    sim = Simulation.__new__(Simulation)
    sim._carry = carry
    sim._sim = _agglo.Simulation._from_restart(state, carry)
    sim._hooks = []
    for kind, function, every, every_events in hooks:
        sim._add_hook(kind, function, every, every_events)
    return sim
