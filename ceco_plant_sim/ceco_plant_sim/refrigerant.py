"""Vapour-compression cycle of the plant's A/C, with CoolProp properties.

The refrigerant loop is quasi-steady (its mass and energy storage are fast
compared with the evaporator wall and the cabin): at every plant sub-step the
evaporating and condensing temperatures are the solution of two algebraic
balances (see :func:`solve_cycle` and ``docs/plant.md``)::

    r1 = mdot_ref * (h1 - h3)              - UA_er * (T_wall - T_e)        = 0
    r2 = mdot_ref * (h1 - h3 + dh_s/eta_is) - eps_c * C_c * (T_c - T_amb) = 0

    mdot_ref = rho_1(T_e) * V_disp * N/60 * eta_vol(pr)       (compressor)
    W_shaft  = mdot_ref * dh_s(T_e, T_c) / eta_is(pr),  P_el = W_shaft / eta_mi

State points: 1 compressor suction (evaporator exit, superheat ``dT_sh``
above T_e at the evaporating pressure, suction line losses neglected),
2s isentropic discharge at the condensing pressure, 3 condenser exit
(subcooled by ``dT_sc`` below T_c at the condensing pressure), 4 evaporator
inlet after isenthalpic expansion (h4 = h3).

Refrigerant properties come from CoolProp (Bell et al., Ind. Eng. Chem. Res.
53 (2014) 2498) for R-1234yf (Richter et al. / Akasaka EOS as shipped in
CoolProp). They are tabulated once per (fluid, superheat, subcooling, grid)
by :func:`build_cycle_tables` (cached) and interpolated (linear in 1-D,
bilinear in 2-D on uniform grids) in pure Python, which is what makes a
600 s simulation run in a fraction of a second. ``tests/test_refrigerant.py``
bounds the table error against direct CoolProp calls.

The plant takes its tables from :func:`cycle_tables`: the configuration of the
default ``PlantParams`` (R-1234yf, 5 K superheat, 5 K subcooling, the default
grid) is shipped as a generated data file, ``data/cycle_tables_R1234yf.npz``
(the raw CoolProp values of :func:`build_cycle_tables`, float64, with their
provenance: CoolProp version, fluid, grid, superheat, subcooling, generation
command and date), loaded in a few milliseconds without importing CoolProp
(whose import alone takes ~2.3 s). Any other configuration is built with
CoolProp, imported then, with a warning. Regenerate the file with
``python tools/make_refrigerant_tables.py``; ``--check`` (and
``tests/test_refrigerant.py``) compare it bit for bit with a fresh build.

A thermostatic expansion valve with a maximum operating pressure (MOP
charge) caps the evaporating temperature at ``te_mop_c``: in a hot start the
compressor then runs at the MOP suction density and the evaporator is
compressor-limited (the refrigerant leaves more superheated; the
superheat change is neglected in the enthalpies).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

from . import refrigerant_table_file as _refrigerant_table_file
from . import refrigerant_tables as _refrigerant_tables
from .plant_ops import NUMERIC, cycle_failure_message
from .refrigerant_table_file import *  # noqa: F403 - re-exported (__all__): the shipped table file
from .refrigerant_tables import *  # noqa: F403 - re-exported (__all__): the property tables
from .refrigerant_tables import CycleTables

__all__ = [
    "CompressorModel",
    "CycleSolution",
    "CycleVars",
    "cycle_vars",
    "solve_cycle",
    *_refrigerant_tables.__all__,
    *_refrigerant_table_file.__all__,
]


@dataclass(frozen=True)
class CompressorModel:
    """Electric scroll compressor efficiencies (pressure-ratio maps, typical of automotive scrolls)."""

    displacement_m3: float
    """Swept volume per revolution [m3]."""
    eta_vol_0: float
    """Volumetric efficiency extrapolated to pressure ratio 1 [-]."""
    eta_vol_slope: float
    """Volumetric efficiency loss per unit of pressure ratio above 1 [-]."""
    eta_is_max: float
    """Peak isentropic efficiency [-]."""
    eta_is_curv: float
    """Isentropic efficiency loss per (pressure ratio - optimum)^2 [-]."""
    pr_opt: float
    """Pressure ratio of peak isentropic efficiency (built-in volume ratio) [-]."""
    eta_motor_inverter: float
    """Motor and inverter efficiency (electrical -> shaft) [-]."""

    def eta_vol(self, pr: float) -> float:
        """Volumetric efficiency at pressure ratio ``pr`` (floored at 0.3)."""
        return max(0.3, self.eta_vol_0 - self.eta_vol_slope * (max(pr, 1.0) - 1.0))

    def eta_is(self, pr: float) -> float:
        """Isentropic efficiency at pressure ratio ``pr`` (floored at 0.3)."""
        d = max(pr, 1.0) - self.pr_opt
        return max(0.3, self.eta_is_max - self.eta_is_curv * d * d)


@dataclass(frozen=True)
class CycleSolution:
    """Quasi-steady refrigerant cycle at one instant."""

    t_evap_sat_c: float
    """Evaporating (saturation) temperature [degC]."""
    t_cond_c: float
    """Condensing temperature [degC]."""
    mdot_ref_kgps: float
    """Refrigerant mass flow [kg/s]."""
    q_evap_ref_w: float
    """Heat absorbed by the refrigerant in the evaporator [W]."""
    w_shaft_w: float
    """Compressor shaft power [W]."""
    p_comp_w: float
    """Compressor electrical power (shaft / motor-inverter efficiency) [W]."""
    q_cond_w: float
    """Heat rejected at the condenser [W]."""
    pressure_ratio: float
    """Discharge / suction pressure ratio [-]."""
    mop_active: bool
    """True when the expansion valve's MOP caps the evaporating temperature."""
    head_pressure_control: bool
    """True when head-pressure control holds the pressure ratio at its minimum (cold condenser air)."""
    iterations: int
    """Newton iterations used."""


class CycleVars(NamedTuple):
    """The cycle solve's result as plain values (floats numerically, CasADi scalars symbolically).

    The fields of :class:`CycleSolution` but ``q_cond_w``, plus ``converged`` (the solve stopped by
    its rule within ``max_iter`` evaluations; the numeric evaluation raises instead of returning False).
    """

    t_evap_sat_c: Any
    t_cond_c: Any
    mdot_ref_kgps: Any
    q_evap_ref_w: Any
    w_shaft_w: Any
    p_comp_w: Any
    pressure_ratio: Any
    mop_active: Any
    head_pressure_control: Any
    iterations: Any
    converged: Any


class _Newton(NamedTuple):
    """State of the cycle's Newton iteration between property evaluations."""

    t_e: Any
    """Current evaporating temperature [degC]."""
    t_c: Any
    """Current condensing temperature [degC]."""
    mop: Any
    """MOP pin active."""
    hp: Any
    """Head-pressure control active."""
    it: Any
    """Property evaluations so far."""
    rounds: Any
    """Converged solves so far (a constraint flag added starts a new one; at most 3)."""
    done: Any
    """Converged with no new constraint flag."""
    mdot: Any
    """Refrigerant flow of the last converged evaluation [kg/s]."""
    q_e: Any
    """Evaporator capacity of the last converged evaluation [W]."""
    w_sh: Any
    """Shaft power of the last converged evaluation [W]."""
    pr: Any
    """Pressure ratio of the last converged evaluation [-]."""


def _cycle_eval(
    ops,
    tab: CycleTables,
    comp: CompressorModel,
    vn,
    t_e,
    t_c,
    t_wall_c,
    ua_er_wpk,
    t_air_c,
    epsc_wpk,
):
    """Residuals (r1, r2) [W], their analytic Jacobian, and the cycle quantities at (t_e, t_c).

    The Jacobian is exact for the piecewise-linear / bilinear interpolants. ``ops`` evaluates it
    (:mod:`ceco_plant_sim.plant_ops`).
    """
    p_e, p_e1 = ops.interp1(tab.p_evap_pa, t_e)
    rho, rho1 = ops.interp1(tab.rho_suc_kgm3, t_e)
    h1, h11 = ops.interp1(tab.h_suc_jpkg, t_e)
    p_c, p_c1 = ops.interp1(tab.p_cond_pa, t_c)
    h3, h31 = ops.interp1(tab.h_liq_jpkg, t_c)
    dhs, dhs_e, dhs_c = ops.interp2(tab.dh_is_jpkg, t_e, t_c)
    pr = p_c / p_e
    pr_e = -p_c * p_e1 / (p_e * p_e)
    pr_c = p_c1 / p_e
    # volumetric and isentropic efficiencies (floored at 0.3, pr < 1 counted as 1) and their slopes in pr
    # (0 where floored or pr <= 1)
    above = pr > 1.0
    prc = ops.fmax(pr, 1.0)
    ev = comp.eta_vol_0 - comp.eta_vol_slope * (prc - 1.0)
    ev1 = ops.where(ops.logic_and(above, ev >= 0.3), -comp.eta_vol_slope, 0.0)
    ev = ops.fmax(ev, 0.3)
    d = prc - comp.pr_opt
    ei = comp.eta_is_max - comp.eta_is_curv * d * d
    ei1 = ops.where(ops.logic_and(above, ei >= 0.3), -2.0 * comp.eta_is_curv * d, 0.0)
    ei = ops.fmax(ei, 0.3)
    m = rho * vn * ev
    m_e = vn * (rho1 * ev + rho * ev1 * pr_e)
    m_c = vn * rho * ev1 * pr_c
    dh = h1 - h3
    w = dhs / ei
    w_e = dhs_e / ei - dhs * ei1 * pr_e / (ei * ei)
    w_c = dhs_c / ei - dhs * ei1 * pr_c / (ei * ei)
    q_e = m * dh
    r1 = q_e - ua_er_wpk * (t_wall_c - t_e)
    r2 = m * (dh + w) - epsc_wpk * (t_c - t_air_c)
    j11 = m_e * dh + m * h11 + ua_er_wpk
    j12 = m_c * dh - m * h31
    j21 = m_e * (dh + w) + m * (h11 + w_e)
    j22 = m_c * (dh + w) + m * (-h31 + w_c) - epsc_wpk
    return r1, r2, j11, j12, j21, j22, m, q_e, m * w, pr, p_e, p_e1, p_c, p_c1


def _newton_evaluation(s: _Newton, ops, tab, comp, vn, args, te_mop_c, tol_k, pr_min) -> _Newton:
    """One property evaluation of the Newton solve: a Newton update, or (converged) the constraint-flag check."""
    r1, r2, j11, j12, j21, j22, m, q_e, w_sh, pr, p_e, p_e1, p_c, p_c1 = _cycle_eval(
        ops, tab, comp, vn, s.t_e, s.t_c, *args
    )
    it = s.it + 1
    hp = s.hp
    # head-pressure control: condenser air reduced so that p_c = pr_min p_e
    r2, j21, j22 = ops.where(hp, (p_c - pr_min * p_e, -pr_min * p_e1, p_c1), (r2, j21, j22))

    det = j11 * j22 - j12 * j21
    de, dc = ops.where(
        s.mop,
        (0.0, -r2 / j22),  # T_e pinned at the MOP: the condenser (or head-pressure) equation alone
        (-(j22 * r1 - j12 * r2) / det, -(-j21 * r1 + j11 * r2) / det),
    )
    converged = ops.logic_and(abs(de) < tol_k, abs(dc) < tol_k)

    def check_flags():  # this point is within ~tol_k of the root: keep its evaluated quantities
        pin = ops.logic_and(ops.logic_not(s.mop), s.t_e > te_mop_c)
        new_mop = ops.logic_or(s.mop, pin)
        # head-pressure control is judged on a solution with the evaporating temperature it will have:
        # not in the round that pins the MOP (there T_e, so p_e, is still above the pin)
        new_hp = ops.logic_or(hp, ops.logic_and(ops.logic_not(pin), pr < pr_min * (1.0 - 1e-9)))
        same = ops.logic_and(new_mop == s.mop, new_hp == hp)
        rounds = s.rounds + 1
        t_e = ops.where(ops.logic_and(ops.logic_not(same), new_mop), te_mop_c, s.t_e)
        done = ops.logic_or(same, rounds >= 3)  # constraint flags only get added: at most 3 solves
        return _Newton(t_e, s.t_c, new_mop, new_hp, it, rounds, done, m, q_e, w_sh, pr)

    def update():  # each update limited to 10 K
        t_e = s.t_e + ops.fmax(-10.0, ops.fmin(10.0, de))
        t_c = s.t_c + ops.fmax(-10.0, ops.fmin(10.0, dc))
        return _Newton(t_e, t_c, s.mop, hp, it, s.rounds, s.done, s.mdot, s.q_e, s.w_sh, s.pr)

    return ops.cond(converged, check_flags, update)


def cycle_vars(
    ops,
    tab: CycleTables,
    comp: CompressorModel,
    speed_rpm,
    t_wall_c,
    ua_er_wpk: float,
    t_air_cond_c,
    epsc_cond_wpk,
    te_mop_c: float,
    guess,
    tol_k: float = 1e-7,
    max_iter: int = 30,
    pr_min: float = 1.0,
) -> CycleVars:
    """:func:`solve_cycle` evaluated by ``ops`` (the one implementation of the solve).

    ``guess`` is (t_e [degC], t_c [degC], valid): valid false (0) takes the built-in start.
    Numerically the iteration stops at its rule and a failure raises RuntimeError; symbolically
    (:class:`~ceco_plant_sim.plant_ops.ExactOps`) the ``max_iter`` evaluations are unrolled, each
    masked once the solve is done, and ``converged`` reports the stop. The Newton update and the
    pinned update are both computed and one is selected (numerically too: the Jacobian's
    determinant is far from 0, |det| ~ UA_er eps_c C_c).
    """

    def off():
        return CycleVars(t_wall_c, t_air_cond_c, 0.0, 0.0, 0.0, 0.0, 1.0, False, False, 0, True)

    def on():
        vn = comp.displacement_m3 * speed_rpm / 60.0
        g_e, g_c, g_ok = guess
        t_e = ops.where(g_ok, g_e, ops.fmin(t_wall_c - 5.0, te_mop_c))
        t_c = ops.where(g_ok, g_c, t_air_cond_c + 15.0)
        args = (t_wall_c, ua_er_wpk, t_air_cond_c, epsc_cond_wpk)
        s = _Newton(t_e, t_c, False, False, 0, 0, False, 0.0, 0.0, 0.0, 1.0)
        s = ops.loop(int(max_iter), _newton_evaluation, s, ops, tab, comp, vn, args, te_mop_c, tol_k, pr_min)
        ok = ops.check(
            s.done,
            lambda: cycle_failure_message(max_iter, f"speed {speed_rpm:.0f} rpm, wall {t_wall_c:.2f} degC"),
        )
        return CycleVars(
            s.t_e, s.t_c, s.mdot, s.q_e, s.w_sh, s.w_sh / comp.eta_motor_inverter, s.pr, s.mop, s.hp, s.it, ok
        )

    return ops.cond(speed_rpm <= 0.0, off, on)


def solve_cycle(
    tab: CycleTables,
    comp: CompressorModel,
    speed_rpm: float,
    t_wall_c: float,
    ua_er_wpk: float,
    t_air_cond_c: float,
    epsc_cond_wpk: float,
    te_mop_c: float,
    guess: tuple[float, float] | None = None,
    tol_k: float = 1e-7,
    max_iter: int = 30,
    pr_min: float = 1.0,
) -> CycleSolution:
    """Solve the quasi-steady cycle for (T_e, T_c) by Newton's method.

    Args:
        tab: the refrigerant property tables.
        comp: the compressor's efficiencies and displacement.
        speed_rpm: compressor speed [rpm] (>= 0; 0 means off).
        t_wall_c: evaporator wall temperature [degC].
        ua_er_wpk: wall-to-refrigerant conductance of the evaporator [W/K].
        t_air_cond_c: condenser inlet air temperature [degC].
        epsc_cond_wpk: condenser effectiveness times air heat-capacity rate [W/K].
        te_mop_c: expansion valve MOP cap on the evaporating temperature [degC].
        guess: starting (T_e, T_c) [degC]; None for a built-in start.
        tol_k: convergence tolerance on the Newton update [K].
        max_iter: largest number of property evaluations [-].
        pr_min: minimum pressure ratio held by head-pressure control [-] (1 = none).

    Newton on (r1, r2) with the analytic Jacobian of the interpolated
    properties, each update limited to 10 K; converged at the first iterate
    whose Newton update is below ``tol_k`` in both temperatures (that iterate
    and its evaluated flows are returned: it lies within ~tol_k of the root).
    ``iterations`` counts property evaluations.
    If the solution exceeds ``te_mop_c``, T_e is pinned at the MOP and only
    the condenser equation is solved for T_c. If the pressure ratio falls
    below ``pr_min`` (condenser air colder than the evaporator), the
    condenser balance r2 is replaced by p_c = pr_min p_e (head-pressure
    control throttles the condenser air; the condenser then rejects
    Q_ref + W at that pressure). Raises RuntimeError if ``max_iter``
    evaluations are reached. The numeric evaluation of :func:`cycle_vars`.
    """
    g = (0.0, 0.0, False) if guess is None else (guess[0], guess[1], True)
    v = cycle_vars(
        NUMERIC,
        tab,
        comp,
        speed_rpm,
        t_wall_c,
        ua_er_wpk,
        t_air_cond_c,
        epsc_cond_wpk,
        te_mop_c,
        g,
        tol_k,
        max_iter,
        pr_min,
    )
    return CycleSolution(
        t_evap_sat_c=v.t_evap_sat_c,
        t_cond_c=v.t_cond_c,
        mdot_ref_kgps=v.mdot_ref_kgps,
        q_evap_ref_w=v.q_evap_ref_w,
        w_shaft_w=v.w_shaft_w,
        p_comp_w=v.p_comp_w,
        q_cond_w=v.q_evap_ref_w + v.w_shaft_w,
        pressure_ratio=v.pressure_ratio,
        mop_active=v.mop_active,
        head_pressure_control=v.head_pressure_control,
        iterations=v.iterations,
    )
