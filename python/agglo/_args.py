"""Whole-number arguments checked before they reach Rust: a value that is not a whole
number, or lies outside its range, is refused with a ScenarioError naming the argument
and the range (numbers that overflowed the conversion raised a bare OverflowError or
TypeError naming nothing, and 1.5 was taken as 1)."""

from __future__ import annotations

import numbers

from ._agglo import ScenarioError

#: The largest seed (seeds are unsigned 64-bit integers).
MAX_SEED = 2**64 - 1
#: The most worker threads a run may ask for (agglo::farm::MAX_THREADS).
MAX_THREADS = 1024
#: The largest count of steps or events (signed 64-bit, far beyond any run).
MAX_COUNT = 2**63 - 1


def whole(name: str, value, lo: int, hi: int) -> int:
    """``value`` as an int in [lo, hi]; a ScenarioError naming ``name`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ScenarioError(f"{name}: allowed a whole number {lo} ≤ {name} ≤ {hi} (got {value!r})")
    value = int(value)
    if not lo <= value <= hi:
        raise ScenarioError(f"{name}: allowed {lo} ≤ {name} ≤ {hi} (got {value})")
    return value
