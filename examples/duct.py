"""A duct in which a gas carries fine grains downstream while they collide and stick:
a one-dimensional finite-volume flow that calls agglo once per cell per macro step
(issue 32, docs/coupling.md, "A worked example").

The gas flows at U along a duct of length L, cut into cells of width dx. Each macro
step dt (U dt <= dx):

1. transport: the grains move with the gas; each size class's number and mass
   densities are advected by the first-order upwind scheme (a sectional method), with
   monomers at volume fraction ``phi_in`` entering at the inlet;
2. agglomeration: every cell's classes go to agglo as one batch
   (``Coupling.advance_cells``); each cell's boxes run dt of collisions, and the
   returned source rates of number and mass per class update the cell.

The grains' fluctuating velocity (granular temperature Tg) is kept at its inlet value
in every cell: the gas's turbulence is assumed to keep them agitated (a flow solver
would transport Tg too and take agglo's figure back). Seeds derive from (cell, step),
so the run is the same bytes for any thread count.

    python examples/duct.py --cells 24 --steps 160 --plot docs/coupling_duct.png

prints the size distribution along the duct; ``--plot`` draws it (needs matplotlib).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

import agglo
from agglo.subgrid import Coupling

ROOT = pathlib.Path(__file__).resolve().parents[1]
# Classes by primaries per body: 1, 2, 3-4, 5-8, 9-16, 17-32, 33 and up.
EDGES_IN_PRIMARIES = np.array([0.5, 1.5, 2.5, 4.5, 8.5, 16.5, 32.5, 1e9])


def run(cells: int, steps: int, length: float = 0.02, speed: float = 2.0, phi_in: float = 0.01,
        bodies: int = 1000, replicas: int = 4, threads: int = 0) -> dict:
    """Run the duct; return the final class densities per cell and the ledgers."""
    base = agglo.Scenario.load(ROOT / "scenarios/ballistic_aggregation.json")
    b0, m0 = base.primary_radius, base.primary_mass  # the primary grain's radius and mass
    # Re-lifted every step (no states are passed back), as the figure in
    # docs/coupling.md was drawn.
    coupling = Coupling(base, EDGES_IN_PRIMARIES * m0, bodies=bodies, replicas=replicas,
                        persist=False)
    k = coupling.classes
    dx = length / cells
    dt = 0.8 * dx / speed  # CFL 0.8
    n_in = phi_in / (4.0 / 3.0 * np.pi * b0**3)  # monomers per m^3 at the inlet
    inflow_n = np.zeros(k)
    inflow_n[0] = n_in
    inflow_m = inflow_n * m0
    n = np.zeros((cells, k))  # number density per class [1/m^3]
    mass = np.zeros((cells, k))  # mass density per class [kg/m^3]
    courant = speed * dt / dx
    mass_in = mass_out = clipped = 0.0
    wall = 0.0
    for step in range(steps):
        # 1. Upwind transport: what leaves cell i enters cell i+1; monomers enter cell 0.
        upstream_n = np.vstack([inflow_n, n[:-1]])
        upstream_m = np.vstack([inflow_m, mass[:-1]])
        mass_out += courant * mass[-1].sum() * dx
        mass_in += courant * inflow_m.sum() * dx
        n = n + courant * (upstream_n - n)
        mass = mass + courant * (upstream_m - mass)
        # 2. Agglomeration: one box per cell holding something, advanced over dt.
        live = np.flatnonzero(n.sum(axis=1) > 0)
        if live.size == 0:
            continue
        # The class's representative mass: its mean (the lightest it may hold when it is
        # empty), kept inside the class's edges and no lighter than a primary grain.
        occupied = n[live] > 0
        low = np.maximum(EDGES_IN_PRIMARIES[:-1] * (1 + 1e-12), 1.0) * m0
        rep = np.where(occupied, mass[live] / np.where(occupied, n[live], 1.0), low)
        rep = np.clip(rep, low, EDGES_IN_PRIMARIES[1:] * (1 - 1e-12) * m0)
        start = time.perf_counter()
        outs, _ = coupling.advance_cells(
            step, live, number_density=n[live], mass=rep,
            velocity=np.zeros((live.size, k, 3)), temperature=np.full((live.size, k), 300.0),
            granular_temperature=np.ones((live.size, k)), dt=dt, threads=threads)
        wall += time.perf_counter() - start
        for i, out in zip(live, outs):
            n[i] += dt * out["number_rate"]
            mass[i] += dt * out["mass_rate"]
        # Sampling noise can take a nearly empty class below zero: clip, and count it.
        negative = mass < 0
        clipped += -mass[negative].sum() * dx
        n = np.maximum(n, 0.0)
        mass = np.maximum(mass, 0.0)
    x = (np.arange(cells) + 0.5) * dx
    held = mass.sum() * dx
    return dict(x=x, n=n, mass=mass, m0=m0, dt=dt, steps=steps, mass_in=mass_in,
                mass_out=mass_out, held=held, clipped=clipped, wall=wall,
                mean_primaries=(mass.sum(axis=1) / m0) / np.maximum(n.sum(axis=1), 1e-300))


def plot(r: dict, path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fractions = r["mass"] / np.maximum(r["mass"].sum(axis=1, keepdims=True), 1e-300)
    labels = ["1", "2", "3-4", "5-8", "9-16", "17-32", "33+"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    a.stackplot(r["x"] * 1e3, fractions.T, labels=labels)
    a.set_xlabel("distance along the duct [mm]")
    a.set_ylabel("mass fraction in class")
    a.set_title("grain mass by primaries per body")
    a.legend(loc="upper right", fontsize=7, title="primaries", title_fontsize=7)
    b.plot(r["x"] * 1e3, r["mean_primaries"], "o-")
    b.set_xlabel("distance along the duct [mm]")
    b.set_ylabel("mean primaries per body")
    b.set_title(f"after {r['steps']} macro steps of {r['dt'] * 1e3:.2f} ms")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cells", type=int, default=24)
    p.add_argument("--steps", type=int, default=160)
    p.add_argument("--bodies", type=int, default=1000)
    p.add_argument("--replicas", type=int, default=4,
                   help="replica boxes K per cell (K >= 4: fewer give standard errors of 1-3 "
                        "degrees of freedom)")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--plot", help="draw the distribution to this PNG (needs matplotlib)")
    a = p.parse_args(argv)
    if a.plot:
        # Before the work, not after it: a missing matplotlib must not cost the run.
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            p.error("--plot needs matplotlib (pip install matplotlib)")
    r = run(a.cells, a.steps, bodies=a.bodies, replicas=a.replicas, threads=a.threads)
    print(f"{a.cells} cells x {a.steps} macro steps of {r['dt']:.3e} s; "
          f"agglo took {r['wall']:.2f} s of wall time")
    print(" x [mm]   mean primaries/body   mass fraction in classes 1, 2, 3-4, 5-8, 9-16, 17-32, 33+")
    for i in range(0, len(r["x"]), max(1, len(r["x"]) // 8)):
        f = r["mass"][i] / max(r["mass"][i].sum(), 1e-300)
        print(f"{r['x'][i] * 1e3:7.2f}   {r['mean_primaries'][i]:8.3f}            "
              + " ".join(f"{v:5.3f}" for v in f))
    balance = r["mass_in"] - r["mass_out"] - r["held"] + r["clipped"]
    print(f"mass per unit duct area: in {r['mass_in']:.6e}, out {r['mass_out']:.6e}, "
          f"held {r['held']:.6e}, clipped {r['clipped']:.3e} kg/m^2; "
          f"imbalance {balance / r['mass_in']:.1e} of the inflow")
    if a.plot:
        plot(r, a.plot)
        print(f"plot: {a.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
