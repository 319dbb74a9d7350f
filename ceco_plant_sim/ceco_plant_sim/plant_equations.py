"""The plant's equations, written once: the simulator, the exact symbolic model and the smooth one.

One right-hand side (:meth:`PlantEquations.rhs`: air loop, cabin network, moisture, the A/C ECU's
compressor PI with its limits and anti-windup) and one integrator (:meth:`PlantEquations.step`:
``ceil(dt / substep_s)`` classical RK4 sub-steps with the energy and water quadratures), evaluated
by an ``ops`` object (:mod:`ceco_plant_sim.plant_ops`):

* numerically (:data:`~ceco_plant_sim.plant_ops.NUMERIC`) by :class:`~ceco_plant_sim.plant.CabinPlant`,
  bit for bit the plant before the equations were written once;
* symbolically with exact branches (:class:`~ceco_plant_sim.plant_ops.ExactOps`) and
* symbolically and smoothly (:class:`~ceco_plant_sim.plant_ops.SmoothOps`), both as CasADi Functions
  by :class:`~ceco_plant_sim.plant_model.PlantModel`.

The refrigerant loop is a ``cycle`` object with one method, ``run``: :class:`NewtonCycle` (the
plant's: the Newton solve at the ECU's speed, the inverter power limit by a secant on the speed; for
the numeric and exact evaluations) or :class:`~ceco_plant_sim.smooth_cycle.SmoothCycle` (a smooth
table of that solve, for the smooth evaluation).

Vectors are named tuples whose fields are the layouts below (:data:`STATE_NAMES` from
:class:`~ceco_plant_sim.plant_state.PlantState`, :data:`INPUT_NAMES` from
:class:`~ceco_core.contracts.AcInput`): a new state is a new ``PlantState`` field and its derivative
in :meth:`PlantEquations.rhs`; a new input is a new ``AcInput`` field read there by name.
Equations, units, references: docs/plant.md.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any, NamedTuple

from ceco_core.air_quality import (
    cabin_water_flows_kgps,
    co2_flows_kgps,
    co2_generation_kgps,
    co2_kgkg_from_ppm,
    co2_ppm_from_kgkg,
    coil_outlet_humidity_ratio,
    leakage_kgps,
)
from ceco_core.contracts import AcInput
from ceco_core.psychro import humidity_ratio_from_vapour_pressure, relative_humidity, saturation_vapour_pressure_pa

from .plant_ops import NUMERIC
from .plant_params import PlantParams
from .plant_state import ENVIRONMENT_FIELDS, PlantState
from .refrigerant import CompressorModel, CycleTables, CycleVars, cycle_vars

__all__ = [
    "STATE_NAMES",
    "INPUT_NAMES",
    "ENV_NAMES",
    "FLOW_NAMES",
    "ALG_NAMES",
    "State",
    "Input",
    "Env",
    "Flows",
    "Alg",
    "Guess",
    "NO_GUESS",
    "CompressorRun",
    "blower_power_w",
    "condenser_eps_c_wpk",
    "saturation_excess_kgkg",
    "cabin_vapour_kgkg",
    "cabin_relative_humidity",
    "compressor_model",
    "NewtonCycle",
    "PlantEquations",
]


class State(NamedTuple):
    """The plant's state vector: the :class:`~ceco_plant_sim.plant_state.PlantState` fields, in order."""

    t_cab_c: Any
    """Cabin air temperature [degC]."""
    t_int_c: Any
    """Interior mass temperature [degC]."""
    t_shell_c: Any
    """Shell temperature [degC]."""
    t_glass_c: Any
    """Glazing temperature [degC]."""
    t_evap_c: Any
    """Evaporator wall temperature [degC]."""
    t_duct_c: Any
    """HVAC case and duct wall temperature [degC]."""
    w_cab_kgkg: Any
    """Cabin humidity ratio [kg/kg dry air]."""
    comp_pi_integral_rpm: Any
    """Integral part of the compressor PI [rpm]."""
    recirc_share: Any
    """Position of the fresh/recirculation door: recirculated share of the blower flow [0..1]."""
    co2_cab_kgkg: Any
    """Cabin CO2 [kg CO2/kg dry air]."""


class Input(NamedTuple):
    """The commanded inputs: the :class:`~ceco_core.contracts.AcInput` fields, in order."""

    mdot_bl_kgps: Any
    """Blower air mass flow [kg/s]."""
    t_evap_sp_c: Any
    """Evaporator wall temperature set-point [degC]."""
    recirc_share: Any
    """Commanded recirculated share of the blower flow [0..1] (a number here: the simulator puts the
    plant's default in for a command that leaves the door alone)."""


class Env(NamedTuple):
    """The environment the plant is driven by (``ENVIRONMENT_FIELDS``, in order)."""

    t_amb_c: Any
    """Ambient air temperature [degC]."""
    solar_wm2: Any
    """Solar irradiance on the vehicle [W/m2]."""
    speed_mps: Any
    """Vehicle speed [m/s]."""
    rh: Any
    """Ambient relative humidity [0..1]."""


class Flows(NamedTuple):
    """Flows integrated over a step with the RK4 weights (then [J] or [kg])."""

    p_comp_w: Any
    """Compressor electrical power [W]."""
    p_cond_fan_w: Any
    """Condenser fan electrical power [W]."""
    q_evap_w: Any
    """Heat removed from the air by the evaporator, sensible + latent [W]."""
    q_latent_w: Any
    """Its latent part [W]."""
    q_evap_ref_w: Any
    """Heat absorbed by the refrigerant [W]."""
    mdot_water_in_kgps: Any
    """Water into the cabin air: fresh air, leakage, occupants [kg/s]."""
    mdot_water_out_kgps: Any
    """Water leaving with the exfiltrated air [kg/s]."""
    mdot_condensate_kgps: Any
    """Water condensed on the evaporator and fog deposited from the cabin air [kg/s]."""
    mdot_co2_in_kgps: Any
    """CO2 into the cabin air with the fresh share of the supply and the leakage [kg/s]."""
    mdot_co2_out_kgps: Any
    """CO2 leaving with the exfiltrated air [kg/s]."""
    mdot_co2_gen_kgps: Any
    """CO2 exhaled by the occupants [kg/s]."""


class Alg(NamedTuple):
    """Algebraic variables at one instant (the PlantOutputs fields of those names)."""

    t_vent_c: Any
    """Vent air temperature [degC]."""
    t_evap_out_c: Any
    """Air temperature leaving the evaporator [degC]."""
    t_evap_sat_c: Any
    """Refrigerant evaporating temperature [degC]."""
    t_cond_c: Any
    """Refrigerant condensing temperature [degC]."""
    comp_speed_rpm: Any
    """Compressor speed [rpm]."""
    comp_duty: Any
    """Compressor on-time fraction [0..1]."""
    capacity_limited: Any
    """The speed or power limit binds."""
    mop_active: Any
    """The MOP caps the evaporating temperature."""
    mdot_ref_kgps: Any
    """Refrigerant flow, duty-averaged [kg/s]."""
    cycle_iterations: Any
    """Property evaluations of the last cycle solve [-]."""


STATE_NAMES = State._fields
"""The plant's states in integrator order."""
INPUT_NAMES = Input._fields
"""The commanded inputs: blower flow [kg/s], evaporator set-point [degC], recirculated share [0..1]."""
ENV_NAMES = Env._fields
"""The environment: ambient [degC], solar [W/m2], vehicle speed [m/s], ambient rh [0..1]."""
FLOW_NAMES = Flows._fields
"""The integrated flows (:class:`Flows`)."""
ALG_NAMES = Alg._fields
"""The algebraic variables (:class:`Alg`)."""

for _vec, _names, _owner in (
    (State, tuple(f.name for f in fields(PlantState)), "PlantState"),
    (Input, tuple(f.name for f in fields(AcInput)), "AcInput"),
    (Env, ENVIRONMENT_FIELDS, "plant_state.ENVIRONMENT_FIELDS"),
):
    if _vec._fields != _names:  # a state or input added on one side only
        raise TypeError(f"plant_equations.{_vec.__name__} fields {_vec._fields} differ from {_owner}'s {_names}")


class Guess(NamedTuple):
    """Warm start of the refrigerant solve, carried from RK4 stage to stage and step to step."""

    t_evap_sat_c: Any
    """Evaporating temperature of the last solve with the compressor running [degC]."""
    t_cond_c: Any
    """Its condensing temperature [degC]."""
    valid: Any
    """1 once a solve ran (0: the solve's built-in start)."""


NO_GUESS = Guess(0.0, 0.0, 0.0)
"""No warm start yet (key-on)."""


class CompressorRun(NamedTuple):
    """What the refrigerant loop returns to the right-hand side (per unit of on-time, before the duty)."""

    speed_rpm: Any
    """Compressor speed [rpm] (0 when off)."""
    q_evap_ref_w: Any
    """Refrigerant capacity while running [W]."""
    p_comp_w: Any
    """Compressor electrical power while running [W]."""
    t_evap_sat_c: Any
    """Evaporating temperature [degC]."""
    t_cond_c: Any
    """Condensing temperature [degC]."""
    mdot_ref_kgps: Any
    """Refrigerant flow while running [kg/s]."""
    mop_active: Any
    """The expansion valve's MOP caps the evaporating temperature."""
    iterations: Any
    """Property evaluations of the last cycle solve [-]."""
    power_limited: Any
    """The inverter power limit lowered the speed."""
    guess: Guess
    """Warm start for the next solve."""
    ok: Any
    """Every cycle solve converged."""


def blower_power_w(p: PlantParams, mdot_kgps):
    """Fan law: P = dp(mdot) * Vdot / eta + P_fixed, dp = dp_ref (mdot/mdot_ref)^2  =>  P ~ mdot^3 [W]."""
    r = mdot_kgps / p.mdot_bl_ref_kgps
    return p.dp_blower_ref_pa * r * r * (mdot_kgps / p.rho_air_kgm3) / p.eta_blower + p.p_blower_fixed_w


def saturation_excess_kgkg(params: PlantParams, t_c, w_kgkg, ops=NUMERIC):
    """Water beyond saturation of air at ``t_c`` [degC] holding ``w_kgkg`` [kg water/kg dry air]: condensed [kg/kg].

    ``max(W - W_s(t), 0)``, ``W_s = 0.621945 p_ws(t) / (p - p_ws(t))`` (ASHRAE Fundamentals 2017 ch. 1,
    eq. 23; a state beyond it is saturated air plus condensed water, the fog region of the chart);
    the max is the ``water`` scale's (exact, or softplus in the smooth model). docs/plant.md "cabin humidity".
    """
    pws = ops.scalar(saturation_vapour_pressure_pa(t_c))
    w_s = humidity_ratio_from_vapour_pressure(pws, params.p_atm_pa)
    return ops.scaled("water").fmax(w_kgkg - w_s, 0.0)


def cabin_vapour_kgkg(params: PlantParams, t_cab_c, w_cab_kgkg, ops=NUMERIC):
    """Vapour held by the cabin air [kg/kg dry air]: ``min(W_cab, W_s(T_cab)) = W_cab - W_fog``.

    The cabin's water ``w_cab_kgkg`` [kg/kg] beyond saturation at ``t_cab_c`` [degC] is fog
    (:func:`saturation_excess_kgkg`); the vapour, its pressure and dew point stop at saturation
    (docs/plant.md "cabin humidity"). Below saturation it is ``w_cab_kgkg`` itself (bit for bit).
    """
    return w_cab_kgkg - saturation_excess_kgkg(params, t_cab_c, w_cab_kgkg, ops)


def cabin_relative_humidity(params: PlantParams, t_cab_c, w_cab_kgkg, ops=NUMERIC):
    """Relative humidity of the cabin air [0..1]: ``p_w(W_vap) / p_ws(T_cab)`` of :func:`cabin_vapour_kgkg`.

    ASHRAE Fundamentals 2017 ch. 1, eq. 24. At saturation the quotient can exceed 1 by rounding (4e-16); it
    is then 1.
    """
    rh = relative_humidity(t_cab_c, cabin_vapour_kgkg(params, t_cab_c, w_cab_kgkg, ops), params.p_atm_pa)
    return ops.where(rh > 1.0, 1.0, rh)


def condenser_eps_c_wpk(params: PlantParams, speed_mps, ops=NUMERIC):
    """Condenser effectiveness x air heat-capacity rate [W/K] at vehicle speed ``speed_mps``.

    Face velocity v = sqrt(v_fan^2 + (k_ram V)^2) (fan and ram pressure add
    across the quadratic core resistance), mdot_air = rho A v, UA = UA_ref
    (v / v_ref)^n, eps = 1 - exp(-UA / (mdot_air cp)) (condensing side
    isothermal, C_r = 0; Incropera & DeWitt, eq. 11.35a).
    """
    p = params
    v = ops.sqrt(p.v_face_fan_mps**2 + (p.ram_face_ratio * speed_mps) ** 2)
    c_air = p.rho_air_kgm3 * p.a_cond_face_m2 * v * p.cp_air_jpkgk
    ua = p.ua_cond_ref_wpk * (v / p.v_face_ref_mps) ** p.ua_cond_exp
    return c_air * (1.0 - ops.exp(-ua / c_air))


def compressor_model(p: PlantParams) -> CompressorModel:
    """The compressor's displacement and efficiency maps from the plant parameters."""
    return CompressorModel(
        displacement_m3=p.displacement_m3,
        eta_vol_0=p.eta_vol_0,
        eta_vol_slope=p.eta_vol_slope,
        eta_is_max=p.eta_is_max,
        eta_is_curv=p.eta_is_curv,
        pr_opt=p.pr_opt,
        eta_motor_inverter=p.eta_motor_inverter,
    )


class _Secant(NamedTuple):
    n0: Any
    f0: Any
    n: Any
    sol: CycleVars
    done: Any
    ok: Any


class NewtonCycle:
    """The plant's refrigerant loop: the cycle solved by Newton at the ECU's speed (numeric and exact evaluations).

    If the compressor at full duty would draw more than ``p_comp_max_w``, the ECU lowers the speed
    until P_el = P_max: secant iteration on P_el(N) - P_max from N and N P_max / P_el(N), stopped
    within 0.05 % of the limit (cap 6), each solve warm-started from the previous one.
    """

    def __init__(self, params: PlantParams, tables: CycleTables) -> None:
        self.params = params
        self.tables = tables
        self.comp = compressor_model(params)

    def solve(self, ops, speed_rpm, t_wall_c, t_amb_c, epsc_wpk, guess: Guess) -> CycleVars:
        """The cycle at one speed (:func:`~ceco_plant_sim.refrigerant.cycle_vars`; one Function symbolically)."""
        p = self.params

        def solve(n, t_w, t_a, e_c, g_e, g_c, g_ok):
            return cycle_vars(
                ops,
                self.tables,
                self.comp,
                n,
                t_w,
                p.ua_evap_ref_wpk,
                t_a,
                e_c,
                p.te_mop_c,
                (g_e, g_c, g_ok),
                p.cycle_tol_k,
                p.cycle_max_iter,
                p.pr_min,
            )

        return ops.call("cycle_solve", solve, speed_rpm, t_wall_c, t_amb_c, epsc_wpk, *guess)

    def run(self, ops, n_cmd, n_run, duty, t_ev, t_amb, epsc, guess: Guess) -> CompressorRun:
        """The loop at the ECU's command: speed ``n_run`` when ``n_cmd > 0``, the power limit at full duty."""
        p_max = self.params.p_comp_max_w
        speed = ops.where(n_cmd > 0.0, n_run, 0.0)
        sol = self.solve(ops, speed, t_ev, t_amb, epsc, guess)
        limited = ops.logic_and(duty == 1.0, sol.p_comp_w > p_max)

        def body(s: _Secant, t_ev, t_amb, epsc) -> _Secant:  # one secant update on P_el(N) - P_max
            p_max = self.params.p_comp_max_w
            s2 = self.solve(ops, s.n, t_ev, t_amb, epsc, Guess(s.sol.t_evap_sat_c, s.sol.t_cond_c, 1.0))
            f1 = s2.p_comp_w - p_max
            ok = ops.logic_and(s.ok, s2.converged)
            stop = ops.logic_or(abs(f1) < 5e-4 * p_max, f1 == s.f0)
            return ops.cond(
                stop,
                lambda: _Secant(s.n0, s.f0, s.n, s2, True, ok),
                lambda: _Secant(s.n, f1, s.n - f1 * (s.n - s.n0) / (f1 - s.f0), s2, False, ok),
            )

        def power_limit():
            # done from the start where the limit does not bind: numerically never (this branch runs only
            # when it binds); symbolically the discarded branch then costs no iteration (CompiledOps)
            done = ops.logic_not(limited)
            s = _Secant(speed, sol.p_comp_w - p_max, speed * p_max / sol.p_comp_w, sol, done, sol.converged)
            s = ops.loop(6, body, s, t_ev, t_amb, epsc)
            return s.n, s.sol, s.ok

        speed, sol, ok = ops.cond(limited, power_limit, lambda: (speed, sol, sol.converged))
        # warm start of the next solve (the caller decides whether to keep it)
        guess = ops.where(speed > 0.0, Guess(sol.t_evap_sat_c, sol.t_cond_c, 1.0), guess)
        return CompressorRun(
            speed_rpm=speed,
            q_evap_ref_w=sol.q_evap_ref_w,
            p_comp_w=sol.p_comp_w,
            t_evap_sat_c=sol.t_evap_sat_c,
            t_cond_c=sol.t_cond_c,
            mdot_ref_kgps=sol.mdot_ref_kgps,
            mop_active=sol.mop_active,
            iterations=sol.iterations,
            power_limited=limited,
            guess=guess,
            ok=ok,
        )


class PlantEquations:
    """The right-hand side and the RK4 step of the plant, evaluated by ``ops`` with the refrigerant loop ``cycle``.

    Args:
        params: validated :class:`PlantParams`.
        cycle: :class:`NewtonCycle` (numeric, exact) or a smooth cycle table (smooth).
        ops: :data:`~ceco_plant_sim.plant_ops.NUMERIC`, an ``ExactOps`` or a ``SmoothOps``.
    """

    def __init__(self, params: PlantParams, cycle, ops=NUMERIC) -> None:
        self.params = params
        self.cycle = cycle
        self.ops = ops
        self.m_air_kg = params.rho_air_kgm3 * params.cabin_volume_m3
        """Dry-air mass of the cabin [kg]."""
        self.co2_gen_kgps = co2_generation_kgps(params.occ_met, params.occ_body_area_m2, params.occ_rq)
        """CO2 exhaled per occupant [kg/s] (``ceco_core.air_quality.co2_generation_kgps``)."""
        self.co2_amb_kgkg = co2_kgkg_from_ppm(params.co2_amb_ppm)
        """Ambient CO2 [kg CO2/kg dry air]."""

    def substeps(self, dt_s: float) -> tuple[int, float]:
        """(number, length [s]) of the equal RK4 sub-steps of a step ``dt_s``: ceil(dt_s / substep_s)."""
        n_sub = max(1, math.ceil(dt_s / self.params.substep_s - 1e-9))
        return n_sub, dt_s / n_sub

    def rhs(self, x: State, u: Input, p_bl, env: Env, guess: Guess):
        """Derivatives, flows and algebraic variables at one instant.

        ``p_bl`` is the blower power [W] (:func:`blower_power_w` of ``u``, computed once per step).
        Returns (dx :class:`State` [unit/s], :class:`Flows`, :class:`Alg`, the next :class:`Guess`, ok).
        """
        o = self.ops
        p = self.params
        t_cab, t_int, t_sh, t_gl = x.t_cab_c, x.t_int_c, x.t_shell_c, x.t_glass_c
        t_ev, t_du, w_cab, pi_i = x.t_evap_c, x.t_duct_c, x.w_cab_kgkg, x.comp_pi_integral_rpm
        mdot, t_sp = u.mdot_bl_kgps, u.t_evap_sp_c
        t_amb, solar, speed, rh_amb = env.t_amb_c, env.solar_wm2, env.speed_mps, env.rh
        cp_a = p.cp_air_jpkgk
        wsat = saturation_vapour_pressure_pa
        patm = p.p_atm_pa

        # ambient humidity ratio
        pw_amb = rh_amb * o.scalar(wsat(t_amb))
        w_amb = humidity_ratio_from_vapour_pressure(pw_amb, patm)

        # --- the fresh/recirculation door: rate-limited servo, |dr/dt| <= 1 / door_travel_s
        r = x.recirc_share  # the door's actual position mixes the air
        sd_door = o.scaled("door")
        v_door = 1.0 / p.door_travel_s
        d_r = sd_door.fmin(sd_door.fmax((u.recirc_share - r) / p.door_tau_s, -v_door), v_door)

        # --- air loop: mixing box -> blower -> evaporator -> ducts -> vents
        t_mix = r * t_cab + (1.0 - r) * t_amb
        w_mix = r * w_cab + (1.0 - r) * w_amb
        cp_m = cp_a + w_mix * p.cp_vap_jpkgk
        c_air = mdot * cp_m
        rr = mdot / p.mdot_bl_ref_kgps
        t_in = t_mix + p_bl / c_air  # blow-through module: all blower power ends as heat in the air
        ua_air = p.ua_evap_air_ref_wpk * rr**p.ua_evap_air_exp
        bf = o.exp(-ua_air / c_air)  # bypass factor = 1 - effectiveness
        t_out = t_ev + bf * (t_in - t_ev)
        pws_w = o.scalar(wsat(t_ev))
        w_sw = humidity_ratio_from_vapour_pressure(pws_w, patm)
        w_out = coil_outlet_humidity_ratio(w_mix, w_sw, bf, o.scaled("water").fmax)  # condensation below the dew point
        q_sens = c_air * (t_in - t_out)
        q_lat = mdot * (w_mix - w_out) * p.h_fg_jpkg
        # HVAC case and ducts: the supply air exchanges with their wall, which exchanges with the panel
        ua_da = p.ua_duct_air_ref_wpk * rr**p.ua_evap_air_exp
        t_vent = t_out + (t_du - t_out) * (1.0 - o.exp(-ua_da / c_air))
        q_duct = c_air * (t_vent - t_out)  # duct wall -> supply air
        q_duct_int = p.ua_duct_wpk * (t_int - t_du)  # instrument panel (interior mass) -> duct wall

        # --- compressor: A/C ECU PI on the evaporator wall temperature
        err = t_ev - t_sp
        n_cmd = p.comp_kp_rpm_per_k * err + pi_i
        n_max = p.comp_speed_max_rpm
        sn, sd, se = o.scaled("speed"), o.scaled("duty"), o.scaled("err")
        n_run = sn.fmin(sn.fmax(n_cmd, p.comp_speed_min_rpm), n_max)  # speed while running
        duty = sd.fmin(sd.fmax(n_cmd / p.comp_speed_min_rpm, 0.0), 1.0)  # below N_min: cycling at N_min
        epsc = condenser_eps_c_wpk(p, speed, o)
        c = self.cycle.run(o, n_cmd, n_run, duty, t_ev, t_amb, epsc, guess)
        saturated_high = o.logic_or(sn.ge(n_cmd, n_max), c.power_limited)
        frozen = o.logic_or(  # conditional integration (anti-windup)
            o.logic_and(saturated_high, se.gt(err, 0.0)),
            o.logic_and(sn.le(n_cmd, 0.0), se.lt(err, 0.0)),
        )
        dpi = o.where(frozen, 0.0, p.comp_ki_rpm_per_ks * err)
        q_ref = duty * c.q_evap_ref_w
        p_comp = duty * c.p_comp_w
        p_fan = duty * p.p_cond_fan_w

        # --- cabin network
        h_in = p.h_in_natural_wm2k + (p.h_in_forced_wm2k - p.h_in_natural_wm2k) * rr**0.8
        h_out = p.h_out_natural_wm2k + p.h_out_speed_coef * speed**0.8
        m_inf = leakage_kgps(p.infiltration_0_kgps, p.infiltration_per_mps_kgps, speed)
        g_int = h_in * p.a_int_m2
        g_sh_in = p.u_shell_in_wm2k * p.a_shell_m2
        g_gl_in = h_in * p.a_glass_m2
        q_int_cab = g_int * (t_int - t_cab)
        q_sh_cab = g_sh_in * (t_sh - t_cab)
        q_gl_cab = g_gl_in * (t_gl - t_cab)
        q_rad_sh = p.g_rad_int_shell_wpk * (t_int - t_sh)
        q_rad_gl = p.g_rad_int_glass_wpk * (t_int - t_gl)
        n_occ = p.n_occupants
        cp_cab = cp_a + w_cab * p.cp_vap_jpkgk
        d_cab = (
            mdot * cp_cab * (t_vent - t_cab)
            + m_inf * cp_cab * (t_amb - t_cab)
            + q_int_cab
            + q_sh_cab
            + q_gl_cab
            + n_occ * p.occ_sensible_w
        ) / (self.m_air_kg * cp_cab)
        # water balance of the cabin air [kg/s]: in with the fresh share of the supply, the leakage and
        # the occupants; out with the exfiltrated air (both leave at the cabin state); the condensate
        # leaves the supply air on the coil. (Identical to mdot (W_out - W_cab) + mdot_inf (W_amb - W_cab) + ...)
        fresh = (1.0 - r) * mdot + m_inf
        water_in, water_out, condensate = cabin_water_flows_kgps(
            w_cab, w_amb, w_mix, w_out, fresh, mdot, n_occ * p.occ_latent_w / p.h_fg_jpkg
        )
        # water beyond saturation at T_cab is fog (condensed in the air); it deposits on the cabin surfaces
        # with tau_fog and leaves the balance with the coil's condensate (0 below saturation); the whole-drive
        # optimum's smooth model leaves the sink out (SmoothOps.fog_deposition)
        if o.fog_deposition:
            fog_out = self.m_air_kg * saturation_excess_kgkg(p, t_cab, w_cab, o) / p.fog_removal_tau_s
            condensate = condensate + fog_out
        d_w = (water_in - water_out - condensate) / self.m_air_kg
        # CO2 balance of the cabin air [kg/s]: in with the fresh share and the leakage at the ambient
        # fraction, out with the exfiltrated air at the cabin's, exhaled by the occupants
        co2 = co2_flows_kgps(x.co2_cab_kgkg, self.co2_amb_kgkg, fresh, n_occ, self.co2_gen_kgps)
        d_co2 = (co2.into - co2.out + co2.generated) / self.m_air_kg
        d_int = (p.tau_glass * p.a_glass_sun_m2 * solar - q_int_cab - q_rad_sh - q_rad_gl - q_duct_int) / p.c_int_jpk
        d_du = (q_duct_int - q_duct) / p.c_duct_jpk
        d_sh = (
            p.alpha_shell * p.a_shell_sun_m2 * solar + h_out * p.a_shell_m2 * (t_amb - t_sh) - q_sh_cab + q_rad_sh
        ) / p.c_shell_jpk
        d_gl = (
            p.alpha_glass * p.a_glass_sun_m2 * solar + h_out * p.a_glass_m2 * (t_amb - t_gl) - q_gl_cab + q_rad_gl
        ) / p.c_glass_jpk
        d_ev = (q_sens + q_lat - q_ref) / p.c_evap_jpk

        dx = State(
            t_cab_c=d_cab,
            t_int_c=d_int,
            t_shell_c=d_sh,
            t_glass_c=d_gl,
            t_evap_c=d_ev,
            t_duct_c=d_du,
            w_cab_kgkg=d_w,
            comp_pi_integral_rpm=dpi,
            recirc_share=d_r,
            co2_cab_kgkg=d_co2,
        )
        flows = Flows(
            p_comp,
            p_fan,
            q_sens + q_lat,
            q_lat,
            q_ref,
            water_in,
            water_out,
            condensate,
            co2.into,
            co2.out,
            co2.generated,
        )
        alg = Alg(
            t_vent_c=t_vent,
            t_evap_out_c=t_out,
            t_evap_sat_c=c.t_evap_sat_c,
            t_cond_c=c.t_cond_c,
            comp_speed_rpm=c.speed_rpm,
            comp_duty=duty,
            capacity_limited=saturated_high,
            mop_active=c.mop_active,
            mdot_ref_kgps=duty * c.mdot_ref_kgps,
            cycle_iterations=c.iterations,
        )
        return dx, flows, alg, c.guess, c.ok

    def step(self, x: State, u: Input, env: Env, dt_s: float, guess: Guess):
        """Advance ``dt_s`` [s] by classical RK4 sub-steps (:meth:`substeps`) with ``u`` and ``env`` held.

        Returns (state at the end, :class:`Flows` integrated over the step with the RK4 weights [J or kg],
        the warm start after the last stage, ok).
        """
        o = self.ops
        n_sub, h = self.substeps(dt_s)
        p_bl = blower_power_w(self.params, u.mdot_bl_kgps)
        acc = (0.0,) * len(FLOW_NAMES)
        ok = True
        for _ in range(n_sub):
            k1, a1, _, guess, ok1 = self.rhs(x, u, p_bl, env, guess)
            x2 = State._make([xi + 0.5 * h * ki for xi, ki in zip(x, k1)])
            k2, a2, _, guess, ok2 = self.rhs(x2, u, p_bl, env, guess)
            x3 = State._make([xi + 0.5 * h * ki for xi, ki in zip(x, k2)])
            k3, a3, _, guess, ok3 = self.rhs(x3, u, p_bl, env, guess)
            x4 = State._make([xi + h * ki for xi, ki in zip(x, k3)])
            k4, a4, _, guess, ok4 = self.rhs(x4, u, p_bl, env, guess)
            x = State._make(
                [xi + h / 6.0 * (q1 + 2.0 * q2 + 2.0 * q3 + q4) for xi, q1, q2, q3, q4 in zip(x, k1, k2, k3, k4)]
            )
            acc = tuple(s + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4) for s, b1, b2, b3, b4 in zip(acc, a1, a2, a3, a4))
            ok = o.logic_and(o.logic_and(o.logic_and(o.logic_and(ok, ok1), ok2), ok3), ok4)
        return x, Flows._make(acc), guess, ok

    def outputs(self, x: State, u: Input, env: Env, dt_s: float, acc: Flows, guess: Guess):
        """The plant's report at state ``x`` (the end of a step): ``({PlantOutputs field: value}, ok)``.

        ``acc`` holds the flows integrated over the step of ``dt_s`` [s] (:meth:`step`: energies [J],
        water [kg]); ``dt_s = 0`` reports an instant (``acc`` the instantaneous flows, zero energies).
        The algebraic variables are those of :meth:`rhs` at ``x`` with the warm start ``guess``; ``ok``
        is that cycle solve's flag. Temperatures and states at ``x``, powers step means, ``cop`` the
        mean refrigerant capacity over the mean compressor power (0 with the compressor off).
        """
        o = self.ops
        p_bl = blower_power_w(self.params, u.mdot_bl_kgps)
        _, _, alg, _, ok = self.rhs(x, u, p_bl, env, guess)
        if dt_s > 0.0:
            mean = (
                acc.p_comp_w / dt_s,
                acc.p_cond_fan_w / dt_s,
                acc.q_evap_w / dt_s,
                acc.q_latent_w / dt_s,
                acc.q_evap_ref_w / dt_s,
            )
            energies = (acc.p_comp_w, p_bl * dt_s)
            water = (acc.mdot_water_in_kgps, acc.mdot_water_out_kgps, acc.mdot_condensate_kgps)
            co2 = (acc.mdot_co2_in_kgps, acc.mdot_co2_out_kgps, acc.mdot_co2_gen_kgps)
        else:
            mean = tuple(acc[:5])
            energies = (0.0, 0.0)
            water = (0.0, 0.0, 0.0)
            co2 = (0.0, 0.0, 0.0)
        out = {
            "t_cab_c": x.t_cab_c,
            "t_int_c": x.t_int_c,
            "t_shell_c": x.t_shell_c,
            "t_glass_c": x.t_glass_c,
            "t_evap_c": x.t_evap_c,
            "t_duct_c": x.t_duct_c,
            "t_vent_c": alg.t_vent_c,
            "t_evap_out_c": alg.t_evap_out_c,
            "t_evap_sat_c": alg.t_evap_sat_c,
            "t_cond_c": alg.t_cond_c,
            "rh_cab": cabin_relative_humidity(self.params, x.t_cab_c, x.w_cab_kgkg, o),
            "w_cab_kgkg": x.w_cab_kgkg,
            "p_comp_w": mean[0],
            "p_blower_w": p_bl,
            "p_cond_fan_w": mean[1],
            "e_comp_j": energies[0],
            "e_blower_j": energies[1],
            "q_evap_w": mean[2],
            "q_latent_w": mean[3],
            "q_evap_ref_w": mean[4],
            "cop": o.cond(mean[0] > 0.0, lambda: mean[4] / mean[0], lambda: 0.0),
            "comp_speed_rpm": alg.comp_speed_rpm,
            "comp_duty": alg.comp_duty,
            "capacity_limited": alg.capacity_limited,
            "mop_active": alg.mop_active,
            "mdot_ref_kgps": alg.mdot_ref_kgps,
            "cycle_iterations": alg.cycle_iterations,
            "m_water_in_kg": water[0],
            "m_water_out_kg": water[1],
            "m_condensate_kg": water[2],
            "recirc_share": x.recirc_share,
            "co2_cab_ppm": co2_ppm_from_kgkg(x.co2_cab_kgkg),
            "m_co2_in_kg": co2[0],
            "m_co2_out_kg": co2[1],
            "m_co2_gen_kg": co2[2],
        }
        return out, ok
