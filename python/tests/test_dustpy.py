"""agglo's measured kernels inside DustPy (issue 38): a DustPy ring driven by kernels that
`agglo kernel` measured follows agglo's own cluster count, and what `install_dustpy`
installs survives DustPy's updates.

DustPy (from PyPI, the `test` extra: it builds from source and needs gfortran) and the
agglo binary ($AGGLO_BIN, else target/debug/agglo; `cargo build` first). The kernel module
is loaded by file path, as a DustPy user who copied it would.

The ring: ballistic aggregation in a box of side L (every contact sticks) is one DustPy
radial cell with gas, drift and diffusion off, Σ_k = m_k n_k L and H_k = L/√(4π), so that
DustPy's vertical length √(2π(H_i² + H_j²)) is L and its rate per area is the box's rate
per volume times L. DustPy's N/N0 is Σ_k Σ_k/m_k over its start; agglo's the mean of
bodies/N0 over the same 16 seeds the kernel was measured on (so the two share their
noise, and what is compared is the coagulation, not two samples).
"""

import importlib.util
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

dustpy = pytest.importorskip("dustpy", reason="DustPy: pip install 'dustpy==1.0.9' (needs gfortran)")
from dustpy import Simulation, std  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SPEC = importlib.util.spec_from_file_location("agglo_kernel_dp", ROOT / "python/agglo/kernel.py")
kernel = importlib.util.module_from_spec(SPEC)
sys.modules[SPEC.name] = kernel
SPEC.loader.exec_module(kernel)

SCENE = ROOT / "scenarios/ballistic_aggregation.json"
SEEDS = 16
N0 = 10_000
SIDE_CM = 2.0  # the scene's box: half_width 0.01 m
# The primary's mass [g]: the shipped scene's total mass / N0 (4/3 π b0³ ρ at φ = 0.05).
PRIMARY_G = 4.0005736781e-5
# The documented grid (docs/kernel.md) and one whose first point is the primary
# (`primary`: the scenario's primary mass; 5 decades to 4 g, 36 points).
DOCUMENTED = "dustpy:1e-5,1,7"
ON_PRIMARY = "dustpy:primary,4,7"
# Consecutive windows for a time-dependent kernel, ×4 each: the system cools and
# coarsens by orders of magnitude over the run (N: 1e4 → 12).
WINDOWS = ["0:0.001", "0.001:0.004", "0.004:0.016", "0.016:0.064", "0.064:0.5"]
# Five initial mean free times: K_11 n0 = 1.39 cm³/s × 1e4 / 8 cm³ → 0.58 ms each.
EARLY = 3e-3


def binary() -> Path:
    import os

    path = Path(os.environ.get("AGGLO_BIN", ROOT / "target/debug/agglo"))
    if not path.exists():
        pytest.skip(f"no agglo binary at {path}: cargo build, or set AGGLO_BIN")
    return path


def measure(out: Path, grid: str, window: str | None = None) -> Path:
    args = [str(binary()), "kernel", str(SCENE), "--bins", grid, "--seeds", str(SEEDS),
            "--threads", "0", "--units", "cgs", "--out", str(out), "-q"]
    if window:
        args += ["--window", window]
    subprocess.run(args, check=True)
    return out


@pytest.fixture(scope="module")
def agglo_curve(tmp_path_factory):
    """Mean N/N0 of the scene's seeds 1..16 (the seeds `agglo kernel` pools) at the
    scene's log-spaced sample times."""
    out = tmp_path_factory.mktemp("runs")
    # The scene's samples, log-spaced from 1e-4 s at 20 per decade, land on the first
    # step at or after each nominal time, which differs by seed (by < 1 %): each run's
    # count is interpolated to the nominal times.
    t = np.concatenate([[0.0], 1e-4 * 10 ** (np.arange(0, 75) / 20)])
    t = t[t <= 0.5]
    curves = []
    for seed in range(1, SEEDS + 1):
        path = out / f"series_{seed}.csv"
        subprocess.run([str(binary()), "run", str(SCENE), "--seed", str(seed), "-q",
                        "--series", str(path)], check=True)
        table = np.genfromtxt(path, delimiter=",", names=True)
        assert table["bodies"][0] == N0
        curves.append(np.interp(t, table["t"], table["bodies"] / N0))
    return t, np.mean(curves, axis=0)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    out = tmp_path_factory.mktemp("kernels")
    return {
        "documented": measure(out / "documented.npz", DOCUMENTED),
        "documented_14": measure(out / "documented_14.npz", "dustpy:1e-5,1,14"),
        "primary": measure(out / "primary.npz", ON_PRIMARY),
        "windows": [measure(out / f"w{i}.npz", DOCUMENTED, w) for i, w in enumerate(WINDOWS)],
    }


def ring(files, times):
    """DustPy's N/N0 at `times` [s] in the ring, driven by `files` through install_dustpy."""
    first = kernel.load(files[0])
    m = first.mass_centres
    decades = np.ceil(np.log10(m[-1] / m[0]) - 1e-9)
    sim = Simulation()
    sim.verbosity = 0
    sim.ini.grid.mmin, sim.ini.grid.mmax = m[0], m[-1]
    sim.ini.grid.Nmbpd = int(round((m.size - 1) / decades))
    sim.ini.grid.Nr = 3  # DustPy computes kernels in interior cells: one ring, cell 1
    sim.ini.dust.rhoMonomer = first.scenario["material"]["rho"] * 1e-3
    sim.initialize()
    sim.dust.H[...] = SIDE_CM / np.sqrt(4 * np.pi)
    sim.dust.H.updater = None
    for field in (sim.dust.v.rad, sim.dust.D):
        field[...] = 0.0
        field.updater = None
    sim.integrator.instructions = sim.integrator.instructions[:1]  # no gas evolution
    sim.t.updater = lambda s: s.t.cfl * std.dust.dt(s)  # the dust's own time step
    sigma = np.array(sim.dust.SigmaFloor) * 0.1
    primary = int(np.searchsorted(first.mass_edges, PRIMARY_G, side="right") - 1)
    sigma[1, primary] = m[primary] * N0 / SIDE_CM**3 * SIDE_CM
    sim.dust.Sigma[...] = sigma
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", kernel.FilledKernelWarning)
        kernel.install_dustpy(sim, files)
    sim.update()
    sim.writer = None
    start = (np.asarray(sim.dust.Sigma[1]) / m).sum()
    counts = []
    for t in times:
        if t > float(sim.t):
            sim.t.snapshots = np.array([t])
            sim.run()
        counts.append((np.asarray(sim.dust.Sigma[1]) / m).sum() / start)
    return np.array(counts)


# docs/kernel.md's table: the largest |DustPy/agglo − 1| to 3 ms and to the end, and the
# ratio at 0.5 s. Deterministic (same seeds, same DustPy), so checked to the digits quoted
# (±0.05 percentage points): a change in the engine or the fill shows here and in the docs.
DOCUMENTED_FIGURES = {
    "primary": (1.34, 21.1, 0.821),
    "documented": (1.41, 20.6, 0.830),
    "documented_14": (1.59, 19.6, 0.846),
    "windows": (1.44, 13.2, 0.894),
}


def figures(ratio, t):
    return (100 * np.abs(ratio[t <= EARLY] - 1).max(), 100 * np.abs(ratio - 1).max(), ratio[-1])


def check_documented(name, ratio, t):
    early, worst, end = figures(ratio, t)
    doc = DOCUMENTED_FIGURES[name]
    assert early == pytest.approx(doc[0], abs=0.006), (name, early)
    assert worst == pytest.approx(doc[1], abs=0.06), (name, worst)
    assert end == pytest.approx(doc[2], abs=6e-4), (name, end)


def test_primary_grid_starts_at_the_primary(files):
    k = kernel.load(files["primary"])
    assert k.mass_centres[0] == pytest.approx(PRIMARY_G, rel=1e-9)
    assert k.classes == 36 and k.mass_centres[-1] == pytest.approx(4.0, rel=1e-12)
    # Points at 1, 1.39, 1.93, 2.68 … primaries (10^(1/7) apart): the dimers sit in
    # class 2, and class 1 holds no body — DustPy's sticking feeds it all the same, so
    # even this grid needs the fill.
    assert k.exposure[0, 0] > 0 and k.exposure[2, 2] > 0
    assert k.exposure[1].max() == 0 and k.measured[1].max() == 0
    # docs/kernel.md's figures for this file: the monomer kernel and the sampled
    # geometric kernel and relative speed, exposure-weighted like K (deterministic: to the
    # digits quoted).
    assert k.kernel[0, 0] == pytest.approx(1.386, abs=5e-4)
    assert k.geometric_kernel[0, 0] == pytest.approx(1.181, abs=5e-4)
    assert k.relative_speed_mean[0, 0] == pytest.approx(208.8, abs=0.05)


@pytest.mark.parametrize("grid", ["primary", "documented", "documented_14"])
def test_ring_follows_agglo_on_any_grid(files, agglo_curve, grid):
    t, agglo = agglo_curve
    ratio = ring([files[grid]], t) / agglo
    early = t <= EARLY
    # Up to five free times a whole-run kernel is the kernel of the epoch (measured:
    # within 1.6 % on all three grids): 2 %, the target. Without the fill of the
    # classes no body occupies, the documented grids stall (DustPy 116× agglo's count).
    assert np.abs(ratio[early] - 1).max() < 0.02, ratio[early]
    # To the end (0.5 s, N/N0 = 0.0015): a whole-run K is a time average of a cooling
    # system, so DustPy runs fast (measured: 21 % at worst, at 0.36 s): 25 %.
    assert np.abs(ratio - 1).max() < 0.25, ratio
    check_documented(grid, ratio, t)


def test_windowed_kernels_follow_agglo_closer(files, agglo_curve):
    t, agglo = agglo_curve
    windowed = ring(files["windows"], t) / agglo
    whole = ring([files["documented"]], t) / agglo
    assert np.abs(windowed[t <= EARLY] - 1).max() < 0.02, windowed
    assert np.abs(windowed - 1).max() < 0.25, windowed
    # Each window's K describes its epoch: past 10 ms the windowed run stays closer to
    # agglo than the whole-run kernel (measured: 13 % against 20 % at worst).
    late = t >= 0.01
    assert np.abs(windowed[late] - 1).max() < np.abs(whole[late] - 1).max()
    check_documented("windows", windowed, t)


@pytest.fixture(scope="module")
def fragmenting(tmp_path_factory):
    """quick_demo (bonds, bounces and fragments), on a grid that holds it."""
    out = tmp_path_factory.mktemp("quick") / "quick.npz"
    subprocess.run([str(binary()), "kernel", str(ROOT / "scenarios/quick_demo.json"),
                    "--bins", "dustpy:1e-5,1,7", "--seeds", "2", "--threads", "1",
                    "--units", "cgs", "--out", str(out), "-q"], check=True)
    return kernel.load(out)


def disc(k, rho_g_cm3):
    """DustPy's default disc on the file's grid, 8 radial cells."""
    m = k.mass_centres
    sim = Simulation()
    sim.verbosity = 0
    sim.ini.grid.mmin, sim.ini.grid.mmax = m[0], m[-1]
    sim.ini.grid.Nmbpd = int(round((m.size - 1) / np.ceil(np.log10(m[-1] / m[0]) - 1e-9)))
    sim.ini.grid.Nr = 8
    sim.ini.dust.rhoMonomer = rho_g_cm3
    sim.initialize()
    return sim


def test_installed_probabilities_and_kernel_survive_updates(fragmenting):
    k = fragmenting
    assert k.counts[2].sum() > 0 and k.counts[1].sum() > 0  # fragments and bounces seen
    sim = disc(k, k.scenario["material"]["rho"] * 1e-3)
    with pytest.warns(kernel.FilledKernelWarning, match="class pairs"):
        installed = kernel.install_dustpy(sim, k)
    filled = installed.fills[0]
    seen = k.counts_total > 0
    # Measured probabilities where impacts were seen, unchanged by the fill.
    np.testing.assert_array_equal(filled["stick"][seen], k.probability[0][seen])
    np.testing.assert_array_equal(filled["frag"][seen], k.probability[2][seen])

    def check():
        for ir in range(1, 7):
            np.testing.assert_array_equal(sim.dust.p.stick[ir], filled["stick"])
            np.testing.assert_array_equal(sim.dust.p.frag[ir], filled["frag"])
        expected = kernel.dustpy_kernel(filled["kernel"], np.asarray(sim.dust.H))
        np.testing.assert_allclose(sim.dust.kernel, expected, rtol=1e-12, atol=0)

    check()
    sim.update()  # DustPy's own p_frag would make them 0 / 1 from its v_rel and vFrag
    check()
    # A few integration steps: DustPy's H moves (its St changes with Σ), the kernel's
    # vertical factor follows it at every update.
    h0 = np.array(sim.dust.H)
    sim.writer = None
    sim.t.snapshots = [float(sim.t) + 10 * 3.15e7]
    sim.run()
    assert not np.array_equal(h0, np.asarray(sim.dust.H))
    check()


def test_install_refuses_another_density_or_grid(fragmenting):
    k = fragmenting
    sim = disc(k, 1.67)  # DustPy's default rhoMonomer; the scenario has 3000 kg/m³
    with pytest.raises(ValueError, match=r"rhoMonomer = 3\b"):
        kernel.install_dustpy(sim, k)
    other = Simulation()
    other.verbosity = 0
    other.ini.grid.Nr = 4
    other.ini.dust.rhoMonomer = 3.0
    other.initialize()  # DustPy's default mass grid, 1e-12..1e5 g
    with pytest.raises(ValueError, match=r"sim\.grid\.m .*1e-12\.\.100000 g"):
        kernel.install_dustpy(other, k)
