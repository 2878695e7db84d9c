"""agglo inside a flow solver: a box of grains advanced over each cell's macro time step,
its homogenized figures handed back (Zohdi 2004 section 9; docs/coupling.md).

The same library calls as the C interface (capi/) and ``agglo::subgrid`` in Rust:

>>> import numpy as np, agglo
>>> from agglo.subgrid import Coupling
>>> base = agglo.Scenario.load("scenarios/ballistic_aggregation.json")
>>> c = Coupling(base, edges, bodies=1000, replicas=4)          # doctest: +SKIP
>>> outs, states = c.advance_cells(0, cells=[0, 1], number_density=n,  # (cells, classes)
...     mass=m, velocity=v, temperature=T, granular_temperature=Tg,    # v: (cells, classes, 3)
...     dt=1e-4, gas_velocity=[0, 0, 0], gas_temperature=300.0)       # doctest: +SKIP
>>> outs[0]["number_rate"], outs[0].se["number_rate"]                # doctest: +SKIP

Every figure is the mean over the cell's K replica boxes, with its standard error in
``.se``; units are in ``.units``. Per-cell arguments (``dt``, ``gas_velocity``,
``gas_temperature``) may be given once for all cells. A cell's output is the same bytes
for any ``threads`` and any order of ``cells``.

:class:`MicroSimulation` has the interface of preCICE's Micro Manager
(``solve(macro_data, dt) -> dict``, ``get_state``/``set_state``):
``micro_simulation(coupling)`` returns such a class bound to a coupling.
"""

from __future__ import annotations

import json
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from . import _agglo
from ._agglo import CellState
from ._args import MAX_THREADS, whole
from .scenario import Scenario

__all__ = ["Coupling", "CellOutput", "CellState", "MicroSimulation", "micro_simulation"]


#: Ranges of the Rust side's unsigned integers (cell ids and steps: u64; sizes: u32).
_MAX_U64 = 2**64 - 1
_MAX_U32 = 2**32 - 1


class CellOutput:
    """One cell's figures after a macro step: ``out[name]`` is the mean over the
    replicas, ``out.se[name]`` its standard error, ``out.units[name]`` the unit.

    Per class: ``number_rate`` [1/(m³ s)], ``mass_rate`` [kg/(m³ s)], ``momentum_rate``
    (classes, 3) [N/m³], ``number_density`` [1/m³], ``mass_density`` [kg/m³],
    ``velocity`` (classes, 3) [m/s], ``temperature`` [K], ``class_granular_temperature``
    [m²/s²] (unbiased; NaN where no replica held two bodies of the class),
    ``class_granular_temperature_axes`` (classes, 3) [m²/s²] (the diagonal T_xx, T_yy,
    T_zz of each class's granular temperature tensor, unbiased, over the same replicas),
    ``present`` and ``granular_replicas`` [replicas holding one, two bodies of the class],
    ``fluctuation_energy_rate`` and ``thermal_energy_rate`` [W/m³] (transport
    ½ρ·3T and Cρθ with them and energy closes), ``ignored`` (1 for a trace class that was
    not lifted). Per cell: ``total_number_rate`` [1/(m³ s)] (the growth),
    ``granular_temperature``, ``gas_momentum_rate`` (3), ``force_work_rate``,
    ``heat_loss_rate``, ``reaction_heat_rate``, ``dissipation_rate``,
    ``fracture_energy_rate`` [W/m³], ``impact_rate``, ``bond_rate``, ``bounce_rate``,
    ``fragment_rate`` [1/(m³ s)], ``bodies`` [per box]. With ``Coupling(kernel=True)``:
    ``kernel_exposure`` [s/m³], ``kernel_bonds``, ``kernel_bounces``,
    ``kernel_fragments`` (classes, classes), the pooled sums of ``agglo kernel`` over the
    replicas (their ``se`` is NaN).

    A standard error covers replica noise only (not the bias of a finite box or Δt,
    docs/coupling.md); count rates have a Poisson floor, and NaN means "not measured".
    """

    __slots__ = ("mean", "se", "units", "cell", "macro_step", "dt", "replicas", "box_volume")

    def __init__(self, d: Dict[str, Any]):
        self.mean: Dict[str, np.ndarray] = d["mean"]
        self.se: Dict[str, np.ndarray] = d["se"]
        self.units: Dict[str, str] = d["units"]
        self.cell: int = d["cell"]
        self.macro_step: int = d["macro_step"]
        self.dt: float = d["dt"]
        self.replicas: int = d["replicas"]
        self.box_volume: float = d["box_volume"]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.mean[name]

    def names(self) -> List[str]:
        return list(self.mean)

    def __repr__(self) -> str:
        return (f"<CellOutput cell {self.cell} step {self.macro_step}: "
                f"{len(self.mean)} figures over {self.replicas} replicas>")


def _rows(values, n: int, per_cell: Tuple[int, ...], name: str) -> np.ndarray:
    """``values`` as a contiguous float64 array of shape (n, *per_cell); a value given
    once (shape ``per_cell``) is repeated for every cell."""
    a = np.asarray(values, dtype=np.float64)
    if a.shape == per_cell:
        a = np.broadcast_to(a, (n,) + per_cell)
    if a.shape != (n,) + per_cell:
        raise _agglo.ScenarioError(
            f"{name}: shape {a.shape} (must be {(n,) + per_cell}, or {per_cell} for every cell)")
    return np.ascontiguousarray(a)


class Coupling:
    """The settings every cell shares: the base ``scenario`` (its material, impact,
    physics, core and seed; the cell sets the box, velocities, end time and gas), the
    class ``edges`` [kg], N = ``bodies`` per box (``None``: sized for a relative standard
    error ``target_se`` of the impact rate within [``min_bodies``, ``max_bodies``]), K =
    ``replicas`` boxes per cell, whether cells keep their bodies between macro steps
    (a closed cell, ``keep_bodies``) or keep them and adjust them to what transport
    changed (``persist``: bodies added or removed, velocities shifted and rescaled per
    class; with no transport the closed cell; the default unless ``keep_bodies``, since
    re-lifted chains drift as Δt shrinks — ``persist=False`` lifts every step afresh),
    and whether to pool the kernel sums.
    """

    def __init__(self, scenario, edges: Sequence[float], *, bodies: Optional[int] = 1000,
                 replicas: int = 4, keep_bodies: bool = False, kernel: bool = False,
                 target_se: float = 0.05, min_bodies: int = 100, max_bodies: int = 100_000,
                 persist: Optional[bool] = None):
        if not isinstance(scenario, Scenario):
            scenario = Scenario.load(scenario)
        # Whole numbers checked by name (1.5 was taken as 1, 2**40 raised a bare
        # OverflowError); their upper ranges are the Rust side's u32.
        if bodies is not None:
            bodies = whole("bodies", bodies, 0, _MAX_U32)
        self._c = _agglo.Coupling(scenario._inner, [float(e) for e in edges], bodies,
                                  whole("replicas", replicas, 0, _MAX_U32), bool(keep_bodies),
                                  bool(kernel), float(target_se),
                                  whole("min_bodies", min_bodies, 0, _MAX_U32),
                                  whole("max_bodies", max_bodies, 0, _MAX_U32),
                                  None if persist is None else bool(persist))

    @property
    def classes(self) -> int:
        """The number of size classes."""
        return self._c.classes

    @property
    def persist(self) -> bool:
        """Whether cells keep their boxes and adjust them to transport (the default
        unless ``keep_bodies``)."""
        return self._c.persist

    @property
    def edges(self) -> np.ndarray:
        """The class edges [kg]."""
        return np.array(self._c.edges)

    @property
    def primary(self) -> Tuple[float, float]:
        """The primary grain's radius [m] and mass [kg]."""
        return self._c.primary

    def advance_cells(self, macro_step: int, cells: Iterable[int], *, number_density, mass,
                      velocity, temperature, granular_temperature, dt, gas_velocity=(0.0, 0.0, 0.0),
                      gas_temperature=300.0, drag: Optional[Dict[str, Any]] = None,
                      states: Optional[Sequence[Optional[CellState]]] = None,
                      threads: int = 0,
                      granular_anisotropy=None) -> Tuple[List[CellOutput], List[CellState]]:
        """Advance a macro step's ``cells`` (their ids) on ``threads`` Rust threads (0: one
        per core), the GIL released. Per-class arrays have shape (cells, classes),
        ``velocity`` (cells, classes, 3); ``dt`` [s], ``gas_temperature`` [K] and
        ``gas_velocity`` [m/s] are per cell or one for all. ``granular_anisotropy``
        (cells, classes, 3), optional, splits each class's granular temperature T over the
        axes: component i's variance is T·3a_i/(a_x + a_y + a_z) (``None``: isotropic,
        [1, 1, 1]). ``drag`` is the scenario's
        ``field.drag.relaxation`` form (``{"stokes": {"viscosity": 1.8e-5}}``), ``None`` for
        none. ``states``: each cell's state from its last step (or ``None``). Raises
        ``ScenarioError`` naming every cell and field out of range."""
        cells = [whole("cells", c, 0, _MAX_U64) for c in cells]
        n, k = len(cells), self.classes
        outs, new_states = self._c.advance_cells(
            whole("macro_step", macro_step, 0, _MAX_U64), cells,
            _rows(number_density, n, (k,), "number_density"),
            _rows(mass, n, (k,), "mass"),
            _rows(velocity, n, (k, 3), "velocity"),
            _rows(temperature, n, (k,), "temperature"),
            _rows(granular_temperature, n, (k,), "granular_temperature"),
            _rows(dt, n, (), "dt"),
            _rows(gas_velocity, n, (3,), "gas_velocity"),
            _rows(gas_temperature, n, (), "gas_temperature"),
            None if drag is None else json.dumps(drag),
            None if states is None else list(states),
            whole("threads", threads, 0, MAX_THREADS),
            None if granular_anisotropy is None
            else _rows(granular_anisotropy, n, (k, 3), "granular_anisotropy"),
        )
        return [CellOutput(d) for d in outs], new_states

    def advance(self, cell: int, macro_step: int, *, state: Optional[CellState] = None,
                **inputs) -> Tuple[CellOutput, CellState]:
        """One cell: per-class arrays of shape (classes,), ``velocity`` (classes, 3), the
        rest as in :meth:`advance_cells` (the same figures as that cell in a batch)."""
        batched = {name: np.asarray(value, dtype=np.float64)[None, ...]
                   for name, value in inputs.items() if name not in ("drag", "threads")}
        outs, states = self.advance_cells(macro_step, [cell], states=[state],
                                          drag=inputs.get("drag"),
                                          threads=inputs.get("threads", 1), **batched)
        return outs[0], states[0]


class MicroSimulation:
    """preCICE Micro Manager's micro simulation: one per macro cell. Bind a coupling with
    :func:`micro_simulation`; ``macro_data`` holds ``number_density``, ``mass``,
    ``velocity``, ``temperature``, ``granular_temperature`` (per class),
    ``gas_velocity``, ``gas_temperature`` and optionally ``drag``; ``solve`` returns every
    figure's mean by name and its standard error as ``NAME_se``."""

    coupling: Optional[Coupling] = None

    def __init__(self, sim_id: int):
        if self.coupling is None:
            raise _agglo.AggloError("MicroSimulation: bind a coupling with micro_simulation(coupling)")
        self._id = int(sim_id)
        self._step = 0
        self._state: Optional[CellState] = None

    def solve(self, macro_data: Dict[str, Any], dt: float) -> Dict[str, Any]:
        data = dict(macro_data)
        out, self._state = self.coupling.advance(self._id, self._step, state=self._state, dt=dt, **data)
        self._step += 1
        result: Dict[str, Any] = dict(out.mean)
        result.update({f"{name}_se": se for name, se in out.se.items()})
        return result

    def get_state(self) -> Tuple[int, Optional[bytes]]:
        return self._step, None if self._state is None else self._state.to_bytes()

    def set_state(self, state: Tuple[int, Optional[bytes]]) -> None:
        self._step, data = state
        self._state = None if data is None else CellState.from_bytes(data)


def micro_simulation(coupling: Coupling) -> type:
    """A :class:`MicroSimulation` class bound to ``coupling`` (preCICE's Micro Manager
    makes one instance per cell from the class it is given)."""
    return type("AggloMicroSimulation", (MicroSimulation,), {"coupling": coupling})
