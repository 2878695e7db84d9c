"""Type stub of the compiled module agglo._agglo (python/src/). Use the package `agglo`:
its classes wrap these."""

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

class ScenarioError(ValueError):
    """A scenario that cannot be read or is out of range; names the field and range."""

class AggloError(RuntimeError):
    """A run or an output that failed, with its causes."""

class Scenario:
    @staticmethod
    def load(path: str) -> Scenario: ...
    @staticmethod
    def from_json(text: str) -> Scenario: ...
    @staticmethod
    def json_schema() -> str: ...
    def to_json(self) -> str: ...
    def with_settings(self, settings: List[str]) -> Scenario: ...
    def with_seed(self, seed: int) -> Scenario: ...
    def validation_report(self) -> Tuple[str, Optional[str]]: ...
    def with_bodies(
        self,
        position: npt.NDArray[np.float64],
        velocity: Optional[npt.NDArray[np.float64]] = None,
        primaries: Optional[npt.NDArray[np.float64]] = None,
        radius: Optional[npt.NDArray[np.float64]] = None,
        mass: Optional[npt.NDArray[np.float64]] = None,
        temperature: Optional[npt.NDArray[np.float64]] = None,
        id: Optional[npt.NDArray[np.uint64]] = None,
        separate: bool = False,
    ) -> Scenario: ...
    def derived(self) -> Dict[str, float]: ...

class Simulation:
    def __init__(self, scenario: Scenario, seed: Optional[int] = None) -> None: ...
    def run(
        self,
        until: Optional[float] = None,
        tables: Optional[Dict[str, Optional[str]]] = None,
        sampling: Optional[str] = None,
        recording: Optional[str] = None,
        summary: Optional[str] = None,
        final_state: Optional[str] = None,
        live: Optional[str] = None,
        progress: bool = False,
        command_line: Optional[str] = None,
    ) -> bool: ...
    def step(self, n: int = 1) -> bool: ...
    def close(self) -> None: ...
    @property
    def t(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def finished(self) -> bool: ...
    @property
    def scenario(self) -> Scenario: ...
    def counters_json(self) -> str: ...
    def summary_json(self) -> str: ...
    def pipeline_json(self) -> str: ...
    def bodies(self) -> Dict[str, npt.NDArray]: ...
    def table(self, name: str) -> Dict[str, object]: ...

def ensemble(
    scenario: Scenario, seeds: Sequence[int], threads: int = 0, tables: Sequence[str] = ...
) -> List[Tuple[str, Dict[str, Dict[str, object]]]]: ...
def table_units(table: str) -> Dict[str, str]: ...

class CellState:
    """A subgrid cell's state between macro steps (opaque, picklable)."""
    def to_bytes(self) -> bytes: ...
    @staticmethod
    def from_bytes(bytes: bytes) -> "CellState": ...
    @property
    def cell(self) -> int: ...
    @property
    def macro_steps(self) -> int: ...

class Coupling:
    """agglo::subgrid's settings; wrapped by agglo.subgrid.Coupling."""
    def __init__(
        self,
        scenario: Scenario,
        edges: Sequence[float],
        bodies: Optional[int] = 1000,
        replicas: int = 4,
        keep_bodies: bool = False,
        kernel: bool = False,
        target_se: float = 0.05,
        min_bodies: int = 100,
        max_bodies: int = 100000,
        persist: bool = False,
    ) -> None: ...
    @property
    def classes(self) -> int: ...
    @property
    def edges(self) -> List[float]: ...
    @property
    def primary(self) -> Tuple[float, float]: ...
    @property
    def replicas(self) -> int: ...
    def advance_cells(
        self,
        macro_step: int,
        cells: Sequence[int],
        number_density: npt.NDArray,
        mass: npt.NDArray,
        velocity: npt.NDArray,
        temperature: npt.NDArray,
        granular_temperature: npt.NDArray,
        dt: npt.NDArray,
        gas_velocity: npt.NDArray,
        gas_temperature: npt.NDArray,
        drag: Optional[str] = None,
        states: Optional[Sequence[Optional[CellState]]] = None,
        threads: int = 0,
    ) -> Tuple[List[Dict[str, object]], List[CellState]]: ...
