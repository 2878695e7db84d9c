"""agglo.subgrid: a flow solver's cells advanced from Python (issue 32), with the same
library calls as the C interface: determinism over threads and order, one cell equal to
its batch entry, mass conserved, states kept as bytes, preCICE's Micro Manager
interface, and bad input refused naming the cell and the field."""

import pathlib
import pickle

import numpy as np
import pytest

import agglo
from agglo.subgrid import CellState, Coupling, micro_simulation

CLASSES = 5
PRIMARIES = np.array([1.0, 2.0, 3.0, 5.0, 9.0])  # per body, one per class
BASE = pathlib.Path(__file__).resolve().parents[2] / "scenarios/ballistic_aggregation.json"


def edges_of(base):
    """Classes by primaries: 1, 2, 3-4, 5-8, 9 and up [kg]."""
    m0 = base.primary_mass
    return np.array([0.5, 1.5, 2.5, 4.5, 8.5, 1e9]) * m0


@pytest.fixture(scope="module")
def coupling():
    base = agglo.Scenario.load(BASE)
    # Re-lifted boxes, as these tests were written (persist is the default).
    return Coupling(base, edges_of(base), bodies=300, replicas=2, persist=False)


def monomers(c, phis):
    """Per-cell inputs: monomers at volume fractions ``phis``, at rest on average."""
    b0, m0 = c.primary
    n = len(phis)
    density = np.zeros((n, CLASSES))
    density[:, 0] = np.asarray(phis) / (4.0 / 3.0 * np.pi * b0**3)
    return dict(
        number_density=density,
        mass=np.tile(PRIMARIES * m0, (n, 1)),
        velocity=np.zeros((n, CLASSES, 3)),
        temperature=np.full((n, CLASSES), 300.0),
        granular_temperature=np.ones((n, CLASSES)),
        dt=2e-4,
    )


def test_a_batch_is_the_same_for_any_thread_count_and_order(coupling):
    phis = [0.02, 0.03, 0.04, 0.05]
    inputs = monomers(coupling, phis)
    one, _ = coupling.advance_cells(0, [10, 11, 12, 13], threads=1, **inputs)
    two, _ = coupling.advance_cells(0, [10, 11, 12, 13], threads=2, **inputs)
    order = [2, 0, 3, 1]
    shuffled = {k: (v[order] if isinstance(v, np.ndarray) else v) for k, v in inputs.items()}
    mixed, _ = coupling.advance_cells(0, [12, 10, 13, 11], threads=2, **shuffled)
    for i, cell in enumerate([10, 11, 12, 13]):
        j = order.index(i)
        assert one[i].cell == two[i].cell == mixed[j].cell == cell
        for name in one[i].names():
            assert one[i][name].tobytes() == two[i][name].tobytes(), name
            assert one[i][name].tobytes() == mixed[j][name].tobytes(), name
            assert one[i].se[name].tobytes() == mixed[j].se[name].tobytes(), name


def test_one_cell_is_its_batch_entry_and_conserves_mass(coupling):
    inputs = monomers(coupling, [0.03, 0.05])
    batch, _ = coupling.advance_cells(3, [7, 8], **inputs)
    alone, state = coupling.advance(8, 3, **{k: (v[1] if isinstance(v, np.ndarray) else v)
                                             for k, v in inputs.items()})
    for name in alone.names():
        assert alone[name].tobytes() == batch[1][name].tobytes(), name
    assert isinstance(state, CellState) and state.cell == 8
    # Grains stick: monomers are lost to bigger classes, and no mass is made or lost
    # (the rates cancel to rounding: 1e-12 of the largest).
    rates = alone["mass_rate"]
    assert alone["number_rate"][0] < 0
    assert abs(rates.sum()) <= 1e-12 * np.abs(rates).max()
    assert alone["velocity"].shape == (CLASSES, 3)
    assert alone["impact_rate"].shape == ()
    assert alone.units["number_rate"] == "1/(m^3 s)"


def test_states_round_trip_through_bytes_and_pickle():
    base = agglo.Scenario.load(BASE)
    closed = Coupling(base, edges_of(base), bodies=300, replicas=2, keep_bodies=True)
    inputs = monomers(closed, [0.04])
    first, states = closed.advance_cells(0, [5], **inputs)
    again = CellState.from_bytes(states[0].to_bytes())
    pickled = pickle.loads(pickle.dumps(states[0]))
    a, _ = closed.advance_cells(1, [5], states=[states[0]], **inputs)
    b, _ = closed.advance_cells(1, [5], states=[again], **inputs)
    c, _ = closed.advance_cells(1, [5], states=[pickled], **inputs)
    assert a[0]["number_density"].tobytes() == b[0]["number_density"].tobytes()
    assert a[0]["number_density"].tobytes() == c[0]["number_density"].tobytes()
    # The closed cell went on from its bodies: fewer monomers than it started with.
    assert a[0]["number_density"][0] < first[0]["number_density"][0]
    with pytest.raises(agglo.ScenarioError, match="state"):
        CellState.from_bytes(b"\x01\x02")


def test_micro_manager_interface(coupling):
    Micro = micro_simulation(coupling)
    inputs = {k: (v[0] if isinstance(v, np.ndarray) else v)
              for k, v in monomers(coupling, [0.03]).items()}
    dt = inputs.pop("dt")
    macro = dict(inputs, gas_velocity=[0.0, 0.0, 0.0], gas_temperature=300.0)
    sim = Micro(4)
    first = sim.solve(macro, dt)
    saved = sim.get_state()
    second = sim.solve(macro, dt)
    restored = Micro(4)
    restored.set_state(saved)
    assert restored.solve(macro, dt)["number_rate"].tobytes() == second["number_rate"].tobytes()
    assert "number_rate_se" in first and first["number_rate"].shape == (CLASSES,)


def test_bad_input_names_the_cell_and_the_field(coupling):
    inputs = monomers(coupling, [0.03, 0.03])
    inputs["number_density"][1, 2] = -1.0
    with pytest.raises(agglo.ScenarioError, match=r"cell 9: classes\[2\]\.number_density"):
        coupling.advance_cells(0, [8, 9], **inputs)
    inputs = monomers(coupling, [0.03])
    with pytest.raises(agglo.ScenarioError, match="dt"):
        coupling.advance_cells(0, [1], **dict(inputs, dt=0.0))
    with pytest.raises(agglo.ScenarioError, match=r"velocity: shape \(1, 5\)"):
        coupling.advance_cells(0, [1], **dict(inputs, velocity=np.zeros((1, 5))))
    with pytest.raises(agglo.ScenarioError, match="number_density"):
        coupling.advance_cells(0, [1], **dict(inputs, number_density=np.full((1, 5), np.nan)))
    with pytest.raises(agglo.ScenarioError, match="drag"):
        coupling.advance_cells(0, [1], drag={"sticky": 1}, **inputs)
    with pytest.raises(agglo.ScenarioError, match="edges"):
        Coupling(agglo.Scenario.load(BASE), [1.0, 0.5])


def test_the_kernel_sums_count_the_bonds_of_every_replica():
    base = agglo.Scenario.load(BASE)
    c = Coupling(base, edges_of(base), bodies=300, replicas=3, kernel=True)
    out, _ = c.advance(2, 0, **{k: (v[0] if isinstance(v, np.ndarray) else v)
                               for k, v in monomers(c, [0.04]).items()})
    bonds = out["kernel_bonds"]
    assert bonds.shape == (CLASSES, CLASSES)
    assert np.isnan(out.se["kernel_bonds"]).all()
    # The pooled counts are the bonds of all K boxes; bond_rate is their mean per box
    # per volume and time, so the two agree to rounding.
    per_boxes = out["bond_rate"] * out.box_volume * out.dt * out.replicas
    assert bonds.sum() > 0 and bonds.sum() == pytest.approx(per_boxes, rel=1e-9)
    assert np.all(np.tril(bonds, -1) == 0)  # filled for i <= j only
    assert (out["kernel_exposure"] > 0).any()


def test_energy_rates_close_and_the_primary_comes_from_the_scenario(coupling):
    base = agglo.Scenario.load(BASE)
    assert (base.primary_radius, base.primary_mass) == coupling.primary
    inputs = {k: (v[0] if isinstance(v, np.ndarray) else v)
              for k, v in monomers(coupling, [0.05]).items()}
    out, _ = coupling.advance(3, 0, **inputs)
    dt = inputs["dt"]
    # The solver's mean-flow energy 1/2 |p|^2 / rho per class before and after the rates
    # (all at rest here, so only the rates' own momentum counts).
    rho0 = inputs["number_density"] * inputs["mass"]
    rho1 = rho0 + dt * out["mass_rate"]
    p1 = dt * out["momentum_rate"]
    mean_flow = np.where(rho1 > 0, 0.5 * (p1**2).sum(axis=1) / np.where(rho1 > 0, rho1, 1), 0)
    kinetic = mean_flow.sum() / dt + out["fluctuation_energy_rate"].sum()
    d = out["dissipation_rate"]
    assert d > 0
    # Kinetic energy: field work less dissipation, to rounding (1e-9 of the dissipation);
    # thermal: the dissipation (sticky grains, no reaction heat, no cooling), to the
    # rounding of the thermal sums C rho theta (1e-12 of them, some 1e-5 of D).
    assert abs(kinetic - (out["force_work_rate"] - d)) <= 1e-9 * d
    thermal_scale = 1000.0 * 300.0 * rho0.sum() / dt
    assert abs(out["thermal_energy_rate"].sum() - d) <= 1e-12 * thermal_scale
    assert out.units["fluctuation_energy_rate"] == "W/m^3"
    assert "total_number_rate" in out.names() and not out["ignored"].any()


def test_persistent_cells_take_up_what_transport_brings():
    base = agglo.Scenario.load(BASE)
    c = Coupling(base, edges_of(base), bodies=300, replicas=2, persist=True)
    inputs = monomers(c, [0.04])
    first, states = c.advance_cells(0, [3], **inputs)
    # Transport doubles the monomers: the kept boxes get about 300 more bodies each
    # (Poisson), on top of the ~290 they ended with.
    doubled = dict(inputs, number_density=2 * inputs["number_density"])
    second, _ = c.advance_cells(1, [3], states=states, **doubled)
    assert second[0].box_volume == first[0].box_volume
    assert 500 < second[0]["bodies"] < 700
    with pytest.raises(agglo.ScenarioError, match="persist"):
        Coupling(base, edges_of(base), keep_bodies=True, persist=True)
    # persist is the default, and keep_bodies alone turns it off.
    assert Coupling(base, edges_of(base)).persist
    assert not Coupling(base, edges_of(base), keep_bodies=True).persist


def test_an_anisotropic_class_comes_back_with_its_axes():
    """Issue 37 item 4b: the diagonal of each class's granular temperature tensor,
    lifted from ``granular_anisotropy`` and restricted as
    ``class_granular_temperature_axes``, on a step without impacts (1 ns)."""
    base = agglo.Scenario.load(BASE)
    c = Coupling(base, edges_of(base), bodies=300, replicas=48)
    inputs = dict(monomers(c, [0.02]), dt=1e-9)
    a = np.ones((1, CLASSES, 3))
    a[0, 0] = [10.0, 1.0, 1.0]  # variances 2.5, 0.25, 0.25 at T = 1
    out, _ = c.advance(0, 0, **{k: (v[0] if isinstance(v, np.ndarray) else v)
                               for k, v in inputs.items()},
                       granular_anisotropy=a[0])
    axes, se = out["class_granular_temperature_axes"][0], out.se["class_granular_temperature_axes"][0]
    want = np.array([2.5, 0.25, 0.25])
    assert np.all(se > 0) and np.all(se < 0.1 * want)
    assert np.all(np.abs(axes - want) <= 3 * se), (axes, se)
    with pytest.raises(agglo.ScenarioError, match=r"granular_anisotropy\[1\]"):
        bad = a[0].copy()
        bad[0, 1] = -1.0
        c.advance(0, 0, **{k: (v[0] if isinstance(v, np.ndarray) else v)
                           for k, v in inputs.items()}, granular_anisotropy=bad)
