"""Scenarios from Python: the library's own loading, --set and validation, with the
command line's messages."""

import json
import pickle
import subprocess

import numpy as np
import pytest

import agglo


def test_load_and_attribute_access_mirror_the_json(scenarios):
    s = agglo.Scenario.load(scenarios / "quick_demo.json")
    raw = json.loads((scenarios / "quick_demo.json").read_text())
    assert s.name == raw["name"]
    assert s.cloud.count == raw["cloud"]["count"]
    assert s.box.half_width == raw["box"]["half_width"]
    assert s.material.rho == raw["material"]["rho"]
    assert s.cloud.v_rel == raw["cloud"]["v_rel"]
    with pytest.raises(AttributeError, match="no field `nosuch`"):
        s.cloud.nosuch
    with pytest.raises(AttributeError, match="immutable"):
        s.cloud.count = 3


def test_from_dict_and_from_json_round_trip(scenarios):
    s = agglo.Scenario.load(scenarios / "quick_demo.json")
    assert agglo.Scenario.from_dict(s.to_dict()) == s
    assert agglo.Scenario.from_json(s.to_json()) == s
    assert pickle.loads(pickle.dumps(s)) == s


def test_set_takes_the_paths_and_messages_of_the_command_line(scenarios, agglo_bin):
    s = agglo.Scenario.load(scenarios / "quick_demo.json")
    t = s.set({"cloud.count": 120, "time.end": 1e-3})
    assert (t.cloud.count, t.time.end) == (120, 1e-3)
    assert s.cloud.count == 300, "set returns a copy"
    assert t.name == "quick_demo (cloud.count=120, time.end=0.001)"
    # The same message as `agglo run --set` (its first line after "error: ").
    with pytest.raises(agglo.ScenarioError) as python_error:
        s.set({"material.rho": -1})
    cli = subprocess.run(
        [str(agglo_bin), "run", str(scenarios / "quick_demo.json"), "--set", "material.rho=-1", "-q"],
        capture_output=True,
        text=True,
    )
    assert cli.returncode != 0
    assert "material.rho" in str(python_error.value)
    assert str(python_error.value) in cli.stderr, (str(python_error.value), cli.stderr)
    assert isinstance(python_error.value, ValueError)


def test_validate_returns_the_report_agglo_validate_prints(scenarios, agglo_bin):
    path = scenarios / "quick_demo.json"
    report = agglo.Scenario.load(path).validate()
    cli = subprocess.run([str(agglo_bin), "validate", str(path)], capture_output=True, text=True, check=True)
    # Everything but the memory line (the memory available changes between calls).
    strip = lambda text: [l for l in text.splitlines() if not l.startswith("memory:")]
    assert strip(report) == strip(cli.stdout)
    assert "<pre>" in report._repr_html_()
    assert "pipeline (" in report


def test_with_bodies_is_checked_like_cloud_bodies(scenarios):
    s = agglo.Scenario.load(scenarios / "two_body.json")
    b0 = s.primary_radius
    position = np.array([[-2 * b0, 0, 0], [2 * b0, 0, 0], [0, 3 * b0, 0]])
    velocity = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 0]])
    t = s.with_bodies(position, velocity, id=[10, 20, 30])
    assert t.cloud.count == 3
    assert [b["id"] for b in t.cloud.bodies] == [10, 20, 30]
    # Overlapping bodies are refused, naming the field.
    with pytest.raises(agglo.ScenarioError, match="cloud.bodies"):
        s.with_bodies(np.array([[0.0, 0, 0], [0.5 * b0, 0, 0]]))
    # ... unless asked to separate them (an end state's few overlaps): pushed apart to
    # contact along x, their centre of mass (equal masses: the midpoint) kept.
    apart = s.with_bodies(np.array([[0.0, 0, 0], [0.5 * b0, 0, 0]]), separate=True)
    x = [b["position"][0] for b in apart.cloud.bodies]
    assert x[1] - x[0] == pytest.approx(2 * b0, rel=1e-8)
    assert (x[0] + x[1]) / 2 == pytest.approx(0.25 * b0, rel=1e-12)
    # Outside the box.
    d = s.box.half_width
    with pytest.raises(agglo.ScenarioError, match="cloud.bodies"):
        s.with_bodies(np.array([[2 * d, 0, 0]]))
    with pytest.raises(agglo.ScenarioError, match=r"velocity: shape"):
        s.with_bodies(position, velocity[:2])
    with pytest.raises(agglo.ScenarioError, match="primaries: 2 values for 3 bodies"):
        s.with_bodies(position, primaries=[1.0, 1.0])


def test_with_bodies_runs_the_given_bodies(scenarios):
    s = agglo.Scenario.load(scenarios / "two_body.json")
    b0 = s.primary_radius
    position = np.array([[-3 * b0, 0, 0], [3 * b0, 0, 0]])
    velocity = np.array([[2.0, 0, 0], [-2.0, 0, 0]])
    sim = agglo.Simulation(s.with_bodies(position, velocity, id=[5, 9]))
    start = sim.bodies()
    assert list(start["id"]) == [5, 9]
    np.testing.assert_array_equal(start["x"], position[:, 0])
    sim.run()
    assert sim.counters["impacts"] >= 1
