"""python/agglo/kernel.py against a file `agglo kernel` writes (numpy and pytest only).

The module is loaded by file path, so this runs without the compiled agglo package. The
binary is $AGGLO_BIN, or target/debug/agglo of this checkout (`cargo build` first).
"""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SPEC = importlib.util.spec_from_file_location("agglo_kernel", ROOT / "python/agglo/kernel.py")
kernel = importlib.util.module_from_spec(SPEC)
# Registered before it runs, as an import would (dataclasses look their module up).
sys.modules[SPEC.name] = kernel
SPEC.loader.exec_module(kernel)

SCENE = ROOT / "scenarios/ballistic_aggregation.json"
# 500 primaries: b0 = 5.8e-4 m at the scene's size ratio, m0 = 8.0e-4 g, about one collision
# time (1.6 ms) to the end: a few dozen classes of the grid below fill.
SETTINGS = ["--set", "cloud.count=500", "--set", "time.end=2e-3"]
DUSTPY = (1e-4, 1e-1, 7)  # mmin [g], mmax [g], bins per decade


def binary() -> Path:
    path = Path(os.environ.get("AGGLO_BIN", ROOT / "target/debug/agglo"))
    if not path.exists():
        pytest.skip(f"no agglo binary at {path}: cargo build, or set AGGLO_BIN")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    out = tmp_path_factory.mktemp("kernel")
    grid = "dustpy:{},{},{}".format(*DUSTPY)
    paths = {}
    for units in ("cgs", "si"):
        path = out / f"k_{units}.npz"
        subprocess.run(
            [str(binary()), "kernel", str(SCENE), "--bins", grid, "--seeds", "2",
             "--threads", "1", "--units", units, "--out", str(path), "-q", *SETTINGS],
            check=True,
        )
        paths[units] = path
    return paths


def dustpy_m(mmin, mmax, nmbpd):
    """DustPy's Simulation._makemassgrid, restated."""
    decades = np.ceil(np.log10(mmax) - np.log10(mmin))
    nm = int(decades * nmbpd) + 1
    return np.logspace(np.log10(mmin), np.log10(mmax), num=nm, base=10.0)


def test_file_has_documented_shapes_and_units(files):
    k = kernel.load(files["cgs"])
    m = dustpy_m(*DUSTPY)
    nm = m.size
    assert k.classes == nm == 22
    np.testing.assert_allclose(k.mass_centres, m, rtol=1e-12)
    assert k.mass_edges.shape == (nm + 1,)
    for name in ("kernel", "exposure", "counts_total", "kernel_se_poisson", "geometric_kernel"):
        assert k.arrays[name].shape == (nm, nm), name
    for name in ("counts", "kernel_outcome", "probability", "probability_low"):
        assert k.arrays[name].shape == (3, nm, nm), name
    assert k.fragment_mass_fraction.shape == (nm, nm, nm)
    assert k.outcomes == ["bond", "bounce", "fragment"]
    assert k.array_units["kernel"] == "cm^3/s"
    assert k.array_units["exposure"] == "s/cm^3"
    assert k.array_units["mass_centres"] == "g"
    assert k.runs == 2 and list(k.seeds) == [1, 2]
    # Symmetric, and K = C/E wherever there was exposure.
    K = k.kernel
    np.testing.assert_array_equal(np.isnan(K), np.isnan(K.T))
    seen = k.exposure > 0
    np.testing.assert_allclose(K[seen], (k.counts_total / np.where(seen, k.exposure, 1))[seen])
    # Ballistic aggregation: every impact bonds.
    assert k.counts_total.sum() > 0
    assert k.counts[1].sum() == 0 and k.counts[2].sum() == 0


def test_si_and_cgs_files_agree(files):
    cgs = kernel.load(files["cgs"])
    si_raw = kernel.load(files["si"], units="si")
    assert si_raw.array_units["kernel"] == "m^3/s"
    seen = ~np.isnan(cgs.kernel)
    # The same runs: the cgs numbers are the SI ones times 1e6 (to rounding).
    np.testing.assert_allclose(cgs.kernel[seen], si_raw.kernel[seen] * 1e6, rtol=1e-12)
    # An SI file loaded as cgs is converted.
    si_as_cgs = kernel.load(files["si"])
    np.testing.assert_allclose(si_as_cgs.kernel[seen], cgs.kernel[seen], rtol=1e-12)
    np.testing.assert_allclose(si_as_cgs.mass_centres, cgs.mass_centres, rtol=1e-12)


def test_dustpy_arrays_apply_the_vertical_factor_and_half_diagonal(files):
    k = kernel.load(files["cgs"])
    nm, nr = k.classes, 5
    H = np.linspace(1e9, 5e9, nr)[:, None] * np.ones(nm)  # cm
    with pytest.warns(kernel.FilledKernelWarning, match=r"class pairs \(.* %\) were not measured"):
        arrays = kernel.dustpy_arrays(k, H, m_grid=dustpy_m(*DUSTPY))
    for name in ("kernel", "stick", "frag"):
        assert arrays[name].shape == (nr, nm, nm), name
    K3 = arrays["kernel_3d"]
    i = int(np.argmax(np.diag(K3)))  # the monomer class: the best-measured pair
    assert K3[i, i] > 0
    expected = 0.5 * K3[i, i] / np.sqrt(2 * np.pi * 2 * H[2, i] ** 2)
    assert arrays["kernel"][2, i, i] == pytest.approx(expected, rel=1e-12)
    j = i + 3
    expected = K3[i, j] / np.sqrt(2 * np.pi * (H[2, i] ** 2 + H[2, j] ** 2))
    assert arrays["kernel"][2, i, j] == pytest.approx(expected, rel=1e-12)
    # DustPy's own kernel fills j >= i only (its coagulation reads that triangle).
    assert arrays["kernel"][2, j, i] == 0.0
    assert not arrays["kernel"][:, np.tril_indices(nm, -1)[0], np.tril_indices(nm, -1)[1]].any()
    # Measured entries are the file's K; the rest filled, every entry finite and >= 0.
    measured = arrays["measured"]
    np.testing.assert_array_equal(measured, k.exposure > 0)
    np.testing.assert_array_equal(k.measured, (k.exposure > 0).astype(np.int64))  # the file's mask
    np.testing.assert_array_equal(K3[measured], k.kernel[measured])
    assert np.isfinite(K3).all() and (K3 >= 0).all()
    # DustPy leaves the boundary cells at zero.
    assert not arrays["kernel"][0].any() and not arrays["kernel"][-1].any()
    # Ballistic: stick = 1 where impacts were seen, frag = 0.
    assert arrays["stick"][2, i, i] == 1.0 and arrays["frag"][2, i, i] == 0.0
    with pytest.raises(ValueError, match=r"sim\.grid\.m \(29 masses, 1e-05\.\.0\.1 g\)"):
        kernel.dustpy_arrays(k, H, m_grid=dustpy_m(1e-5, 1e-1, 7))


def test_fill_reaches_every_class_the_runs_left_empty(files):
    k = kernel.load(files["cgs"])
    with pytest.warns(kernel.FilledKernelWarning) as caught:
        filled = kernel.fill(k)
    # The grid's points between the masses n primaries can have hold no body: their rows
    # and columns have no exposure, and are the ones DustPy's sticking feeds anyway.
    empty = filled["empty_classes"]
    assert empty.size > 0
    assert not (k.exposure[empty] > 0).any()
    K = filled["kernel"]
    assert np.isfinite(K).all() and np.array_equal(K, K.T)
    assert (K[empty] > 0).any(axis=1).all()
    # The warning says how much was filled, in the file's own units.
    nm = k.classes
    assert f"{filled['filled_pairs']} of {nm * nm} class pairs" in str(caught[0].message)
    assert f"{empty.size} of {nm} classes never held a body" in str(caught[0].message)
    assert " g)" in str(caught[0].message)
    # "zero" keeps the old behaviour: nothing there.
    zero = kernel.fill(k, missing="zero", warn=False)["kernel"]
    assert not zero[empty].any()
    with pytest.raises(ValueError, match="missing: allowed"):
        kernel.fill(k, missing="nearest")


def test_fill_is_exact_on_a_power_law():
    # Interpolation in log mass, geometric in K, is exact for K = m_i^a m_j^a: rows of
    # measured classes (including whole classes that were never occupied, and single
    # pairs that never coexisted) come back to rounding.
    m = np.logspace(-5, 0, 36)
    exact = np.outer(m, m) ** (1 / 3) + 0.0
    holes = exact.copy()
    for c in (0, 3, 4, 17, 35):  # whole classes, at both ends too
        holes[c, :] = np.nan
        holes[:, c] = np.nan
    holes[10, 20] = holes[20, 10] = np.nan
    filled = kernel.fill_symmetric(holes, np.log(m))
    inside = np.ones(36, bool)
    inside[[0, 35]] = False  # beyond the measured range: the nearest value, not exact
    np.testing.assert_allclose(filled[np.ix_(inside, inside)], exact[np.ix_(inside, inside)],
                               rtol=1e-12)
    np.testing.assert_allclose(filled[0, 1:35], exact[1, 1:35], rtol=1e-12)


def test_kernel_module_imports_without_the_compiled_extension(files):
    # A DustPy user's environment: numpy, no agglo._agglo. The package from the source
    # tree, with the extension made unimportable even if it is installed.
    script = f"""
import sys
class NoExtension:
    def find_spec(self, name, path=None, target=None):
        if name == "agglo._agglo":
            raise ImportError("agglo._agglo blocked by the test")
sys.meta_path.insert(0, NoExtension())
sys.path.insert(0, {str(ROOT / "python")!r})
from agglo.kernel import load, fill, install_dustpy, dustpy_arrays
k = load({str(files["cgs"])!r})
assert k.classes == 22
import agglo
assert "agglo._agglo" not in sys.modules
try:
    agglo.Scenario
except ImportError as e:
    assert "blocked" in str(e)
else:
    raise SystemExit("agglo.Scenario imported without the extension")
print("ok")
"""
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"


def test_openfoam_table(files, tmp_path):
    k = kernel.load(files["si"], units="si")
    table = kernel.openfoam_table(k)
    nm = k.classes
    assert table["dSph"].shape == (nm,) and table["rate"].shape == (nm, nm)
    # Diameters back to masses: ρπd³/6 = the class mass [kg].
    rho = k.scenario["material"]["rho"]
    np.testing.assert_allclose(rho * np.pi * table["dSph"] ** 3 / 6, k.mass_centres, rtol=1e-12)
    np.testing.assert_allclose(table["rate"], np.nan_to_num(k.kernel_outcome[0]))
    path = tmp_path / "coalescenceTable"
    kernel.write_openfoam_table(k, path)
    text = path.read_text()
    assert text.startswith("FoamFile") and text.count("\n    (") == nm
