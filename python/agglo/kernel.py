"""Load a kernel file written by ``agglo kernel`` and hand it to a coagulation code.

``agglo kernel SCENARIO --bins GRID --seeds S --out kernel.npz`` measures, on the
consumer's mass grid, the collision kernel K_ij and the outcome probabilities of every
pair of mass classes (docs/outputs.md, "agglo kernel", lists every array with its unit).

This module needs numpy only: ``from agglo.kernel import ...`` does not import the
compiled extension (``import agglo`` loads it on first use of ``agglo.Scenario`` and the
rest), and the file itself imports nothing from agglo, so it can be copied alone into a
DustPy project (only :func:`measure` needs the compiled package). Into DustPy:

>>> from agglo.kernel import install_dustpy
>>> sim.ini.dust.rhoMonomer = 1.0          # the scenario's density [g/cm³]: checked
>>> sim.initialize()
>>> install_dustpy(sim, "kernel.npz")     # kernel, p.stick, p.frag and their updaters

or by hand (the arrays last until DustPy's next update, unless their updaters are set):

>>> k = load("kernel.npz")                 # every array in cgs; k.array_units: each unit
>>> arrays = dustpy_arrays(k, sim.dust.H, m_grid=sim.grid.m)

Conventions (stored in the file as ``convention``): the rate of (i, j) impacts per unit
volume is ``K_ij n_i n_j`` for i != j and ``0.5 K_ii n_i**2`` for i = j, so a hard-sphere
kernel is ``pi (a_i + a_j)**2 <|dv|>`` on and off the diagonal. OpenFOAM's population
balance uses the same convention (its birth term halves the j == k pair), so its
coalescence rate is K itself. DustPy stores ``(1 - 0.5 delta_ij) K_ij`` divided by its
vertical-integration length ``sqrt(2 pi (H_i**2 + H_j**2))``, for j >= i only:
``sim.dust.kernel`` is then in cm**2/s (DustPy's own unit for it, "Collision kernel
[cm²/s]"), from a K in cm**3/s.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "DustPyKernel",
    "FilledKernelWarning",
    "KernelFile",
    "dustpy_arrays",
    "dustpy_kernel",
    "fill",
    "install_dustpy",
    "load",
    "measure",
    "openfoam_table",
    "write_openfoam_table",
]


def measure(scenario, bins: str, out, *, seeds: int = 8, threads: int = 0, window=None,
            units: str = "si", parquet=None, load_units: str = "cgs") -> "KernelFile":
    """Measure the kernel of ``scenario`` (an ``agglo.Scenario``) as ``agglo kernel`` does,
    with the same library calls: ``seeds`` runs (the scenario's seed, then the next ones)
    on ``threads`` Rust threads (0: one per core), binned on ``bins`` (``edges:m0,m1,…``
    [kg], ``dustpy:mmin,mmax,per_decade`` [g] — ``mmin`` may be ``primary``, the
    scenario's primary mass — or ``openfoam:d0,d1,…`` [m]) within
    ``window`` = (t0, t1) [s]; writes ``out`` (.npz, in ``units``: "si" or "cgs") and the
    long table ``parquet`` if given, and returns the file loaded (in ``load_units``).
    Needs the compiled package (the rest of this module does not)."""
    from . import _agglo
    from ._args import MAX_THREADS, whole

    if units not in ("si", "cgs"):
        raise ValueError(f"measure: units: 'si' or 'cgs' (got {units!r})")
    t0, t1 = (0.0, float("inf")) if window is None else (float(window[0]), float(window[1]))
    _agglo.measure_kernel(
        scenario._inner, bins, str(out), whole("seeds", seeds, 1, 2**32 - 1),
        whole("threads", threads, 0, MAX_THREADS), (t0, t1), units == "cgs",
        None if parquet is None else str(parquet),
    )
    return load(out, units=load_units)

#: Factor from SI to cgs by unit, for the arrays of an SI file.
_TO_CGS = {
    "m^3/s": 1e6,
    "s/m^3": 1e-6,
    "kg": 1e3,
    "m/s": 1e2,
}
_CGS_UNIT = {"m^3/s": "cm^3/s", "s/m^3": "s/cm^3", "kg": "g", "m/s": "cm/s"}


@dataclass
class KernelFile:
    """The arrays of a kernel file, converted to cgs (``units`` is then ``"cgs"``).

    ``arrays`` maps each name to its numpy array; ``array_units`` each name to its unit
    (after conversion); the text arrays (``scenario``, ``convention``, ``grid``,
    ``version``) are plain strings. Attribute access works too: ``k.kernel``.
    """

    arrays: dict
    array_units: dict
    units: str
    scenario: dict = field(default_factory=dict)

    def __getattr__(self, name):
        try:
            return self.__dict__["arrays"][name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def classes(self) -> int:
        """Number of mass classes Nm."""
        return int(self.arrays["mass_centres"].shape[0])


def load(path, units: str = "cgs") -> KernelFile:
    """Read ``path`` (an ``agglo kernel`` .npz) with every array in ``units``
    (``"cgs"`` or ``"si"``; an SI file is converted to cgs on request and back)."""
    if units not in ("cgs", "si"):
        raise ValueError(f"units: allowed 'cgs' or 'si' (got {units!r})")
    raw = _read_npz(Path(path))
    file_units = str(raw["units"])
    if file_units not in ("si", "cgs"):
        raise _damaged(path, f"units: 'si' or 'cgs' (got {file_units[:40]!r})")
    declared = _json_entry(path, raw, "array_units")
    scenario = _json_entry(path, raw, "scenario")
    if not isinstance(declared, dict):
        raise _damaged(path, "array_units: not a mapping of array names to units")
    if not isinstance(scenario, dict):
        raise _damaged(path, "scenario: not a JSON object")
    if raw["mass_centres"].ndim != 1:
        raise _damaged(path, f"mass_centres: shape {raw['mass_centres'].shape} (one value "
                             "per class)")
    arrays, out_units = {}, {}
    for name, value in raw.items():
        unit = declared.get(name, "-")
        if not isinstance(unit, str):
            raise _damaged(path, f"array_units: the unit of {name} is not a string")
        if value.dtype.kind not in "Ufiub":
            raise _damaged(path, f"{name}: an array of {value.dtype} (kernel files hold "
                                 "numbers and text)")
        if value.dtype.kind == "U":
            arrays[name] = str(value) if value.ndim == 0 else [str(v) for v in value]
            out_units[name] = "-"
            continue
        if value.ndim == 0:
            value = value[()]
        factor = 1.0
        if file_units == "si" and units == "cgs" and unit in _TO_CGS:
            factor, unit = _TO_CGS[unit], _CGS_UNIT[unit]
        elif file_units == "cgs" and units == "si":
            back = {v: k for k, v in _CGS_UNIT.items()}
            if unit in back:
                factor, unit = 1.0 / _TO_CGS[back[unit]], back[unit]
        arrays[name] = value * factor if factor != 1.0 else value
        out_units[name] = unit
    return KernelFile(
        arrays=arrays,
        array_units=out_units,
        units=units,
        scenario=scenario,
    )


#: Entries every kernel file holds (docs/outputs.md, "agglo kernel").
_REQUIRED = ("units", "array_units", "scenario", "mass_centres")


def _damaged(path, why: str) -> ValueError:
    return ValueError(f"{path}: not a readable agglo kernel file (.npz written by `agglo "
                      f"kernel`): {why}")


def _read_npz(path: Path) -> dict:
    """Every array of the .npz at ``path``; a ValueError naming the file and what is wrong
    for anything else (a damaged file raised raw zip, zlib, JSON or syntax errors from
    numpy's header parser, or numpy's advice to load pickled data). A file that cannot be
    opened raises as ``open`` does (FileNotFoundError, PermissionError)."""
    with open(path, "rb") as f:
        try:
            z = np.load(f, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise _damaged(path, "a single array, not an .npz archive")
            with z:
                raw = {name: z[name] for name in z.files}
        except ValueError as e:
            if str(e).startswith(f"{path}: "):
                raise
            if "pickle" in str(e):
                raise _damaged(path, "not an .npz archive of plain arrays (pickled or "
                                     "unknown data, left unread)") from None
            raise _damaged(path, str(e)) from None
        except Exception as e:  # noqa: BLE001 - any failure to parse is a damaged file
            # zipfile.BadZipFile, zlib.error, EOFError, SyntaxError or tokenize's errors
            # from a damaged array header, MemoryError for a shape larger than memory...
            raise _damaged(path, f"{type(e).__name__}: {e}") from None
    missing = [name for name in _REQUIRED if name not in raw]
    if missing:
        raise _damaged(path, f"missing {', '.join(missing)}")
    return raw


def _json_entry(path, raw: dict, name: str):
    try:
        return json.loads(str(raw[name]))
    except ValueError as e:
        raise _damaged(path, f"{name}: not JSON ({e})") from None


class FilledKernelWarning(UserWarning):
    """Part of a kernel file's grid had no measurement and was filled (see :func:`fill`)."""


def _interpolate_rows(values: np.ndarray, logm: np.ndarray, geometric: bool) -> np.ndarray:
    """Fill each row's NaN entries from the nearest finite entries of the same row, in log
    mass: geometrically (linear in log value) where both neighbours are > 0 and
    ``geometric``, linearly otherwise; beyond the last finite entry, its value. Rows with
    no finite entry stay NaN."""
    out = values.copy()
    for i, row in enumerate(values):
        ok = np.isfinite(row)
        if ok.all() or not ok.any():
            continue
        x, y = logm[ok], row[ok]
        want = logm[~ok]
        right = np.clip(np.searchsorted(x, want), 1, max(x.size - 1, 1))
        left = right - 1
        if x.size == 1:
            out[i, ~ok] = y[0]
            continue
        w = np.clip((want - x[left]) / (x[right] - x[left]), 0.0, 1.0)
        lo, hi = y[left], y[right]
        linear = lo + w * (hi - lo)
        if geometric:
            positive = (lo > 0) & (hi > 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                logs = np.exp(np.log(np.where(positive, lo, 1.0)) * (1 - w)
                              + np.log(np.where(positive, hi, 1.0)) * w)
            linear = np.where(positive, logs, linear)
        out[i, ~ok] = linear
    return out


def fill_symmetric(values, log_mass, *, geometric: bool = True) -> np.ndarray:
    """A symmetric (Nm, Nm) array with its NaN entries filled by interpolation in log mass
    between the nearest finite entries (:func:`_interpolate_rows` along rows and columns,
    averaged where both give a value). A class with no finite entry at all — one no body
    ever occupied — is filled from its neighbouring classes on the next pass. Finite
    entries are kept as they are."""
    out = np.array(values, dtype=float)
    logm = np.asarray(log_mass, dtype=float)
    if not np.isfinite(out).any():
        raise ValueError("nothing to fill from: every entry is NaN (no pair of classes coexisted)")
    for _ in range(3):
        missing = ~np.isfinite(out)
        if not missing.any():
            break
        rows = _interpolate_rows(out, logm, geometric)
        cols = rows.T
        both = np.isfinite(rows) & np.isfinite(cols)
        filled = np.where(both, 0.5 * (rows + cols), np.where(np.isfinite(rows), rows, cols))
        out = np.where(missing, filled, out)
    return out


def fill(k: "KernelFile", *, missing: str = "interpolate", warn: bool = True) -> dict:
    """The kernel of every pair of classes of the file's grid: measured where measured,
    filled elsewhere, with the mask saying which is which.

    A pair (i, j) is measured where its exposure E_ij > 0 (some pair of those classes
    coexisted in the runs; K may then be 0, with ``kernel_upper95`` its bound). Elsewhere
    the file holds NaN: classes no body of the runs could occupy (on DustPy's grid, the
    points between the masses an aggregate of whole primaries can have, which DustPy's
    sticking feeds anyway) and pairs of classes that never coexisted. ``missing``:

    - ``"interpolate"``: from the nearest measured classes, in log mass (geometric in K
      between two positive neighbours; the nearest value beyond the measured range);
    - ``"geometric"``: the sampled geometric kernel π(b_i + b_j)²⟨|Δv|⟩ where it was
      sampled, interpolated elsewhere;
    - ``"zero"``: 0 (DustPy then never moves mass out of such classes).

    The outcome probabilities where no impact was seen are interpolated the same way
    (linearly). Warns (:class:`FilledKernelWarning`) with how much of the grid was filled.

    Returns ``{"kernel": (Nm, Nm) [the file's kernel unit], "stick", "frag": (Nm, Nm),
    "measured": (Nm, Nm) bool, "filled_pairs": int, "empty_classes": (n,) int}``.
    """
    kernel = np.array(k.arrays["kernel"], dtype=float)
    exposure = np.asarray(k.arrays["exposure"], dtype=float)
    # The file's `measured` mask (files before it: the same from the exposure).
    measured = np.asarray(k.arrays.get("measured", exposure > 0)).astype(bool)
    kernel[~measured] = np.nan
    nm = kernel.shape[0]
    logm = np.log(np.asarray(k.arrays["mass_centres"], dtype=float))
    if missing == "geometric":
        geometric = np.asarray(k.arrays["geometric_kernel"], dtype=float)
        kernel = np.where(measured, kernel, geometric)
    elif missing not in ("interpolate", "zero"):
        raise ValueError(
            f"missing: allowed 'interpolate', 'geometric' or 'zero' (got {missing!r})")
    if missing == "zero":
        kernel = np.nan_to_num(kernel, nan=0.0)
    elif not measured.any():
        raise ValueError(
            f"{k.arrays.get('grid', 'the grid')}: no pair of classes has any exposure "
            "(nothing was measured): check --window and --bins")
    else:
        kernel = fill_symmetric(kernel, logm, geometric=True)
    counts = np.asarray(k.arrays["counts_total"])
    p = np.array(k.arrays["probability"], dtype=float)
    seen = counts > 0
    probabilities = []
    for o in (0, 2):
        q = np.where(seen, p[o], np.nan)
        probabilities.append(fill_symmetric(q, logm, geometric=False) if seen.any() else q)
    empty = np.flatnonzero(~measured.any(axis=1))
    filled_pairs = int((~measured).sum())
    if warn and filled_pairs:
        m = np.asarray(k.arrays["mass_centres"], dtype=float)
        unit = k.array_units.get("mass_centres", "")
        shown = ", ".join(f"{m[c]:.3g}" for c in empty[:6]) + (" …" if empty.size > 6 else "")
        how = {"interpolate": "interpolated in log mass between the nearest measured classes",
               "geometric": "the sampled geometric kernel where sampled, else interpolated",
               "zero": "set to 0"}[missing]
        import warnings

        warnings.warn(
            f"kernel file on `{k.arrays.get('grid', '?')}`: {filled_pairs} of {nm * nm} class "
            f"pairs ({100.0 * filled_pairs / (nm * nm):.1f} %) were not measured (no exposure) "
            f"and are {how}; {empty.size} of {nm} classes never held a body"
            + (f" (masses {shown} {unit})" if empty.size else "")
            + ". The mask is the 'measured' array.",
            FilledKernelWarning,
            stacklevel=3,
        )
    return {
        "kernel": kernel,
        "stick": probabilities[0],
        "frag": probabilities[1],
        "measured": measured,
        "filled_pairs": filled_pairs,
        "empty_classes": empty,
    }


def _check_grid(k: "KernelFile", m_grid) -> None:
    """Refuse a file whose class masses are not ``m_grid`` [g] (DustPy's sim.grid.m)."""
    m = np.asarray(k.arrays["mass_centres"], dtype=float)
    if k.array_units.get("mass_centres") != "g":
        raise ValueError("load the file with units='cgs' for DustPy")
    m_grid = np.asarray(m_grid, dtype=float)
    if m_grid.shape != m.shape or not np.allclose(m_grid, m, rtol=1e-10, atol=0):
        given = (f"{m_grid.size} masses, {m_grid[0]:.6g}..{m_grid[-1]:.6g} g"
                 if m_grid.size else "no masses")
        raise ValueError(
            f"the file's grid ({m.size} classes, {m[0]:.6g}..{m[-1]:.6g} g, from "
            f"`{k.arrays.get('grid', '?')}`) is not sim.grid.m ({given}): run agglo kernel "
            "with --bins dustpy:mmin,mmax,Nmbpd as in sim.ini.grid [g]"
        )


def dustpy_kernel(kernel_3d, H, *, zero_boundaries: bool = True) -> np.ndarray:
    """DustPy's vertically integrated kernel [cm²/s], shape (Nr, Nm, Nm), from K [cm³/s]
    (Nm, Nm) and the dust scale heights ``H`` [cm], (Nr, Nm) or (Nm,), as DustPy's
    ``std.dust.kernel`` lays it out: ``(1 - 0.5 delta_ij) K_ij / sqrt(2 pi (H_i**2 +
    H_j**2))`` on and above the diagonal, 0 below it (DustPy's coagulation reads j ≥ i
    only), and 0 in the first and last radial cells (DustPy computes the interior only)."""
    kernel_3d = np.asarray(kernel_3d, dtype=float)
    nm = kernel_3d.shape[0]
    H = np.asarray(H, dtype=float)
    if H.ndim == 1:
        H = H[None, :]
    if H.ndim != 2 or H.shape[1] != nm:
        raise ValueError(f"H: expected shape (Nr, {nm}) [cm] (got {H.shape})")
    upper = np.triu(np.ones((nm, nm))) * (1.0 - 0.5 * np.eye(nm))
    height = np.sqrt(2.0 * np.pi * (H[:, :, None] ** 2 + H[:, None, :] ** 2))
    out = (upper * kernel_3d)[None, :, :] / height
    if zero_boundaries and out.shape[0] > 2:
        out[0] = 0.0
        out[-1] = 0.0
    return out


def dustpy_arrays(
    k: KernelFile,
    H,
    *,
    m_grid=None,
    missing: str = "interpolate",
    zero_boundaries: bool = True,
    warn: bool = True,
) -> dict:
    """The arrays DustPy reads, shape (Nr, Nm, Nm), from a file on a ``dustpy:`` grid
    (:func:`install_dustpy` puts them into a simulation and keeps them there).

    - ``H``: dust scale heights ``sim.dust.H``, shape (Nr, Nm) [cm] (or (Nm,) for one
      radius); the kernel is :func:`dustpy_kernel` of K.
    - ``m_grid``: ``sim.grid.m`` [g], checked against the file's class masses.
    - ``missing``: how pairs without a measurement are filled (:func:`fill`).
    - ``stick`` and ``frag`` are the bond and fragment probabilities; bounces are the
      rest (DustPy has no bouncing: with ``p.stick + p.frag < 1`` a bounce changes
      nothing, as it should). In the first and last radial cells they are 0, as DustPy's
      own ``p_stick`` leaves them.
    - ``zero_boundaries``: DustPy computes the kernel in the interior cells only
      (``ir = 2 .. Nr-1``); the first and last radial cells are set to 0 likewise.

    Returns ``{"kernel", "stick", "frag", "kernel_3d", "measured", "m"}``: the first three
    (Nr, Nm, Nm), ``kernel_3d`` the filled (Nm, Nm) K in cm³/s, ``measured`` the
    (Nm, Nm) mask of measured pairs, ``m`` the class masses [g].
    """
    if k.array_units.get("kernel") != "cm^3/s":
        raise ValueError("load the file with units='cgs' for DustPy")
    if m_grid is not None:
        _check_grid(k, m_grid)
    filled = fill(k, missing=missing, warn=warn)
    kernel = dustpy_kernel(filled["kernel"], H, zero_boundaries=zero_boundaries)
    nr = kernel.shape[0]
    stick, frag = (_per_cell(filled[name], nr, zero_boundaries) for name in ("stick", "frag"))
    return {
        "kernel": kernel,
        "stick": stick,
        "frag": frag,
        "kernel_3d": filled["kernel"],
        "measured": filled["measured"],
        "m": np.asarray(k.arrays["mass_centres"], dtype=float),
    }


def _per_cell(p, nr: int, zero_boundaries: bool) -> np.ndarray:
    """An (Nm, Nm) probability in every radial cell, 0 in the boundary cells (as DustPy's
    own ``std.dust.p_stick`` leaves them) when ``zero_boundaries``."""
    out = np.broadcast_to(np.nan_to_num(p, nan=0.0), (nr,) + p.shape).copy()
    if zero_boundaries and nr > 2:
        out[0] = 0.0
        out[-1] = 0.0
    return out


class DustPyKernel:
    """Measured kernels installed into a DustPy simulation (made by :func:`install_dustpy`).

    Its methods are the updaters of ``sim.dust.kernel``, ``sim.dust.p.stick`` and
    ``sim.dust.p.frag``: at every ``sim.update()`` they hand DustPy the file whose window
    holds the time ``time(sim)`` [s] (the first before the first window, the last after
    the last), the kernel divided by DustPy's current vertical length
    √(2π(H_i² + H_j²)), so it follows ``sim.dust.H`` as DustPy's own kernel does.
    """

    def __init__(self, files, fills, windows, time):
        self.files = files
        self.fills = fills
        #: [T0, T1) [s] of each file, sorted by T0.
        self.windows = windows
        self._time = time

    def index(self, sim) -> int:
        """The file in use at ``sim``'s time."""
        t = float(self._time(sim))
        starts = np.array([w[0] for w in self.windows])
        return int(max(np.searchsorted(starts, t, side="right") - 1, 0))

    def kernel(self, sim) -> np.ndarray:
        """Updater of ``sim.dust.kernel`` [cm²/s]."""
        return dustpy_kernel(self.fills[self.index(sim)]["kernel"], sim.dust.H)

    def stick(self, sim) -> np.ndarray:
        """Updater of ``sim.dust.p.stick``: the bond probability."""
        return _per_cell(self.fills[self.index(sim)]["stick"], int(sim.grid.Nr), True)

    def frag(self, sim) -> np.ndarray:
        """Updater of ``sim.dust.p.frag``: the fragment probability."""
        return _per_cell(self.fills[self.index(sim)]["frag"], int(sim.grid.Nr), True)


def install_dustpy(sim, files, *, missing: str = "interpolate", time=None,
                   check_density: bool = True, warn: bool = True) -> DustPyKernel:
    """Install measured kernels into an initialized DustPy simulation, for good.

    ``files``: a kernel file (path or :class:`KernelFile`) on ``sim``'s grid
    (``agglo kernel SCENE --bins dustpy:mmin,mmax,Nmbpd`` with sim.ini.grid's values, in
    grams), or a list of them measured in consecutive windows (``--window T0:T1``): a
    time-dependent kernel, the file whose window holds ``time(sim)`` in use (``time``:
    the agglo time [s] of the DustPy state, default ``sim.t``).

    It replaces the updaters of ``sim.dust.kernel``, ``sim.dust.p.stick`` and
    ``sim.dust.p.frag`` by those of a :class:`DustPyKernel` and runs them once, so
    ``sim.update()`` and every integration step keep the measured values (setting the
    arrays alone lasts until the next update: DustPy's own ``p_frag`` recomputes them from
    its v_rel and vFrag). The kernel is recomputed from ``sim.dust.H`` at each update.
    Pairs with no measurement are filled (:func:`fill`, ``missing``), with a warning
    saying how many.

    Checks that ``sim.grid.m`` is the files' grid and (``check_density``) that
    ``sim.dust.rhos`` is the scenario's material density: DustPy's particle sizes, and
    from them its H, Stokes numbers and drift, use it (set
    ``sim.ini.dust.rhoMonomer`` before ``sim.initialize()``).

    Fragments: DustPy spreads the mass of a fragmenting collision over smaller sizes by
    its own law (``sim.ini.dust.fragmentation`` settings, ``sim.dust.coagulation``);
    the file's ``p.frag`` says how often a pair fragments, but agglo's measured
    distribution of the pieces (``fragment_mass_fraction``) does not go into DustPy.

    Returns the :class:`DustPyKernel` (its ``fills[i]["measured"]`` is the mask of
    measured pairs of file i).
    """
    if isinstance(files, (str, Path, KernelFile)):
        files = [files]
    files = [f if isinstance(f, KernelFile) else load(f) for f in files]
    if not files:
        raise ValueError("install_dustpy: files: give at least one kernel file")
    for f in files:
        if f.array_units.get("kernel") != "cm^3/s":
            raise ValueError("install_dustpy: load the files with units='cgs'")
    for field in ("H", "kernel", "rhos"):
        if getattr(sim.dust, field, None) is None:
            raise ValueError(
                f"install_dustpy: sim.dust.{field} is not set: call sim.initialize() first")
    for f in files:
        _check_grid(f, np.asarray(sim.grid.m, dtype=float))
    if check_density:
        for f in files:
            rho = float(f.scenario["material"]["rho"]) * 1e-3  # kg/m³ → g/cm³
            rhos = np.asarray(sim.dust.rhos, dtype=float)
            if not np.allclose(rhos, rho, rtol=1e-6, atol=0):
                raise ValueError(
                    f"install_dustpy: sim.dust.rhos is {rhos.min():.6g}..{rhos.max():.6g} "
                    f"g/cm³, the kernel's scenario has material.rho = {rho * 1e3:.6g} kg/m³ "
                    f"= {rho:.6g} g/cm³: set sim.ini.dust.rhoMonomer = {rho:.6g} before "
                    "sim.initialize() (or pass check_density=False)")
    windows = [tuple(float(x) for x in f.arrays["window"]) for f in files]
    order = np.argsort([w[0] for w in windows], kind="stable")
    files = [files[i] for i in order]
    windows = [windows[i] for i in order]
    for a, b in zip(windows, windows[1:]):
        if b[0] < a[1]:
            raise ValueError(
                f"install_dustpy: the windows [{a[0]:g}, {a[1]:g}) s and [{b[0]:g}, "
                f"{b[1]:g}) s overlap: give files of consecutive windows (--window T0:T1)")
    fills = [fill(f, missing=missing, warn=warn) for f in files]
    installed = DustPyKernel(files, fills, windows,
                             time if time is not None else (lambda s: float(s.t)))
    sim.dust.kernel.updater = installed.kernel
    sim.dust.p.stick.updater = installed.stick
    sim.dust.p.frag.updater = installed.frag
    sim.dust.p.frag.update()
    sim.dust.p.stick.update()
    sim.dust.kernel.update()
    return installed


def openfoam_table(k: KernelFile, *, outcome: str = "bond") -> dict:
    """The coalescence rate per size-group pair [m³/s] for an OpenFOAM population
    balance: ``{"dSph": (Nm,) m, "rate": (Nm, Nm) m³/s}``.

    ``outcome="bond"`` (impacts that stick: coalescence) or ``"all"``. OpenFOAM's
    ``birthByCoalescence`` halves the j == k pair itself, the convention of the file, so
    the rate is K unchanged; NaN (no data) becomes 0. The diameters are the classes'
    sphere-equivalent diameters from the scenario's density (on an ``openfoam:`` grid,
    the dSph given to --bins).
    """
    si = k.array_units.get("kernel") == "m^3/s"
    to_si = 1.0 if si else 1e-6
    if outcome == "bond":
        rate = np.asarray(k.arrays["kernel_outcome"], dtype=float)[0] * to_si
    elif outcome == "all":
        rate = np.asarray(k.arrays["kernel"], dtype=float) * to_si
    else:
        raise ValueError(f"outcome: allowed 'bond' or 'all' (got {outcome!r})")
    rho = float(k.scenario["material"]["rho"])  # kg/m³
    mass = np.asarray(k.arrays["mass_centres"], dtype=float) * (1.0 if si else 1e-3)
    d = np.cbrt(6.0 * mass / (np.pi * rho))
    return {"dSph": d, "rate": np.nan_to_num(rate, nan=0.0)}


def write_openfoam_table(k: KernelFile, path, *, outcome: str = "bond") -> None:
    """Write :func:`openfoam_table` as an OpenFOAM dictionary (``dSph`` list [m] and
    ``rate`` list of rows [m³/s]) for a tabulated coalescence model to read, e.g. a
    ``coded`` coalescence model that looks ``rate[i][j]`` up for size groups i, j."""
    table = openfoam_table(k, outcome=outcome)
    rows = "\n".join(
        "    (" + " ".join(f"{v:.17g}" for v in row) + ")" for row in table["rate"]
    )
    text = (
        "FoamFile\n{\n    format      ascii;\n    class       dictionary;\n"
        "    object      coalescenceTable;\n}\n"
        f"// agglo kernel ({k.arrays['grid']}), outcome {outcome}: coalescence rate per\n"
        "// size-group pair [m^3/s]; rate of (i,j) coalescences per volume is rate*n_i*n_j,\n"
        "// halved for i == j (as populationBalanceModel::birthByCoalescence does).\n"
        "dSph (" + " ".join(f"{d:.17g}" for d in table["dSph"]) + ");\n"
        f"rate\n(\n{rows}\n);\n"
    )
    Path(path).write_text(text)
