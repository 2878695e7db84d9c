"""agglo: particle agglomeration in thermochemically reacting granular flows, from Python.

The engine is Rust (the compiled module ``agglo._agglo``); this package is a thin layer
over it. A scenario is loaded and checked by the same code as ``agglo validate``, a run
goes through the same code as ``agglo run`` (same bytes written for the same scenario
and seed), and results come back as NumPy columns.

    >>> import agglo
    >>> s = agglo.Scenario.load("scenarios/quick_demo.json").set({"time.end": 1e-3})
    >>> sim = agglo.Simulation(s, seed=2)
    >>> sim.run(tables=["series"])
    >>> sim.series().to_pandas()          # doctest: +SKIP
    >>> sim.summary()["growth"]["growth_ratio"]   # doctest: +SKIP

All quantities are SI. See docs/python.md.
"""

from ._agglo import AggloError, ScenarioError, __version__
from .scenario import Scenario, ValidationReport
from .simulation import Carry, Simulation
from .table import Table
from .ensemble import Ensemble, ensemble
from . import subgrid

__all__ = [
    "AggloError",
    "Carry",
    "Ensemble",
    "Scenario",
    "ScenarioError",
    "Simulation",
    "Table",
    "ValidationReport",
    "ensemble",
    "subgrid",
    "__version__",
]
