"""The worked coupled example (examples/duct.py) at a small size: grains carried down a
duct grow along it, the duct's mass balance closes, and the run is the same bytes on one
and two threads."""

import importlib.util
import pathlib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]


def duct():
    spec = importlib.util.spec_from_file_location("duct", ROOT / "examples/duct.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_duct_grows_grains_downstream_and_balances_its_mass():
    d = duct()
    one = d.run(cells=4, steps=10, bodies=300, threads=1)
    two = d.run(cells=4, steps=10, bodies=300, threads=2)
    assert one["n"].tobytes() == two["n"].tobytes()
    assert one["mass"].tobytes() == two["mass"].tobytes()
    # Downstream cells have had longer to grow: the mean size rises along the duct,
    # from nearly monomers (1 primary per body) at the inlet.
    sizes = one["mean_primaries"]
    assert 1.0 < sizes[0] < sizes[-1], sizes
    assert np.all(np.diff(sizes) > 0), sizes
    # Mass: what came in = what left + what is held − what clipping added. Transport
    # and the sources (which cancel between classes) are exact to rounding: 1e-12.
    balance = one["mass_in"] - one["mass_out"] - one["held"] + one["clipped"]
    assert abs(balance) <= 1e-12 * one["mass_in"], balance


def test_plot_without_matplotlib_fails_before_the_work(monkeypatch, capsys):
    d = duct()
    ran = []
    monkeypatch.setattr(d, "run", lambda *a, **k: ran.append(1))
    # An entry of None in sys.modules makes `import matplotlib` raise ImportError.
    monkeypatch.setitem(__import__("sys").modules, "matplotlib", None)
    try:
        d.main(["--plot", "x.png"])
    except SystemExit as e:
        assert e.code == 2
    else:
        raise AssertionError("--plot without matplotlib was accepted")
    assert ran == [], "the duct ran before the refusal"
    assert "needs matplotlib" in capsys.readouterr().err
