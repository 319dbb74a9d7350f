"""The refrigerant property tables of the plant's vapour-compression cycle.

Saturation and compression properties of the refrigerant tabulated on a grid of
evaporating and condensing temperatures (CoolProp values, :func:`build_cycle_tables`),
with linear interpolation and its slopes for the cycle's Newton solve. The shipped,
generated file of the default configuration and :func:`cycle_tables`, which prefers it,
are in :mod:`ceco_plant_sim.refrigerant_table_file`. The cycle itself:
:mod:`ceco_plant_sim.refrigerant`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass

import numpy as np

from ceco_core.units import c_to_k

from .plant_ops import NUMERIC

__all__ = [
    "CycleTables",
    "TableGrid",
    "DEFAULT_GRID",
    "build_cycle_tables",
    "make_tables",
    "ARRAYS_1D_TE",
    "ARRAYS_1D_TC",
    "ARRAY_2D",
    "direct_cycle_properties",
]

ARRAYS_1D_TE = ("p_evap_pa", "rho_suc_kgm3", "h_suc_jpkg")
"""Properties tabulated over the evaporating temperature (saturated vapour, suction)."""
ARRAYS_1D_TC = ("p_cond_pa", "h_liq_jpkg")
"""Properties tabulated over the condensing temperature (saturated liquid)."""
ARRAY_2D = "dh_is_jpkg"
"""The isentropic enthalpy rise, over (evaporating, condensing) temperature."""


def _coolprop():
    """CoolProp's PropsSI module, imported on first use (~2.3 s on the shared 2-core machine)."""
    try:
        import CoolProp.CoolProp as CP
    except ImportError as err:
        raise ImportError(
            f"refrigerant tables: CoolProp is needed to build tables that the shipped file "
            f"(ceco_plant_sim/data/cycle_tables_R1234yf.npz) does not hold ({err})"
        ) from err
    return CP


def _coolprop_version() -> str:
    import CoolProp

    return f"{CoolProp.__version__} ({CoolProp.__gitrevision__})"


@dataclass(frozen=True)
class TableGrid:
    """Uniform temperature grids of the cycle tables."""

    te_min_c: float = -30.0
    """Lowest tabulated evaporating temperature [degC]."""
    te_max_c: float = 30.0
    """Highest tabulated evaporating temperature [degC]."""
    tc_min_c: float = 10.0
    """Lowest tabulated condensing temperature [degC]."""
    tc_max_c: float = 85.0
    """Highest tabulated condensing temperature [degC]."""
    step_1d_k: float = 0.5
    """Step of the 1-D tables in t_e and in t_c [K]."""
    step_2d_k: float = 2.5
    """Step of the 2-D isentropic-work table in both temperatures [K]."""

    def validate(self) -> TableGrid:
        """Check every field; raise ValueError naming the first bad field. Returns self."""
        for name, v in asdict(self).items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name}: must be a finite number, got {v!r}")
        for name in ("step_1d_k", "step_2d_k"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name}: must be > 0, got {getattr(self, name)}")
        if self.te_max_c <= self.te_min_c:
            raise ValueError(f"te_max_c: must exceed te_min_c, got {self.te_max_c} <= {self.te_min_c}")
        if self.tc_max_c <= self.tc_min_c:
            raise ValueError(f"tc_max_c: must exceed tc_min_c, got {self.tc_max_c} <= {self.tc_min_c}")
        return self

    def build_args(self) -> tuple[float, ...]:
        """The grid as the positional arguments 4-9 of :func:`build_cycle_tables`."""
        return (self.te_min_c, self.te_max_c, self.tc_min_c, self.tc_max_c, self.step_1d_k, self.step_2d_k)

    def shapes(self) -> dict[str, tuple[int, ...]]:
        """Shape of every table array on this grid."""
        n_e, n_c = (
            _grid(self.te_min_c, self.te_max_c, self.step_1d_k).size,
            _grid(self.tc_min_c, self.tc_max_c, self.step_1d_k).size,
        )
        n2 = (
            _grid(self.te_min_c, self.te_max_c, self.step_2d_k).size,
            _grid(self.tc_min_c, self.tc_max_c, self.step_2d_k).size,
        )
        return {**{k: (n_e,) for k in ARRAYS_1D_TE}, **{k: (n_c,) for k in ARRAYS_1D_TC}, ARRAY_2D: n2}


DEFAULT_GRID = TableGrid()
"""The grid of the plant's tables (and of the shipped file)."""


class _Table1D:
    """Piecewise-linear interpolation on a uniform grid (linear extrapolation beyond the ends)."""

    __slots__ = ("x0", "dx", "inv_dx", "y", "n")

    def __init__(self, x0: float, dx: float, y) -> None:
        self.x0 = float(x0)
        self.dx = float(dx)
        self.inv_dx = 1.0 / float(dx)
        self.y = [float(v) for v in y]
        self.n = len(self.y)

    def __call__(self, x: float) -> float:
        """Return y(x) (the value of :meth:`value_slope`, which holds the one cell lookup)."""
        return self.value_slope(x)[0]

    def value_slope(self, x, ops=NUMERIC):
        """Return (y(x), dy/dx) of the interpolant, evaluated by ``ops`` (``ops.interp1``, :mod:`.plant_ops`)."""
        return ops.interp1(self, x)


class _Table2D:
    """Bilinear interpolation on a uniform (x, y) grid (linear extrapolation beyond the edges)."""

    __slots__ = ("x0", "inv_dx", "y0", "inv_dy", "z", "nx", "ny")

    def __init__(self, x0, dx, y0, dy, z) -> None:
        self.x0 = float(x0)
        self.inv_dx = 1.0 / float(dx)
        self.y0 = float(y0)
        self.inv_dy = 1.0 / float(dy)
        z = np.asarray(z, dtype=float)
        self.nx, self.ny = z.shape
        self.z = [[float(v) for v in row] for row in z]

    def __call__(self, x: float, y: float) -> float:
        """Return z(x, y) (the value of :meth:`value_grad`, which holds the one cell lookup)."""
        return self.value_grad(x, y)[0]

    def value_grad(self, x, y, ops=NUMERIC):
        """Return (z(x, y), dz/dx, dz/dy) of the bilinear interpolant, evaluated by ``ops`` (``interp2``)."""
        return ops.interp2(self, x, y)


@dataclass(frozen=True)
class CycleTables:
    """Tabulated CoolProp properties of one refrigerant cycle configuration.

    Evaporating-side tables are functions of the evaporating (saturation)
    temperature ``t_e`` [degC], condensing-side tables of the condensing
    temperature ``t_c`` [degC]; ``dh_is`` is a function of both.
    """

    fluid: str
    """CoolProp fluid name (``R1234yf``)."""
    superheat_k: float
    """Evaporator-exit superheat [K]."""
    subcool_k: float
    """Condenser-exit subcooling [K]."""
    p_evap_pa: _Table1D
    """Saturation pressure at t_e [Pa]."""
    rho_suc_kgm3: _Table1D
    """Suction vapour density at (p_sat(t_e), t_e + superheat) [kg/m3]."""
    h_suc_jpkg: _Table1D
    """Suction enthalpy at (p_sat(t_e), t_e + superheat) [J/kg]."""
    p_cond_pa: _Table1D
    """Saturation pressure at t_c [Pa]."""
    h_liq_jpkg: _Table1D
    """Condenser-exit liquid enthalpy at (p_sat(t_c), t_c - subcooling) [J/kg]."""
    dh_is_jpkg: _Table2D
    """Isentropic compression work h(p_sat(t_c), s_1) - h_1 [J/kg] over (t_e, t_c)."""
    te_range_c: tuple[float, float]
    """Tabulated t_e range [degC] (linear extrapolation outside)."""
    tc_range_c: tuple[float, float]
    """Tabulated t_c range [degC] (linear extrapolation outside)."""
    source: str = ""
    """Where the values come from (the shipped file and its provenance, or a CoolProp build)."""


def _grid(lo: float, hi: float, step: float) -> np.ndarray:
    n = int(round((hi - lo) / step)) + 1
    return lo + step * np.arange(n)


def direct_cycle_properties(fluid: str, superheat_k: float, subcool_k: float, t_e_c: float, t_c_c: float) -> dict:
    """Cycle state properties from direct CoolProp calls (the reference for the tables).

    Returns a dict with ``p_evap_pa, rho_suc_kgm3, h_suc_jpkg, p_cond_pa,
    h_liq_jpkg, dh_is_jpkg`` for evaporating temperature ``t_e_c`` [degC] and
    condensing temperature ``t_c_c`` [degC].
    """
    CP = _coolprop()
    te_k = c_to_k(t_e_c)
    tc_k = c_to_k(t_c_c)
    p_e = CP.PropsSI("P", "T", te_k, "Q", 1.0, fluid)
    t1_k = te_k + superheat_k
    rho1 = CP.PropsSI("D", "T", t1_k, "P", p_e, fluid)
    h1 = CP.PropsSI("H", "T", t1_k, "P", p_e, fluid)
    s1 = CP.PropsSI("S", "T", t1_k, "P", p_e, fluid)
    p_c = CP.PropsSI("P", "T", tc_k, "Q", 0.0, fluid)
    if subcool_k > 0.0:
        h3 = CP.PropsSI("H", "T", tc_k - subcool_k, "P", p_c, fluid)
    else:
        h3 = CP.PropsSI("H", "T", tc_k, "Q", 0.0, fluid)
    h2s = CP.PropsSI("H", "P", p_c, "S", s1, fluid)
    return {
        "p_evap_pa": p_e,
        "rho_suc_kgm3": rho1,
        "h_suc_jpkg": h1,
        "p_cond_pa": p_c,
        "h_liq_jpkg": h3,
        "dh_is_jpkg": h2s - h1,
    }


@functools.lru_cache(maxsize=8)
def build_cycle_tables(
    fluid: str = "R1234yf",
    superheat_k: float = 5.0,
    subcool_k: float = 5.0,
    te_min_c: float = DEFAULT_GRID.te_min_c,
    te_max_c: float = DEFAULT_GRID.te_max_c,
    tc_min_c: float = DEFAULT_GRID.tc_min_c,
    tc_max_c: float = DEFAULT_GRID.tc_max_c,
    step_1d_k: float = DEFAULT_GRID.step_1d_k,
    step_2d_k: float = DEFAULT_GRID.step_2d_k,
) -> CycleTables:
    """Tabulate the cycle properties with CoolProp once (cached per argument set).

    Imports CoolProp (~2.3 s the first time). Cost: about (te span/step_2d) x
    (tc span/step_2d) CoolProp (p, s) flashes (~0.35 ms each), i.e. ~0.3 s for
    the defaults. The plant calls :func:`cycle_tables`, which takes the shipped
    file instead when it holds the configuration.
    """
    CP = _coolprop()
    try:
        CP.get_fluid_param_string(fluid, "CAS")
    except ValueError:
        raise ValueError(f"fluid: CoolProp does not know {fluid!r}") from None
    grid = TableGrid(te_min_c, te_max_c, tc_min_c, tc_max_c, step_1d_k, step_2d_k).validate()
    te = _grid(te_min_c, te_max_c, step_1d_k)
    tc = _grid(tc_min_c, tc_max_c, step_1d_k)
    p_e, rho1, h1 = [], [], []
    for t in te:
        te_k = c_to_k(float(t))
        p = CP.PropsSI("P", "T", te_k, "Q", 1.0, fluid)
        p_e.append(p)
        rho1.append(CP.PropsSI("D", "T", te_k + superheat_k, "P", p, fluid))
        h1.append(CP.PropsSI("H", "T", te_k + superheat_k, "P", p, fluid))
    p_c, h3 = [], []
    for t in tc:
        tc_k = c_to_k(float(t))
        p = CP.PropsSI("P", "T", tc_k, "Q", 0.0, fluid)
        p_c.append(p)
        if subcool_k > 0.0:
            h3.append(CP.PropsSI("H", "T", tc_k - subcool_k, "P", p, fluid))
        else:
            h3.append(CP.PropsSI("H", "T", tc_k, "Q", 0.0, fluid))
    te2 = _grid(te_min_c, te_max_c, step_2d_k)
    tc2 = _grid(tc_min_c, tc_max_c, step_2d_k)
    dh = np.empty((te2.size, tc2.size))
    for i, t in enumerate(te2):
        te_k = c_to_k(float(t))
        p = CP.PropsSI("P", "T", te_k, "Q", 1.0, fluid)
        s1 = CP.PropsSI("S", "T", te_k + superheat_k, "P", p, fluid)
        hh1 = CP.PropsSI("H", "T", te_k + superheat_k, "P", p, fluid)
        for j, u in enumerate(tc2):
            pc = CP.PropsSI("P", "T", c_to_k(float(u)), "Q", 0.0, fluid)
            dh[i, j] = CP.PropsSI("H", "P", pc, "S", s1, fluid) - hh1
    arrays = {
        "p_evap_pa": p_e,
        "rho_suc_kgm3": rho1,
        "h_suc_jpkg": h1,
        "p_cond_pa": p_c,
        "h_liq_jpkg": h3,
        "dh_is_jpkg": dh,
    }
    return make_tables(
        fluid, superheat_k, subcool_k, grid, arrays, f"built with CoolProp {_coolprop_version()} at run time"
    )


def make_tables(
    fluid: str, superheat_k: float, subcool_k: float, grid: TableGrid, arrays: dict, source: str
) -> CycleTables:
    """The interpolants of one configuration from its raw property values (one path for build and file)."""
    s1, s2 = grid.step_1d_k, grid.step_2d_k
    return CycleTables(
        fluid=fluid,
        superheat_k=float(superheat_k),
        subcool_k=float(subcool_k),
        p_evap_pa=_Table1D(grid.te_min_c, s1, arrays["p_evap_pa"]),
        rho_suc_kgm3=_Table1D(grid.te_min_c, s1, arrays["rho_suc_kgm3"]),
        h_suc_jpkg=_Table1D(grid.te_min_c, s1, arrays["h_suc_jpkg"]),
        p_cond_pa=_Table1D(grid.tc_min_c, s1, arrays["p_cond_pa"]),
        h_liq_jpkg=_Table1D(grid.tc_min_c, s1, arrays["h_liq_jpkg"]),
        dh_is_jpkg=_Table2D(grid.te_min_c, s2, grid.tc_min_c, s2, arrays["dh_is_jpkg"]),
        te_range_c=(float(grid.te_min_c), float(grid.te_max_c)),
        tc_range_c=(float(grid.tc_min_c), float(grid.tc_max_c)),
        source=source,
    )
