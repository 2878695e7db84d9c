"""Load a kernel file written by ``agglo kernel`` and hand it to a coagulation code.

``agglo kernel SCENARIO --bins GRID --seeds S --out kernel.npz`` measures, on the
consumer's mass grid, the collision kernel K_ij and the outcome probabilities of every
pair of mass classes (docs/outputs.md, "agglo kernel", lists every array with its unit).
This module needs numpy only (it does not import the compiled ``agglo`` extension):

>>> from agglo.kernel import load, dustpy_arrays, openfoam_table
>>> k = load("kernel.npz")                 # every array, in cgs, plus k.units_si
>>> arrays = dustpy_arrays(k, H)           # H: sim.dust.H, shape (Nr, Nm), cm
>>> sim.dust.kernel[...] = arrays["kernel"]
>>> sim.dust.p.stick[...] = arrays["stick"]
>>> sim.dust.p.frag[...] = arrays["frag"]

Conventions (stored in the file as ``convention``): the rate of (i, j) impacts per unit
volume is ``K_ij n_i n_j`` for i != j and ``0.5 K_ii n_i**2`` for i = j, so a hard-sphere
kernel is ``pi (a_i + a_j)**2 <|dv|>`` on and off the diagonal. OpenFOAM's population
balance uses the same convention (its birth term halves the j == k pair), so its
coalescence rate is K itself. DustPy stores ``(1 - 0.5 delta_ij) K_ij`` divided by its
vertical-integration length ``sqrt(2 pi (H_i**2 + H_j**2))``: ``sim.dust.kernel`` is then
in cm**2/s (DustPy's own unit for it, "Collision kernel [cm²/s]"), from a K in cm**3/s.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["KernelFile", "load", "dustpy_arrays", "openfoam_table", "write_openfoam_table"]

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
    with np.load(Path(path), allow_pickle=False) as z:
        raw = {name: z[name] for name in z.files}
    file_units = str(raw["units"])
    declared = json.loads(str(raw["array_units"]))
    arrays, out_units = {}, {}
    for name, value in raw.items():
        unit = declared.get(name, "-")
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
        scenario=json.loads(arrays["scenario"]),
    )


def dustpy_arrays(
    k: KernelFile,
    H,
    *,
    m_grid=None,
    missing: str = "zero",
    stick_if_unseen: float = 1.0,
    frag_if_unseen: float = 0.0,
    zero_boundaries: bool = True,
) -> dict:
    """The arrays DustPy reads, shape (Nr, Nm, Nm), from a file on a ``dustpy:`` grid.

    - ``H``: dust scale heights ``sim.dust.H``, shape (Nr, Nm) [cm] (or (Nm,) for one
      radius). The measured kernel K [cm³/s] is turned into DustPy's vertically
      integrated kernel as DustPy's ``std.dust.kernel`` does:
      ``(1 - 0.5 delta_ij) K_ij / sqrt(2 pi (H_i**2 + H_j**2))`` [cm²/s].
    - ``m_grid``: ``sim.grid.m`` [g], checked against the file's class masses.
    - ``missing``: what K is where no pair of the classes coexisted (NaN in the file):
      ``"zero"``, or ``"geometric"`` (the sampled π(b_i + b_j)²⟨|Δv|⟩, zero where
      that is missing too).
    - ``stick`` and ``frag`` are the bond and fragment probabilities; bounces are the
      rest (DustPy has no bouncing: with ``p.stick + p.frag < 1`` a bounce changes
      nothing, as it should). Where no impact was seen they are ``stick_if_unseen`` and
      ``frag_if_unseen``.
    - ``zero_boundaries``: DustPy computes the kernel in the interior cells only
      (``ir = 2 .. Nr-1``); the first and last radial cells are set to 0 likewise.

    Returns ``{"kernel", "stick", "frag", "kernel_3d", "m"}``: the first three
    (Nr, Nm, Nm), ``kernel_3d`` the (Nm, Nm) K in cm³/s, ``m`` the class masses [g].
    """
    kernel = np.array(k.arrays["kernel"], dtype=float)
    if k.array_units.get("kernel") != "cm^3/s":
        raise ValueError("load the file with units='cgs' for DustPy")
    nm = kernel.shape[0]
    m = np.asarray(k.arrays["mass_centres"], dtype=float)
    if m_grid is not None:
        m_grid = np.asarray(m_grid, dtype=float)
        if m_grid.shape != m.shape or not np.allclose(m_grid, m, rtol=1e-10, atol=0):
            raise ValueError(
                f"the file's grid ({nm} classes, {m[0]:.4e}..{m[-1]:.4e} g) is not "
                f"sim.grid.m ({m_grid.size} masses): run agglo kernel with "
                "--bins dustpy:mmin,mmax,Nmbpd as in sim.ini.grid"
            )
    if missing == "geometric":
        geometric = np.nan_to_num(np.asarray(k.arrays["geometric_kernel"], dtype=float))
        kernel = np.where(np.isnan(kernel), geometric, kernel)
    elif missing != "zero":
        raise ValueError(f"missing: allowed 'zero' or 'geometric' (got {missing!r})")
    kernel = np.nan_to_num(kernel, nan=0.0)
    H = np.asarray(H, dtype=float)
    if H.ndim == 1:
        H = H[None, :]
    if H.shape[1] != nm:
        raise ValueError(f"H: expected shape (Nr, {nm}) (got {H.shape})")
    nr = H.shape[0]
    half_diagonal = 1.0 - 0.5 * np.eye(nm)
    height = np.sqrt(2.0 * np.pi * (H[:, :, None] ** 2 + H[:, None, :] ** 2))
    dustpy_kernel = (half_diagonal * kernel)[None, :, :] / height
    p = np.asarray(k.arrays["probability"], dtype=float)
    stick = np.where(np.isnan(p[0]), stick_if_unseen, p[0])
    frag = np.where(np.isnan(p[2]), frag_if_unseen, p[2])
    stick = np.broadcast_to(stick, (nr, nm, nm)).copy()
    frag = np.broadcast_to(frag, (nr, nm, nm)).copy()
    if zero_boundaries and nr > 2:
        dustpy_kernel[0] = 0.0
        dustpy_kernel[-1] = 0.0
    return {
        "kernel": dustpy_kernel,
        "stick": stick,
        "frag": frag,
        "kernel_3d": kernel,
        "m": m,
    }


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
