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

# The compiled module loads on the first use of a name below (PEP 562), not at
# `import agglo`: `agglo.kernel` — reading kernel files and installing them into DustPy —
# needs numpy only, so `from agglo.kernel import load` works where the extension cannot
# be imported (docs/kernel.md). The first of these names read imports everything, in the
# order an eager import would, and raises the extension's ImportError if it is missing.
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


def _load_compiled() -> dict:
    import importlib

    from ._agglo import AggloError, ScenarioError, __version__
    from .scenario import Scenario, ValidationReport
    from .simulation import Carry, Simulation
    from .table import Table

    # Not `from . import subgrid`: that form asks this package for the attribute first,
    # which would come back here.
    subgrid = importlib.import_module(".subgrid", __name__)
    # Last: the function `ensemble` replaces the submodule of that name as the attribute.
    from .ensemble import Ensemble, ensemble

    del importlib
    return dict(locals())


_loading = False


def __getattr__(name):
    global _loading
    if name not in __all__ or _loading:
        raise AttributeError(f"module 'agglo' has no attribute {name!r}")
    _loading = True
    try:
        loaded = _load_compiled()
    finally:
        _loading = False
    globals().update(loaded)
    return loaded[name]


def __dir__():
    return sorted(set(globals()) | set(__all__))
