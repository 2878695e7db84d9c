#!/usr/bin/env python3
"""REBOUND peer benchmark for the engine's "cloud" scenario.

N equal hard spheres (radius b0) at random non-overlapping positions in the
periodic cube [-D, D]^3 (D = 0.01 m), size ratio s = 2 b0 / (V/N)^(1/3) = 0.6
(V = (2D)^3, i.e. volume fraction pi s^3 / 6 = 0.113 for every N), velocity
= (10, 10, 100) m/s + (U[-v0,v0], U[-0.1v0,0.1v0], U[-0.1v0,0.1v0]), v0 = 100
m/s, no gravity, integrated to T with a fixed step.

Variants: merge (REBOUND collision_resolve="merge") and hardsphere
(collision_resolve="hardsphere", constant coefficient of restitution eps).

Prints one JSON line. Run with the venv made by setup.sh (next to this file;
venv at $PEER_REBOUND_VENV, default ${TMPDIR:-/tmp}/rebound-venv):
    $PEER_REBOUND_VENV/bin/python bench.py --n 1000 --variant merge --merge-impl pbc
    $PEER_REBOUND_VENV/bin/python bench.py --n 1000 --variant hardsphere --zohdi-H 3e7
"""
import argparse
import ctypes
import json
import math
import os
import sys
import time

import numpy as np
import rebound

D = 0.01            # half box [m]
L = 2.0 * D         # box edge [m]
S_RATIO = 0.6       # s = 2 b / (V/N)^(1/3)
V0 = 100.0          # perturbation amplitude [m/s]
VMEAN = (10.0, 10.0, 100.0)
RHO = 1000.0        # material density [kg/m^3]; dynamics independent of it
# largest possible |v_i - v_j|: x spread 2 v0, y and z spread 2 * 0.1 v0
VREL_MAX = 2.0 * V0 * math.sqrt(1.0 + 0.1**2 + 0.1**2)


def radius_for(n):
    return 0.5 * S_RATIO * (L**3 / n) ** (1.0 / 3.0)


def place_spheres(n, b, rng):
    """Random sequential addition of non-overlapping spheres (periodic)."""
    dmin = 2.0 * b
    ncell = max(1, int(L // dmin))
    cw = L / ncell
    cells = {}
    pos = np.empty((n, 3))
    k = 0
    attempts = 0
    while k < n:
        batch = rng.uniform(-D, D, size=(max(64, n - k), 3))
        for p in batch:
            attempts += 1
            if attempts > 200 * n + 10000:
                raise RuntimeError("could not place spheres")
            ci = [int((p[a] + D) / cw) % ncell for a in range(3)]
            ok = True
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    for dz in (-1, 0, 1):
                        key = ((ci[0] + dx) % ncell, (ci[1] + dy) % ncell, (ci[2] + dz) % ncell)
                        for j in cells.get(key, ()):
                            d = p - pos[j]
                            d -= L * np.round(d / L)
                            if d @ d < dmin * dmin:
                                ok = False
                                break
                        if not ok:
                            break
                    if not ok:
                        break
                if not ok:
                    break
            if ok:
                pos[k] = p
                cells.setdefault(tuple(ci), []).append(k)
                k += 1
                if k == n:
                    break
    return pos


def count_overlaps(x, r):
    """Pairs with |x_i - x_j|_periodic < r_i + r_j (minimum image)."""
    n = len(r)
    if n < 2:
        return 0
    rmax = r.max()
    cw = max(2.0 * rmax, 1e-12)
    ncell = max(1, int(L // cw))
    if ncell < 3:
        # all-pairs (small N or huge bodies)
        cnt = 0
        for i in range(n - 1):
            d = x[i + 1:] - x[i]
            d -= L * np.round(d / L)
            cnt += int(np.sum(np.einsum("ij,ij->i", d, d) < (r[i + 1:] + r[i]) ** 2))
        return cnt
    cw = L / ncell
    idx = (np.floor((x + D) / cw).astype(np.int64)) % ncell
    cells = {}
    for i, c in enumerate(map(tuple, idx)):
        cells.setdefault(c, []).append(i)
    cnt = 0
    for i in range(n):
        c = idx[i]
        cand = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    cand.extend(cells.get(((c[0] + dx) % ncell, (c[1] + dy) % ncell, (c[2] + dz) % ncell), ()))
        cand = np.array([j for j in set(cand) if j > i], dtype=np.int64)
        if cand.size:
            d = x[cand] - x[i]
            d -= L * np.round(d / L)
            cnt += int(np.sum(np.einsum("ij,ij->i", d, d) < (r[cand] + r[i]) ** 2))
    return cnt


def snapshot(sim):
    ps = sim.particles
    a = np.array([(p.x, p.y, p.z, p.vx, p.vy, p.vz, p.m, p.r) for p in ps])
    return a.reshape(-1, 8)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, required=True)
    ap.add_argument("--variant", choices=["merge", "hardsphere"], required=True)
    ap.add_argument("--T", type=float, default=0.01)
    ap.add_argument("--dt", type=float, default=None,
                    help="fixed step [s]; default: disp-frac * b0 / vrel_max, rounded so T/dt is an integer")
    ap.add_argument("--disp-frac", type=float, default=0.5,
                    help="default dt keeps max relative pair displacement per step <= disp-frac * b0 (default 0.5)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--eps", type=float, default=0.5, help="coefficient of restitution (hardsphere)")
    ap.add_argument("--zohdi-H", type=float, default=0.0,
                    help="if > 0: restitution e(v) = 1 - sqrt(2 rho v^2 / (3 H)) (the engine's law, a0=0, af=1)")
    ap.add_argument("--collision", default="tree", choices=["tree", "linetree", "direct", "line"])
    ap.add_argument("--nroot", type=int, default=1, help="root boxes per axis (box split into nroot^3 trees)")
    ap.add_argument("--nghost", type=int, default=1,
                    help="ghost-box rings for collision search (1 = periodic contacts; 0 = diagnostic only, misses contacts across faces)")
    ap.add_argument("--merge-impl", default="rebound", choices=["rebound", "pbc"],
                    help="rebound: stock 'merge'; pbc: same but uses the ghost-box shift (C helper)")
    ap.add_argument("--cor-impl", default="c", choices=["c", "python"],
                    help="restitution callback in C (libpeer_cor.so) or a Python ctypes callback")
    ap.add_argument("--max-wall", type=float, default=None,
                    help="stop after this many wall seconds (reports completed=false and t reached)")
    ap.add_argument("--chunk", type=int, default=None, help="steps per sim.steps() call")
    ap.add_argument("--overlaps", action="store_true", help="also count overlapping pairs at the end")
    args = ap.parse_args()

    n0 = args.n
    b0 = radius_for(n0)
    rng = np.random.default_rng(args.seed)

    T = args.T
    dt_target = args.dt if args.dt is not None else args.disp_frac * b0 / VREL_MAX
    nsteps = max(1, int(math.ceil(T / dt_target - 1e-9)))
    dt = T / nsteps

    t_setup = time.perf_counter()
    pos = place_spheres(n0, b0, rng)
    vel = np.empty((n0, 3))
    vel[:, 0] = VMEAN[0] + rng.uniform(-V0, V0, n0)
    vel[:, 1] = VMEAN[1] + rng.uniform(-0.1 * V0, 0.1 * V0, n0)
    vel[:, 2] = VMEAN[2] + rng.uniform(-0.1 * V0, 0.1 * V0, n0)
    m0 = RHO * 4.0 / 3.0 * math.pi * b0**3

    sim = rebound.Simulation()
    sim.gravity = "none"
    sim.G = 0.0
    sim.integrator = "leapfrog"     # gravity none -> pure drift (DKD)
    sim.dt = dt
    sim.boundary = "periodic"
    sim.root_size = L / args.nroot
    sim.N_root_x = sim.N_root_y = sim.N_root_z = args.nroot
    sim.N_ghost_x = sim.N_ghost_y = sim.N_ghost_z = args.nghost
    sim.collision = args.collision
    sim.rand_seed = args.seed       # REBOUND shuffles each step's collision list

    keep = []   # keep ctypes objects alive
    cor_impl = None
    merge_impl = None
    lib = None
    so = os.path.join(sys.prefix, "libpeer_cor.so")
    if os.path.exists(so):
        lib = ctypes.CDLL(so)
    if args.variant == "merge":
        if args.merge_impl == "rebound":
            sim.collision_resolve = "merge"
            merge_impl = "rebound"
        else:
            if lib is None:
                raise SystemExit("--merge-impl pbc needs libpeer_cor.so (run setup.sh)")
            ftype = type(sim._collision_resolve)
            fp = ftype(("peer_merge_pbc", lib))
            keep.append(fp)
            sim._collision_resolve = fp
            merge_impl = "pbc"
    else:
        sim.collision_resolve = "hardsphere"
        ftype = type(sim._coefficient_of_restitution)
        if args.cor_impl == "c" and lib is not None:
            ctypes.c_double.in_dll(lib, "peer_cor_eps").value = args.eps
            ctypes.c_double.in_dll(lib, "peer_cor_H").value = args.zohdi_H
            ctypes.c_double.in_dll(lib, "peer_cor_rho").value = RHO
            fp = ftype(("peer_cor_const", lib))
            cor_impl = "c"
        else:
            eps = args.eps
            fp = ftype(lambda r, v: eps)
            cor_impl = "python"
        keep.append(fp)
        sim._coefficient_of_restitution = fp

    for i in range(n0):
        sim.add(m=m0, r=b0, x=pos[i, 0], y=pos[i, 1], z=pos[i, 2],
                vx=vel[i, 0], vy=vel[i, 1], vz=vel[i, 2])
    p_init = (m0 * vel).sum(axis=0)
    ke_fluct0 = 0.5 * m0 * float(((vel - vel.mean(axis=0)) ** 2).sum())
    t_setup = time.perf_counter() - t_setup

    chunk = args.chunk or max(1, min(nsteps, 200))
    # stop points: every `chunk` steps plus ~log-spaced early points (for the N(t) trace)
    stops = set(range(chunk, nsteps, chunk)) | {nsteps}
    stops |= {int(x) for x in np.unique(np.round(np.geomspace(1, nsteps, 24)))}
    stops = sorted(s for s in stops if 1 <= s <= nsteps)
    si = 0
    done = 0
    trace = []          # (t, N, cumulative hardsphere bounces, wall) after each chunk
    psteps = 0          # sum over steps of the particle count (differs from n0*steps for merge)
    t0 = time.perf_counter()
    wall = 0.0
    while done < nsteps:
        k = stops[si] - done
        si += 1
        nb = sim.N
        sim.steps(k)
        done += k
        psteps += k * 0.5 * (nb + sim.N)
        wall = time.perf_counter() - t0
        trace.append((sim.t, sim.N, int(sim.collisions_log_n), wall))
        if args.max_wall is not None and wall > args.max_wall:
            break
    completed = done == nsteps

    a = snapshot(sim)
    nf = len(a)
    p_fin = (a[:, 6:7] * a[:, 3:6]).sum(axis=0)
    drift = float(np.linalg.norm(p_fin - p_init) / np.linalg.norm(p_init))
    vcm = p_fin / a[:, 6].sum()
    ke_fluct = 0.5 * float((a[:, 6:7] * (a[:, 3:6] - vcm) ** 2).sum())
    mass_drift = float(abs(a[:, 6].sum() - n0 * m0) / (n0 * m0))

    out = {
        "n": n0,
        "variant": args.variant,
        "collision": args.collision,
        "dt": dt,
        "steps": done,
        "steps_planned": nsteps,
        "T": T,
        "t_reached": sim.t,
        "completed": completed,
        "wall_s": round(wall, 4),
        "collisions": int(sim.collisions_log_n) if args.variant == "hardsphere" else n0 - nf,
        "collisions_kind": "resolved_bounces" if args.variant == "hardsphere" else "merges",
        "final_n": nf,
        "bf_over_b0": float(a[:, 7].mean() / b0),
        "momentum_drift": drift,
        "mass_drift": mass_drift,
        "ke_fluct_ratio": ke_fluct / ke_fluct0,
        "rebound_version": rebound.__version__,
        "b0": b0,
        "disp_per_step_over_b0": VREL_MAX * dt / b0,
        "particle_steps_per_s": n0 * done / wall if wall > 0 else None,
        "actual_particle_steps_per_s": psteps / wall if wall > 0 else None,
        "seed": args.seed,
        "nroot": args.nroot,
        "nghost": args.nghost,
        "setup_s": round(t_setup, 3),
    }
    if args.variant == "hardsphere":
        out["eps"] = args.eps
        out["zohdi_H"] = args.zohdi_H
        out["cor_impl"] = cor_impl
    else:
        out["merge_impl"] = merge_impl
    if trace:
        # entries nearest to ~log-spaced times, always incl. the last point
        tt = np.array([e[0] for e in trace])
        idx = sorted({int(np.argmin(abs(tt - x))) for x in np.geomspace(tt[0], tt[-1], 16)} | {len(trace) - 1})
        out["trace_t_n_coll_wall"] = [[float(f"{trace[i][0]:.4e}"), trace[i][1], trace[i][2], round(trace[i][3], 3)] for i in idx]
    if args.overlaps:
        out["overlaps_end"] = count_overlaps(a[:, 0:3], a[:, 7])
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
