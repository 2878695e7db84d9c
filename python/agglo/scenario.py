"""Scenarios: load, override and check them with the library's own code.

A :class:`Scenario` is immutable: :meth:`Scenario.set` and :meth:`Scenario.with_bodies`
return a new one. Its sections read as attributes mirroring the JSON
(``s.cloud.count``, ``s.material.rho``, ``s.box.half_width``).
"""

from __future__ import annotations

import json
import os
from typing import Any, Mapping, Optional

from . import _agglo
from ._args import MAX_SEED, whole


class Section:
    """A read-only view of one section of a scenario's JSON (attributes mirror keys)."""

    __slots__ = ("_path", "_value")

    def __init__(self, path: str, value: Mapping[str, Any]):
        object.__setattr__(self, "_path", path)
        object.__setattr__(self, "_value", value)

    def __getattr__(self, name: str) -> Any:
        try:
            value = self._value[name]
        except KeyError:
            raise AttributeError(
                f"{self._path} has no field `{name}` (fields: {', '.join(self._value)})"
            ) from None
        return _view(f"{self._path}.{name}", value)

    def __getitem__(self, name: str) -> Any:
        return self.__getattr__(name)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(
            f"scenarios are immutable: use scenario.set({{'{self._path}.{name}': ...}})"
        )

    def __dir__(self):
        return list(self._value)

    def __contains__(self, name: str) -> bool:
        return name in self._value

    def to_dict(self) -> dict:
        """The section as a plain dict (a copy)."""
        return json.loads(json.dumps(self._value))

    def __repr__(self) -> str:
        return f"<{self._path}: {json.dumps(self._value)}>"


def _view(path: str, value: Any) -> Any:
    return Section(path, value) if isinstance(value, dict) else value


class ValidationReport(str):
    """What ``agglo validate`` prints; shown as preformatted HTML in a notebook."""

    warning: Optional[str] = None

    def _repr_html_(self) -> str:
        import html

        text = html.escape(str(self))
        if self.warning:
            text += f"\n<b>{html.escape(self.warning)}</b>"
        return f"<pre>{text}</pre>"


class Scenario:
    """One run's description, checked as ``agglo validate`` checks a file.

    Make one with :meth:`load`, :meth:`from_json` or :meth:`from_dict`. Errors raise
    :class:`agglo.ScenarioError` (a ``ValueError``) naming the field and the allowed
    range.
    """

    __slots__ = ("_inner", "_dict")

    def __init__(self, inner: "_agglo.Scenario"):
        if not isinstance(inner, _agglo.Scenario):
            raise TypeError(
                "make a Scenario with Scenario.load(path), .from_json(text) or .from_dict(d)"
            )
        object.__setattr__(self, "_inner", inner)
        object.__setattr__(self, "_dict", None)

    @classmethod
    def load(cls, path: "str | os.PathLike[str]") -> "Scenario":
        """Read and check a scenario file (JSON)."""
        return cls(_agglo.Scenario.load(os.fspath(path)))

    @classmethod
    def from_json(cls, text: str) -> "Scenario":
        """Parse and check a scenario from JSON text."""
        return cls(_agglo.Scenario.from_json(text))

    @classmethod
    def from_dict(cls, value: Mapping[str, Any]) -> "Scenario":
        """Check a scenario given as a dict (the JSON's structure)."""
        return cls.from_json(json.dumps(value))

    def to_json(self) -> str:
        """The scenario as pretty JSON."""
        return self._inner.to_json()

    def to_dict(self) -> dict:
        """The scenario as a dict (a copy)."""
        return json.loads(self._inner.to_json())

    def save(self, path: "str | os.PathLike[str]") -> None:
        """Write the scenario as a JSON file that ``agglo run`` reads."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.to_json() + "\n")

    def set(self, settings: Mapping[str, Any]) -> "Scenario":
        """A copy with fields overridden by dotted path, exactly as ``agglo run --set``:
        ``s.set({"cloud.count": 500, "time.end": 1e-3})``. Checked as a file is."""
        pairs = [f"{path}={json.dumps(value)}" for path, value in settings.items()]
        return Scenario(self._inner.with_settings(pairs))

    def with_seed(self, seed: int) -> "Scenario":
        """A copy with another seed (as ``agglo run --seed``)."""
        return Scenario(self._inner.with_seed(whole("seed", seed, 0, MAX_SEED)))

    def with_bodies(
        self,
        position,
        velocity=None,
        *,
        primaries=None,
        radius=None,
        mass=None,
        temperature=None,
        id=None,
        separate: bool = False,
    ) -> "Scenario":
        """A copy whose cloud is the given bodies: ``position`` (N, 3) [m], and optional
        ``velocity`` (N, 3) [m/s], ``primaries``, ``radius`` [m], ``mass`` [kg],
        ``temperature`` [K] and ``id`` arrays of N values. Checked by the same
        placed-bodies check as ``cloud.bodies`` (inside the box, no overlaps, distinct
        ids, consistent masses and radii), O(N). A run's end state can hold a few
        overlapping pairs (a merged body grows into a neighbour): ``separate=True`` first
        pushes each such pair apart along its line of centres, keeping its centre of mass
        (positions only change)."""
        import numpy as np

        def f64(a, ndim):
            if a is None:
                return None
            a = np.ascontiguousarray(a, dtype=np.float64)
            if a.ndim != ndim:
                raise _agglo.ScenarioError(
                    f"with_bodies: an array of {ndim} dimension(s) expected, got shape {a.shape}"
                )
            return a

        ids = None if id is None else _ids(id)
        return Scenario(
            self._inner.with_bodies(
                f64(position, 2),
                f64(velocity, 2),
                f64(primaries, 1),
                f64(radius, 1),
                f64(mass, 1),
                f64(temperature, 1),
                ids,
                bool(separate),
            )
        )

    def validate(self) -> ValidationReport:
        """The report ``agglo validate`` prints (the pipeline the scene runs, why the
        other systems are left out, the memory it needs). Raises ScenarioError when the
        scene cannot be built or cannot fit in memory."""
        text, warning = self._inner.validation_report()
        report = ValidationReport(text)
        report.warning = warning
        return report

    @property
    def primary_radius(self) -> float:
        """The primary grain's radius b0 [m]."""
        return self._inner.derived()["primary_radius"]

    @property
    def primary_mass(self) -> float:
        """The primary grain's mass (4/3) pi b0^3 rho [kg]: the unit a flow solver's class
        edges are given in (``agglo.subgrid.Coupling``), without making a coupling."""
        return self._inner.derived()["primary_mass"]

    @property
    def volume_fraction(self) -> float:
        """The cloud's initial volume fraction."""
        return self._inner.derived()["volume_fraction"]

    @staticmethod
    def json_schema() -> dict:
        """The JSON Schema of the scenario format (``agglo schema``)."""
        return json.loads(_agglo.Scenario.json_schema())

    def _json(self) -> dict:
        if self._dict is None:
            object.__setattr__(self, "_dict", json.loads(self._inner.to_json()))
        return self._dict

    def __getattr__(self, name: str) -> Any:
        data = self._json()
        if name in data:
            return _view(name, data[name])
        raise AttributeError(f"the scenario has no field `{name}` (fields: {', '.join(data)})")

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"scenarios are immutable: use scenario.set({{'{name}': ...}})")

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(self._json()))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scenario) and self._json() == other._json()

    def __repr__(self) -> str:
        d = self._json()
        return f"Scenario({d['name']!r}, N = {d['cloud']['count']}, T = {d['time']['end']} s, seed {d['seed']})"

    def __reduce__(self):
        return (Scenario.from_json, (self.to_json(),))


def _ids(id):
    """``id`` as a contiguous uint64 array, or a ScenarioError naming the first value that
    is not a whole number in [0, 2**64 - 1] (as the CSV path refuses it): numpy's cast
    truncated 0.5 to 0 and wrapped -1 to 2**64 - 1."""
    import numpy as np

    a = np.asarray(id)
    if a.dtype.kind == "u":
        return np.ascontiguousarray(a, dtype=np.uint64)
    if a.dtype.kind == "i" and (a.size == 0 or a.min() >= 0):
        return np.ascontiguousarray(a, dtype=np.uint64)
    if a.dtype.kind == "f" and np.all(np.isfinite(a)) and np.all(a == np.floor(a)) \
            and (a.size == 0 or (a.min() >= 0 and a.max() <= 2**53)):
        # Whole floats up to 2**53 are exact; beyond, they stand for several integers.
        return np.ascontiguousarray(a, dtype=np.uint64)
    flat = a.reshape(-1) if a.dtype.kind in "iuf" else np.asarray(a, dtype=object).reshape(-1)
    for i, value in enumerate(flat):
        value = value.item() if hasattr(value, "item") else value
        if isinstance(value, float) and value.is_integer() and 0 <= value <= 2**53:
            continue
        try:
            whole(f"with_bodies: id.{i}", value, 0, MAX_SEED)
        except _agglo.ScenarioError:
            raise _agglo.ScenarioError(
                f"with_bodies: id.{i}: allowed a whole number 0 ≤ id ≤ 2^64 − 1 "
                f"(exactly, so a float at most 2^53) (got {value!r})") from None
    return np.ascontiguousarray(np.array([int(v) for v in flat], dtype=np.uint64))
