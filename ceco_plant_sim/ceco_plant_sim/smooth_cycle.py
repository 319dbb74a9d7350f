"""The plant's refrigerant cycle as a smooth table: the smooth symbolic model's compressor and cycle.

The plant solves the quasi-steady cycle by Newton at every RK4 stage (:func:`~ceco_plant_sim.refrigerant.solve_cycle`)
and lowers the compressor speed to its inverter power limit by a secant. A gradient-based optimiser
needs the same physics as a C-infinity function instead. :class:`SmoothCycleTable` holds the plant's
own solver sampled on a grid and fits cubic B-splines through the samples (interpolating,
not-a-knot end conditions, one tensor-product spline per output; CasADi ``bspline`` Functions):

* ``cycle(N, T_wall, T_amb, epsc) -> (Q_ref, P_comp, T_e, mdot_ref)``: capacity [W], compressor
  electrical power [W], evaporating temperature [degC], refrigerant flow [kg/s] while running at speed
  N [rpm] (the solver with its MOP pin and head-pressure control; those kinks are smoothed by the
  spline, error measured in docs/plant.md);
* ``n_lim(T_wall, T_amb, epsc)``: the speed at which P_comp reaches ``p_comp_max_w`` [rpm] (the root
  of the solver's P_comp(N) - P_max by Brent's method; where even N_max stays below the limit, the
  tangent extension N_max + (P_max - P(N_max)) / (dP/dN)(N_max), so the table stays smooth across).

``epsc`` is the condenser effectiveness times its air heat-capacity rate [W/K]
(:func:`~ceco_plant_sim.plant_equations.condenser_eps_c_wpk` of the vehicle speed); the grid spans
vehicle speeds 0-45 m/s. Outside the grid box the splines are clamped to the box and
:meth:`SmoothCycleTable.margin` says by how much (it is never silent: the smooth model reports it).

The default configuration ships as a generated file, ``data/smooth_cycle_R1234yf.npz`` (the sampled
solver values, float64, with their provenance: the cycle parameters, grid, generation command, date,
ceco commit), regenerated and checked bit for bit by ``tools/make_smooth_cycle_table.py``; other plant
parameters build their table at run time from the solver (a warning says so; about 20-40 s).
:class:`SmoothCycle` is the cycle object of the smooth :class:`~ceco_plant_sim.plant_equations.PlantEquations`.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math
import os
from dataclasses import asdict
from typing import Any

import casadi
import numpy as np

from .plant_equations import CompressorRun, compressor_model, condenser_eps_c_wpk
from .plant_params import PlantParams
from .refrigerant import cycle_tables, solve_cycle

__all__ = [
    "TableCall",
    "TABLE_OUTPUTS",
    "CYCLE_FIELDS",
    "SmoothCycleGrid",
    "DEFAULT_SMOOTH_GRID",
    "SmoothCycleTable",
    "SmoothCycle",
    "SHIPPED_SMOOTH_TABLE",
    "REGENERATE_SMOOTH_COMMAND",
    "build_smooth_cycle_table",
    "write_smooth_cycle_file",
    "load_smooth_cycle_file",
    "check_smooth_cycle_file",
    "smooth_cycle_table",
]

_LOG = logging.getLogger(__name__)

TABLE_OUTPUTS = ("q_evap_ref_w", "p_comp_w", "t_evap_sat_c", "mdot_ref_kgps")
"""Outputs of the cycle table: refrigerant capacity [W], compressor electrical power [W], evaporating
temperature [degC], refrigerant flow [kg/s], while running (before the duty cycle)."""

CYCLE_FIELDS = (
    "refrigerant",
    "superheat_k",
    "subcool_k",
    "displacement_m3",
    "eta_vol_0",
    "eta_vol_slope",
    "eta_is_max",
    "eta_is_curv",
    "pr_opt",
    "eta_motor_inverter",
    "ua_evap_ref_wpk",
    "te_mop_c",
    "pr_min",
    "comp_speed_min_rpm",
    "comp_speed_max_rpm",
    "p_comp_max_w",
    "rho_air_kgm3",
    "a_cond_face_m2",
    "cp_air_jpkgk",
    "v_face_fan_mps",
    "ram_face_ratio",
    "ua_cond_ref_wpk",
    "v_face_ref_mps",
    "ua_cond_exp",
)
"""The :class:`PlantParams` fields the table depends on (the cycle, the compressor limits, and the
condenser fields that set the grid's epsc range)."""

SHIPPED_SMOOTH_TABLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "smooth_cycle_R1234yf.npz")
"""The generated table of the default parameters, installed with the package."""
REGENERATE_SMOOTH_COMMAND = "python tools/make_smooth_cycle_table.py"
"""The command that regenerates :data:`SHIPPED_SMOOTH_TABLE` (from the repository root)."""
SMOOTH_TABLE_FORMAT = 1
"""Layout version of the file."""

SOLVE_TOL_K = 1e-10
"""Newton tolerance of the table's solves [K] (the plant's 1e-6 K would leave ~1e-7 K of stopping noise in them)."""
SOLVE_MAX_ITER = 60
"""Evaluation cap of the table's solves (a cold start from the solver's built-in guess at every grid point)."""


class StaleSmoothTableError(ValueError):
    """A table file that does not hold what is asked (format, parameters, grid, values)."""


@dataclasses.dataclass(frozen=True)
class SmoothCycleGrid:
    """The sampling grid of the table: uniform axes (first, last, points)."""

    speed_rpm: tuple[float, float, int] = (700.0, 8700.0, 11)
    """Compressor speed axis [rpm]: a little beyond N_min..N_max (the smoothed speed limits overshoot by ln 2 / k)."""
    t_wall_c: tuple[float, float, int] = (0.0, 66.0, 34)
    """Evaporator wall temperature axis [degC]: the coldest coil to a one-hour hot soak."""
    t_amb_c: tuple[float, float, int] = (15.0, 45.0, 13)
    """Ambient (condenser air) temperature axis [degC]."""
    vehicle_speed_mps: tuple[float, float, int] = (0.0, 45.0, 7)
    """Vehicle speeds whose condenser epsc [W/K] span the epsc axis (uniform in epsc) [m/s]."""

    def validate(self) -> SmoothCycleGrid:
        """Raise ValueError naming the first bad axis; return self."""
        for f in dataclasses.fields(self):
            lo, hi, n = getattr(self, f.name)
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo and isinstance(n, int) and n >= 4):
                raise ValueError(f"SmoothCycleGrid.{f.name}: must be (lo, hi > lo, points >= 4), got {(lo, hi, n)!r}")
        return self

    def axes(self, params: PlantParams) -> tuple[np.ndarray, ...]:
        """The four axes: speed [rpm], wall [degC], ambient [degC], epsc [W/K]."""
        e0 = condenser_eps_c_wpk(params, self.vehicle_speed_mps[0])
        e1 = condenser_eps_c_wpk(params, self.vehicle_speed_mps[1])
        return (
            np.linspace(*self.speed_rpm),
            np.linspace(*self.t_wall_c),
            np.linspace(*self.t_amb_c),
            np.linspace(e0, e1, self.vehicle_speed_mps[2]),
        )


DEFAULT_SMOOTH_GRID = SmoothCycleGrid()
"""The grid of the shipped table."""


def cycle_fingerprint(params: PlantParams) -> dict[str, Any]:
    """The table-relevant parameters (:data:`CYCLE_FIELDS`) of ``params``."""
    return {k: getattr(params, k) for k in CYCLE_FIELDS}


def _solver(params: PlantParams):
    p = params
    tab = cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k))
    comp = compressor_model(p)

    def solve(n_rpm, t_wall_c, t_amb_c, epsc_wpk):
        return solve_cycle(
            tab,
            comp,
            float(n_rpm),
            float(t_wall_c),
            p.ua_evap_ref_wpk,
            float(t_amb_c),
            float(epsc_wpk),
            p.te_mop_c,
            tol_k=SOLVE_TOL_K,
            max_iter=SOLVE_MAX_ITER,
            pr_min=p.pr_min,
        )

    return solve


def _power_limit_speed(solve, params: PlantParams, t_wall_c, t_amb_c, epsc_wpk) -> float:
    """Speed at which the solver's P_comp reaches P_max [rpm]; beyond N_max its tangent extension."""
    from scipy.optimize import brentq

    p = params
    n_max = p.comp_speed_max_rpm

    def excess(n):
        return solve(n, t_wall_c, t_amb_c, epsc_wpk).p_comp_w - p.p_comp_max_w

    f_max = excess(n_max)
    if f_max >= 0.0:
        return float(brentq(excess, p.comp_speed_min_rpm, n_max, xtol=1e-9, rtol=1e-14, maxiter=200))
    dn = 1.0  # central difference of the solver's power [W/rpm]
    slope = (excess(n_max + dn) - excess(n_max - dn)) / (2.0 * dn)
    return n_max - f_max / slope


def build_smooth_cycle_table(params: PlantParams, grid: SmoothCycleGrid = DEFAULT_SMOOTH_GRID) -> SmoothCycleTable:
    """Sample the plant's cycle solver on ``grid`` (a cold start at every point, tolerance 1e-10 K).

    Pure numerics, deterministic: the same parameters and grid give the same values bit for bit.
    """
    p = params.validate()
    grid.validate()
    axes = grid.axes(p)
    solve = _solver(p)
    shape = tuple(a.size for a in axes)
    values = {k: np.empty(shape) for k in TABLE_OUTPUTS}
    for i, n in enumerate(axes[0]):
        for j, tw in enumerate(axes[1]):
            for k, ta in enumerate(axes[2]):
                for m, ec in enumerate(axes[3]):
                    s = solve(n, tw, ta, ec)
                    for key in TABLE_OUTPUTS:
                        values[key][i, j, k, m] = getattr(s, key)
    n_lim = np.empty(shape[1:])
    for j, tw in enumerate(axes[1]):
        for k, ta in enumerate(axes[2]):
            for m, ec in enumerate(axes[3]):
                n_lim[j, k, m] = _power_limit_speed(solve, p, tw, ta, ec)
    return SmoothCycleTable(
        fingerprint=cycle_fingerprint(p),
        grid=grid,
        axes=axes,
        values=values,
        n_lim_rpm=n_lim,
        source=f"built from the plant's cycle solver at run time (grid {asdict(grid)})",
    )


def _spline_coefficients(axes, values: np.ndarray) -> tuple[list[list[float]], np.ndarray]:
    """Knots and coefficients of the interpolating cubic tensor-product spline (not-a-knot)."""
    from scipy.interpolate import make_interp_spline

    c = np.asarray(values, dtype=float)
    knots = []
    for d, a in enumerate(axes):  # one axis at a time: interpolate along it, keep the others
        sp = make_interp_spline(a, np.moveaxis(c, d, 0), k=3)
        c = np.moveaxis(sp.c, 0, d)
        knots.append([float(t) for t in sp.t])
    return knots, c


class SmoothCycleTable:
    """The sampled cycle solver of one parameter set and its smooth (B-spline) interpolants."""

    def __init__(self, fingerprint: dict, grid: SmoothCycleGrid, axes, values: dict, n_lim_rpm, source: str):
        self.fingerprint = dict(fingerprint)
        """The parameters the samples were computed with (:data:`CYCLE_FIELDS`)."""
        self.grid = grid
        """The sampling grid."""
        self.axes = tuple(np.asarray(a, dtype=float) for a in axes)
        """Speed [rpm], wall [degC], ambient [degC], epsc [W/K] axes."""
        self.values = {k: np.asarray(values[k], dtype=float) for k in TABLE_OUTPUTS}
        """Sampled outputs (:data:`TABLE_OUTPUTS`), each of shape (speed, wall, ambient, epsc)."""
        self.n_lim_rpm = np.asarray(n_lim_rpm, dtype=float)
        """Power-limit speed [rpm], shape (wall, ambient, epsc)."""
        self.source = source
        """Where the samples come from (the shipped file and its provenance, or a run-time build)."""

    def check_params(self, params: PlantParams) -> None:
        """Raise StaleSmoothTableError naming the first cycle parameter that differs from the table's."""
        for k, v in cycle_fingerprint(params).items():
            if self.fingerprint.get(k) != v:
                raise StaleSmoothTableError(
                    f"smooth cycle table ({self.source}) was built with {k} = {self.fingerprint.get(k)!r}, "
                    f"the plant has {v!r}; build one for these parameters (smooth_cycle_table(params))"
                )

    def box(self) -> tuple[tuple[float, float], ...]:
        """(low, high) of each axis: speed [rpm], wall [degC], ambient [degC], epsc [W/K]."""
        return tuple((float(a[0]), float(a[-1])) for a in self.axes)

    @functools.cached_property
    def cycle(self) -> TableCall:
        """(n_rpm, t_wall_c, t_amb_c, epsc_wpk) -> [q_evap_ref_w, p_comp_w, t_evap_sat_c, mdot_ref_kgps].

        The interpolating cubic B-spline of the samples, evaluated at the inputs clamped to the box
        (a :class:`TableCall`: one call node with its Jacobian in SX graphs).
        """
        stacked = np.stack([self.values[k] for k in TABLE_OUTPUTS], axis=-1)
        knots, c = _spline_coefficients(self.axes, stacked)
        spline = casadi.Function.bspline("cycle_spline", knots, _casadi_order(c), [3] * 4, len(TABLE_OUTPUTS))
        return TableCall(
            self._clamped("smooth_cycle", spline, ("n_rpm", "t_wall_c", "t_amb_c", "epsc_wpk"), self.box())
        )

    @functools.cached_property
    def n_lim(self) -> TableCall:
        """(t_wall_c, t_amb_c, epsc_wpk) -> power-limit speed [rpm] (cubic B-spline, clamped; a :class:`TableCall`)."""
        knots, c = _spline_coefficients(self.axes[1:], self.n_lim_rpm[..., None])
        spline = casadi.Function.bspline("n_lim_spline", knots, _casadi_order(c), [3] * 3, 1)
        return TableCall(self._clamped("smooth_n_lim", spline, ("t_wall_c", "t_amb_c", "epsc_wpk"), self.box()[1:]))

    @staticmethod
    def _clamped(name, spline, names, box) -> casadi.Function:
        """The spline at the inputs clamped to the box: a never-inlined call node in SX graphs (with derivatives)."""
        xs = [casadi.MX.sym(n) for n in names]
        clamped = casadi.vertcat(*[casadi.fmin(casadi.fmax(x, lo), hi) for x, (lo, hi) in zip(xs, box, strict=True)])
        return casadi.Function(name, xs, [spline(clamped)], list(names), ["out"], {"never_inline": True})

    def margin(self, n_rpm, t_wall_c, t_amb_c, epsc_wpk):
        """Smallest distance inside the box, each axis scaled by its span (< 0: outside, the splines clamp)."""
        xs = (n_rpm, t_wall_c, t_amb_c, epsc_wpk)
        m = None
        for x, (lo, hi) in zip(xs, self.box(), strict=True):
            d = casadi.fmin(x - lo, hi - x) / (hi - lo)
            m = d if m is None else casadi.fmin(m, d)
        return m


class TableCall:
    """A table Function whose SX graphs hold one call per use, value and Jacobian together.

    Numeric (and MX) arguments call the Function itself. SX arguments x give
    ``y = y(x*) + J(x*) (x - x*)``, where one call node returns the spline's value y(x*), its Jacobian
    J(x*) and x* (x* = x in value, ``stop_diff``: no derivative). The value is the spline's bit for
    bit (x - x* = 0) and so is the first derivative (J is the spline's own Jacobian), but a Jacobian of
    the SX graph then costs one spline-with-Jacobian call per use instead of one spline forward-derivative
    call per use and per forward direction (the profile of docs/oracle.md "Cost": 4.3 times cheaper on
    the oracle's 5-step interval). Second derivatives of the table are zero in SX graphs: for IPOPT's
    limited-memory Hessian (the oracle's), not for an exact Hessian.
    """

    def __init__(self, function: casadi.Function) -> None:
        self.function = function
        """The table Function (clamped spline)."""
        n = function.n_in()
        xm = casadi.MX.sym("x", n)
        zm = casadi.MX.sym("zero")
        fx = casadi.vertcat(*function.call(casadi.vertsplit(xm)))
        value_jac = casadi.Function(f"{function.name()}_value_jac", [xm], [fx, casadi.jacobian(fx, xm)])
        xs = casadi.stop_diff(xm, 1)
        y0, jac = value_jac(xs)
        # ``zero`` (passed 0) keeps each output's forward derivative structurally nonzero: CasADi's SX
        # forward mode writes NaN for a call output whose derivative has no nonzeros (3.8.2)
        self._linear = casadi.Function(
            f"{function.name()}_linearised",
            [xm, zm],
            [y0 + zm * xm[0], jac + zm * xm[0], xs + zm * xm],
            {"never_inline": True},
        )

    def __call__(self, *args):
        """The table at ``args`` (see the class)."""
        if any(isinstance(a, casadi.SX) for a in args):
            x = casadi.vertcat(*args)
            y0, jac, xs = self._linear(x, 0)
            return y0 + casadi.mtimes(jac, x - xs)
        return self.function(*args)


def _casadi_order(c: np.ndarray) -> list[float]:
    """Flatten coefficients c[i0, i1, ..., out] in CasADi's bspline order (output fastest, then axis 0, 1, ...)."""
    nd = c.ndim - 1
    return np.transpose(c, tuple(range(nd - 1, -1, -1)) + (nd,)).ravel().tolist()


class SmoothCycle:
    """The refrigerant loop of the smooth model: the ECU's speed limited smoothly to the power limit, the table's cycle.

    ``N = smooth_min(N_run, N_lim(T_wall, T_amb, epsc))`` (log-sum-exp, sharpness ``k_speed_per_rpm``),
    the cycle at N from the table; ``power_limited`` is the logistic indicator of N_run > N_lim. The
    warm start passes through unchanged (no iteration).
    """

    def __init__(self, params: PlantParams, table: SmoothCycleTable) -> None:
        table.check_params(params)
        self.params = params
        self.table = table

    def run(self, ops, n_cmd, n_run, duty, t_ev, t_amb, epsc, guess) -> CompressorRun:
        """See :meth:`~ceco_plant_sim.plant_equations.NewtonCycle.run` (same outputs, smooth)."""
        sn = ops.scaled("speed")
        n_lim = self.table.n_lim(t_ev, t_amb, epsc)
        n = sn.fmin(n_run, n_lim)
        q, p_comp, t_e, mdot = casadi.vertsplit(self.table.cycle(n, t_ev, t_amb, epsc), 1)
        return CompressorRun(
            speed_rpm=n,
            q_evap_ref_w=q,
            p_comp_w=p_comp,
            t_evap_sat_c=t_e,
            t_cond_c=t_amb + (q + self.params.eta_motor_inverter * p_comp) / epsc,  # condenser balance
            mdot_ref_kgps=mdot,
            mop_active=t_e >= self.params.te_mop_c - 1e-6,
            iterations=0.0,
            power_limited=sn.gt(n_run, n_lim),
            guess=guess,
            ok=1.0,
        )


# ---------------------------------------------------------------------------------------------- file
def write_smooth_cycle_file(
    path: str,
    params: PlantParams | None = None,
    grid: SmoothCycleGrid = DEFAULT_SMOOTH_GRID,
    command: str = REGENERATE_SMOOTH_COMMAND,
    extra: dict | None = None,
) -> dict:
    """Sample the solver (:func:`build_smooth_cycle_table`) and write the values with their provenance (NPZ).

    The provenance records the format, cycle parameters, grid, outputs and units, solver settings, the
    refrigerant tables' source, the command, the UTC date and the machine, plus ``extra``.
    """
    import datetime
    import platform

    p = (params or PlantParams()).validate()
    tab = build_smooth_cycle_table(p, grid)
    prov = {
        "format": SMOOTH_TABLE_FORMAT,
        "cycle_params": cycle_fingerprint(p),
        "grid": asdict(grid),
        "outputs": list(TABLE_OUTPUTS),
        "units": {
            "q_evap_ref_w": "W",
            "p_comp_w": "W",
            "t_evap_sat_c": "degC",
            "mdot_ref_kgps": "kg/s",
            "n_lim": "rpm",
        },
        "axes": ["speed_rpm", "t_wall_c", "t_amb_c", "epsc_wpk"],
        "solver": f"ceco_plant_sim.refrigerant.solve_cycle, tol_k {SOLVE_TOL_K}, max_iter {SOLVE_MAX_ITER}, cold start",
        "refrigerant_tables": cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k)).source,
        "command": command,
        "date_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()} {platform.system()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}",
        **(extra or {}),
    }
    members = {f"axis_{i}": a for i, a in enumerate(tab.axes)}
    members.update({k: v for k, v in tab.values.items()})
    members["n_lim_rpm"] = tab.n_lim_rpm
    savez: Any = np.savez_compressed  # numpy's stubs type **kwds as its own keyword arguments
    with open(path, "wb") as f:
        savez(f, provenance=np.array(json.dumps(prov, sort_keys=True)), **members)
    return prov


def _read(path: str) -> tuple[dict, dict]:
    fix = f"regenerate it with `{REGENERATE_SMOOTH_COMMAND}`"
    try:
        with np.load(path, allow_pickle=False) as z:
            prov = json.loads(str(z["provenance"]))
            arrays = {k: z[k] for k in z.files if k != "provenance"}
    except (OSError, KeyError, ValueError) as err:
        raise StaleSmoothTableError(f"smooth cycle table {path}: unreadable ({err}); {fix}") from err
    if prov.get("format") != SMOOTH_TABLE_FORMAT:
        raise StaleSmoothTableError(f"smooth cycle table {path}: format {prov.get('format')!r}; {fix}")
    return prov, arrays


def load_smooth_cycle_file(path: str = SHIPPED_SMOOTH_TABLE) -> SmoothCycleTable:
    """The table of a file (StaleSmoothTableError if unreadable or of another format)."""
    prov, arrays = _read(path)
    grid = SmoothCycleGrid(**{k: tuple(v) for k, v in prov["grid"].items()}).validate()
    return SmoothCycleTable(
        fingerprint=prov["cycle_params"],
        grid=grid,
        axes=[arrays[f"axis_{i}"] for i in range(4)],
        values={k: arrays[k] for k in TABLE_OUTPUTS},
        n_lim_rpm=arrays["n_lim_rpm"],
        source=f"shipped file {os.path.basename(path)} (generated {prov.get('date_utc')}, "
        f"ceco {prov.get('ceco_commit')})",
    )


def check_smooth_cycle_file(
    path: str = SHIPPED_SMOOTH_TABLE, sample: int | None = None, seed: int = 0, points=None
) -> dict:
    """Compare a file with a fresh sampling of the current solver: equal bit for bit, or StaleSmoothTableError.

    ``sample``: check only that many random grid points (and power-limit speeds) instead of all;
    ``points``: check only these grid indices (speed, wall, ambient, epsc). Returns the provenance.
    """
    prov, arrays = _read(path)
    fix = f"regenerate it with `{REGENERATE_SMOOTH_COMMAND}`"
    p = PlantParams()
    if prov["cycle_params"] != cycle_fingerprint(p):
        raise StaleSmoothTableError(f"smooth cycle table {path}: built for other plant parameters; {fix}")
    grid = SmoothCycleGrid(**{k: tuple(v) for k, v in prov["grid"].items()})
    axes = grid.axes(p)
    for i, a in enumerate(axes):
        if not np.array_equal(a, arrays[f"axis_{i}"]):
            raise StaleSmoothTableError(f"smooth cycle table {path}: axis {i} differs from the grid's; {fix}")
    solve = _solver(p)
    shape = tuple(a.size for a in axes)
    idx = list(np.ndindex(shape))
    lim = list(np.ndindex(shape[1:]))
    if points is not None:
        idx, lim = [tuple(ix) for ix in points], [tuple(ix)[1:] for ix in points]
    elif sample is not None:
        rng = np.random.default_rng(seed)
        idx = [idx[i] for i in rng.choice(len(idx), size=min(sample, len(idx)), replace=False)]
        lim = [lim[i] for i in rng.choice(len(lim), size=min(sample, len(lim)), replace=False)]
    for ix in idx:
        s = solve(*(a[i] for a, i in zip(axes, ix, strict=True)))
        for key in TABLE_OUTPUTS:
            if getattr(s, key) != arrays[key][ix]:
                raise StaleSmoothTableError(
                    f"smooth cycle table {path}: {key} at grid point {ix} is {arrays[key][ix]!r}, the solver gives "
                    f"{getattr(s, key)!r}; {fix}"
                )
    for ix in lim:
        got = _power_limit_speed(solve, p, *(a[i] for a, i in zip(axes[1:], ix, strict=True)))
        if got != arrays["n_lim_rpm"][ix]:
            raise StaleSmoothTableError(
                f"smooth cycle table {path}: n_lim at {ix} is {arrays['n_lim_rpm'][ix]!r}, "
                f"the solver gives {got!r}; {fix}"
            )
    return prov


@functools.lru_cache(maxsize=4)
def _table_for(key: str) -> SmoothCycleTable:
    params = PlantParams(**json.loads(key))
    try:
        tab = load_smooth_cycle_file(SHIPPED_SMOOTH_TABLE)
        tab.check_params(params)
        return tab
    except StaleSmoothTableError as err:
        _LOG.warning("%s: building the smooth cycle table from the solver instead (20-40 s)", err)
    return build_smooth_cycle_table(params)


def smooth_cycle_table(params: PlantParams | None = None) -> SmoothCycleTable:
    """The smooth cycle table of ``params``: the shipped file if it holds them, else built from the solver (cached)."""
    p = (params or PlantParams()).validate()
    return _table_for(json.dumps(asdict(p), sort_keys=True))
