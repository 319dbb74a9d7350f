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

from . import refrigerant_table_file as _refrigerant_table_file
from . import refrigerant_tables as _refrigerant_tables
from .refrigerant_table_file import *  # noqa: F403 - re-exported (__all__): the shipped table file
from .refrigerant_tables import *  # noqa: F403 - re-exported (__all__): the property tables
from .refrigerant_tables import CycleTables

__all__ = [
    "CompressorModel",
    "CycleSolution",
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


def _cycle_eval(
    tab: CycleTables,
    comp: CompressorModel,
    vn: float,
    t_e: float,
    t_c: float,
    t_wall_c: float,
    ua_er_wpk: float,
    t_air_c: float,
    epsc_wpk: float,
):
    """Residuals (r1, r2) [W], their analytic Jacobian, and the cycle quantities at (t_e, t_c).

    The Jacobian is exact for the piecewise-linear / bilinear interpolants.
    """
    p_e, p_e1 = tab.p_evap_pa.value_slope(t_e)
    rho, rho1 = tab.rho_suc_kgm3.value_slope(t_e)
    h1, h11 = tab.h_suc_jpkg.value_slope(t_e)
    p_c, p_c1 = tab.p_cond_pa.value_slope(t_c)
    h3, h31 = tab.h_liq_jpkg.value_slope(t_c)
    dhs, dhs_e, dhs_c = tab.dh_is_jpkg.value_grad(t_e, t_c)
    pr = p_c / p_e
    pr_e = -p_c * p_e1 / (p_e * p_e)
    pr_c = p_c1 / p_e
    # volumetric efficiency and its slope in pr (0 where floored / pr < 1)
    prc = pr if pr > 1.0 else 1.0
    ev = comp.eta_vol_0 - comp.eta_vol_slope * (prc - 1.0)
    if ev < 0.3:
        ev, ev1 = 0.3, 0.0
    else:
        ev1 = -comp.eta_vol_slope if pr > 1.0 else 0.0
    d = prc - comp.pr_opt
    ei = comp.eta_is_max - comp.eta_is_curv * d * d
    if ei < 0.3:
        ei, ei1 = 0.3, 0.0
    else:
        ei1 = -2.0 * comp.eta_is_curv * d if pr > 1.0 else 0.0
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
    evaluations are reached.
    """
    if speed_rpm <= 0.0:
        return CycleSolution(t_wall_c, t_air_cond_c, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, False, False, 0)
    vn = comp.displacement_m3 * speed_rpm / 60.0
    if guess is None:
        t_e = min(t_wall_c - 5.0, te_mop_c)
        t_c = t_air_cond_c + 15.0
    else:
        t_e, t_c = guess
    args = (t_wall_c, ua_er_wpk, t_air_cond_c, epsc_cond_wpk)
    mop = False
    hp = False
    it = 0
    for _ in range(3):  # constraint flags only get added: at most 3 solves
        converged = False
        while it < max_iter:
            (r1, r2, j11, j12, j21, j22, mdot, q_e, w_sh, pr, p_e, p_e1, p_c, p_c1) = _cycle_eval(
                tab, comp, vn, t_e, t_c, *args
            )
            it += 1
            if hp:  # head-pressure control: condenser air reduced so that p_c = pr_min p_e
                r2 = p_c - pr_min * p_e
                j21 = -pr_min * p_e1
                j22 = p_c1
            if mop:  # T_e pinned at the MOP: the condenser (or head-pressure) equation alone
                de = 0.0
                dc = -r2 / j22
            else:
                det = j11 * j22 - j12 * j21
                de = -(j22 * r1 - j12 * r2) / det
                dc = -(-j21 * r1 + j11 * r2) / det
            if abs(de) < tol_k and abs(dc) < tol_k:
                converged = True  # this point is within ~tol_k of the root: keep its evaluated quantities
                break
            t_e += max(-10.0, min(10.0, de))
            t_c += max(-10.0, min(10.0, dc))
        if not converged:
            raise RuntimeError(
                f"refrigerant cycle did not converge in {max_iter} iterations "
                f"(speed {speed_rpm:.0f} rpm, wall {t_wall_c:.2f} degC)"
            )
        new_mop = mop or t_e > te_mop_c
        new_hp = hp or pr < pr_min * (1.0 - 1e-9)
        if new_mop == mop and new_hp == hp:
            break
        if new_mop:
            t_e = te_mop_c
        mop, hp = new_mop, new_hp
    return CycleSolution(
        t_evap_sat_c=t_e,
        t_cond_c=t_c,
        mdot_ref_kgps=mdot,
        q_evap_ref_w=q_e,
        w_shaft_w=w_sh,
        p_comp_w=w_sh / comp.eta_motor_inverter,
        q_cond_w=q_e + w_sh,
        pressure_ratio=pr,
        mop_active=mop,
        head_pressure_control=hp,
        iterations=it,
    )
