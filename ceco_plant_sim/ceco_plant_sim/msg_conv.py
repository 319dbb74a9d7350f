"""Plant core data -> ceco_msgs messages (CabinState, AcPower, Comfort) and
AcCommand -> AcInput. The one adapter between the plant core and the wire.
"""
from __future__ import annotations

import math

from ceco_msgs.msg import AcCommand, AcPower, CabinState, Comfort
from ceco_plant_sim.plant import AcInput
from ceco_plant_sim.scenario_plant import MEASUREMENTS as MEAS_FIELDS  # carried by CabinState
from ceco_v2x_preview.ros_common import STRATEGIES as KNOWN_STRATEGIES


def state_msg(n: int, t_s: float, stamp, meas: dict, env, u_prev: AcInput, fallback: bool) -> CabinState:
    m = CabinState()
    m.header.stamp = stamp
    m.step_index = int(n)
    m.scenario_time_s = float(t_s)
    for f in MEAS_FIELDS:
        setattr(m, f, float(meas[f]))
    m.t_amb_c = float(env.t_amb_c)
    m.solar_wm2 = float(env.solar_wm2)
    m.rh = float(env.rh)
    m.speed_mps = float(env.speed_mps)
    m.mdot_bl_kgps = float(u_prev.mdot_bl_kgps)
    m.t_evap_sp_c = float(u_prev.t_evap_sp_c)
    m.fallback = bool(fallback)
    return m


def power_msg(n: int, stamp, dt_s: float, u: AcInput, out, e_comp_j: float, e_blower_j: float,
              fallback: bool) -> AcPower:
    m = AcPower()
    m.header.stamp = stamp
    m.step_index = int(n)
    m.interval_s = float(dt_s)
    m.mdot_bl_kgps = float(u.mdot_bl_kgps)
    m.t_evap_sp_c = float(u.t_evap_sp_c)
    m.p_comp_w = float(out.p_comp_w)
    m.p_blower_w = float(out.p_blower_w)
    m.p_cond_fan_w = float(out.p_cond_fan_w)
    m.q_evap_w = float(out.q_evap_w)
    m.q_latent_w = float(out.q_latent_w)
    m.comp_speed_rpm = float(out.comp_speed_rpm)
    m.capacity_limited = bool(out.capacity_limited)
    m.cop = float(out.cop)
    m.e_comp_j = float(e_comp_j)
    m.e_blower_j = float(e_blower_j)
    m.e_total_j = float(e_comp_j + e_blower_j)
    m.fallback = bool(fallback)
    return m


def comfort_msg(n: int, stamp, pmv: float, ppd: float, lb: float, ub: float, meas: dict, u: AcInput,
                solar_wm2: float, met: float, clo: float, iso_valid: bool) -> Comfort:
    m = Comfort()
    m.header.stamp = stamp
    m.step_index = int(n)
    m.pmv = float(pmv)
    m.ppd = float(ppd)
    m.pmv_lb = float(lb)
    m.pmv_ub = float(ub)
    m.t_cab_c = float(meas['t_cab_c'])
    m.t_vent_c = float(meas['t_vent_c'])
    m.t_int_c = float(meas['t_int_c'])
    m.mdot_bl_kgps = float(u.mdot_bl_kgps)
    m.solar_wm2 = float(solar_wm2)
    m.met = float(met)
    m.clo = float(clo)
    m.iso_valid = bool(iso_valid)
    return m




def command_input(msg: AcCommand) -> AcInput:
    """AcCommand -> AcInput; ValueError naming the field when it is not a
    finite value inside the actuator bounds or the strategy is unknown
    (never clamped)."""
    if msg.strategy not in KNOWN_STRATEGIES:
        raise ValueError(f'unknown strategy {msg.strategy!r} (expected one of {", ".join(KNOWN_STRATEGIES)})')
    for name in ('blower_flow_kgps', 'evap_setpoint_c'):
        v = getattr(msg, name)
        if not math.isfinite(v):
            raise ValueError(f'{name}={v!r} is not finite')
    return AcInput(mdot_bl_kgps=msg.blower_flow_kgps, t_evap_sp_c=msg.evap_setpoint_c)
