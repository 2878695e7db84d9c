"""Shared fixtures: the repository, its scenarios, and the `agglo` binary to compare with."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"


def agglo_binary() -> pathlib.Path:
    """The command-line binary: $AGGLO_BIN, else target/release/agglo or target/debug/agglo
    (whichever is newer), else `agglo` on PATH."""
    if os.environ.get("AGGLO_BIN"):
        return pathlib.Path(os.environ["AGGLO_BIN"]).resolve()
    built = [p for p in (ROOT / "target/release/agglo", ROOT / "target/debug/agglo") if p.exists()]
    if built:
        return max(built, key=lambda p: p.stat().st_mtime)
    on_path = shutil.which("agglo")
    if on_path:
        return pathlib.Path(on_path)
    pytest.skip("no agglo binary: cargo build first (or set AGGLO_BIN)")


@pytest.fixture
def agglo_bin() -> pathlib.Path:
    return agglo_binary()


@pytest.fixture
def scenarios() -> pathlib.Path:
    return SCENARIOS
