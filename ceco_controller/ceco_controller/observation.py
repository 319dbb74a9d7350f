"""The controller's :class:`~ceco_core.contracts.Observation` at a control step.

Built once for the in-process simulator (``closed_loop.simulate``: from the
plant and ``make_previews``) and for ``mpc_node`` (from the checked CabinState and
preview messages, via ``msg_conv``), so a DDS run equals the simulator bit for bit.

Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

from collections.abc import Mapping

from ceco_core.contracts import Observation, Previews
from ceco_v2x_preview.scenario import Scenario

__all__ = ["observation"]


def observation(k: int, t_s: float, meas: Mapping, env, u_prev, previews: Previews, scenario: Scenario) -> Observation:
    """Observation for control step ``k`` at ``t_s`` [s].

    Args:
        k: control step index [-].
        t_s: time of the measurements (k * Ts) [s].
        meas: measurements at ``t_s``: ``t_cab_c, t_int_c, t_shell_c, t_evap_c, t_vent_c`` [degC]
            (``ceco_plant_sim.scenario_plant.MEASUREMENTS``).
        env: the measured environment at ``t_s`` (attributes ``t_amb_c`` [degC], ``solar_wm2``
            [W/m2], ``speed_mps`` [m/s]).
        u_prev: the command held before ``t_s`` (attributes ``mdot_bl_kgps`` [kg/s],
            ``t_evap_sp_c`` [degC]; at key-on ``ceco_plant_sim.scenario_plant.KEY_ON_COMMAND``).
        previews: the V2X previews on the grid ``previews.t_s`` = t_s + i * Ts, i = 0..Np.
        scenario: gives the occupant (met, clo) and the PMV comfort bounds, evaluated on the
            preview grid.
    """
    lb, ub = scenario.pmv_bounds(previews.t_s)
    occ = scenario.occupant
    return Observation(
        k=k,
        t_s=t_s,
        t_cab_c=meas["t_cab_c"],
        t_int_c=meas["t_int_c"],
        t_shell_c=meas["t_shell_c"],
        t_evap_c=meas["t_evap_c"],
        t_vent_c=meas["t_vent_c"],
        t_amb_c=env.t_amb_c,
        solar_wm2=env.solar_wm2,
        speed_mps=env.speed_mps,
        mdot_bl_prev_kgps=u_prev.mdot_bl_kgps,
        t_evap_sp_prev_c=u_prev.t_evap_sp_c,
        preview_t_amb_c=previews.t_amb_c,
        preview_solar_wm2=previews.solar_wm2,
        preview_speed_mps=previews.speed_mps,
        preview_valid=previews.valid,
        pmv_lb=lb,
        pmv_ub=ub,
        met=occ.met,
        clo=occ.clo,
        t_glass_c=meas.get("t_glass_c", float("nan")),
        rh_cab=meas.get("rh_cab", float("nan")),
    )
