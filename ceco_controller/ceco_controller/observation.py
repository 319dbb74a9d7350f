"""The controller's :class:`~ceco_core.contracts.Observation` at a control step.

:func:`observation` builds it once for the in-process simulator (``closed_loop.simulate``: from
the plant and ``make_previews``) and for ``mpc_node`` (from the checked CabinState and preview
messages, via ``ceco_controller.step_adapter``), so a DDS run equals the simulator bit for bit.
:func:`fill_previews` turns its previews into the NMPC's exogenous series on the horizon grid;
:func:`nominal_observation` is a plausible one for warm-up solves.

Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ceco_core.contracts import Observation, Previews
from ceco_v2x_preview.scenario import Scenario

__all__ = ["fill_previews", "nominal_observation", "observation"]


def observation(k: int, t_s: float, meas: Mapping, env, u_prev, previews: Previews, scenario: Scenario) -> Observation:
    """Observation for control step ``k`` at ``t_s`` [s].

    Args:
        k: control step index [-].
        t_s: time of the measurements (k * Ts) [s].
        meas: measurements at ``t_s``: ``t_cab_c, t_int_c, t_shell_c, t_evap_c, t_vent_c`` [degC]
            (``ceco_plant_sim.scenario_plant.MEASUREMENTS``).
        env: the measured environment at ``t_s`` (attributes ``t_amb_c`` [degC], ``solar_wm2``
            [W/m2], ``speed_mps`` [m/s], ``rh`` [0..1] the ambient relative humidity, NaN when not
            known: the simulator's ``Environment`` and mpc_node's CabinState both carry it).
        u_prev: the command held before ``t_s`` (attributes ``mdot_bl_kgps`` [kg/s],
            ``t_evap_sp_c`` [degC]; at key-on ``ceco_plant_sim.scenario_plant.KEY_ON_COMMAND``).
        previews: the V2X previews on the grid ``previews.t_s`` = t_s + i * Ts, i = 0..Np.
        scenario: gives the occupant (met, clo) and the PMV comfort bounds, evaluated on the
            preview grid, the number of occupants and the air-quality limits.
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
        rh_amb=float(env.rh),
        co2_cab_ppm=meas.get("co2_cab_ppm", float("nan")),
        co2_sensor_ppm=meas.get("co2_sensor_ppm", float("nan")),
        recirc_share=meas.get("recirc_share", float("nan")),
        n_occupants=int(scenario.occupants),
        co2_limit_ppm=float(scenario.air_quality.co2_limit_ppm),
        fog_margin_min_k=float(scenario.air_quality.fog_margin_min_k),
    )


def fill_previews(
    obs: Observation, n1: int, use_speed_preview: bool, valid: np.ndarray | None = None
) -> tuple[dict, int]:
    """Exogenous series on the N + 1 grid and the number of leading trusted preview points.

    The previews' leading trusted run (``valid``, default ``obs.preview_valid``, and finite), the
    last trusted value held beyond it, the measured current value where nothing is trusted.
    Returns ``(series, trusted)`` with series ``t_amb`` [degC], ``solar`` [W/m2] (>= 0),
    ``speed`` [m/s] (>= 0).
    """
    if obs.n_preview != n1:
        raise ValueError(f"Observation previews have {obs.n_preview} points; this controller needs Np+1 = {n1}")
    series = {
        "t_amb": (obs.preview_t_amb_c, obs.t_amb_c),
        "solar": (obs.preview_solar_wm2, obs.solar_wm2),
        "speed": (obs.preview_speed_mps, obs.speed_mps),
    }
    ok = np.asarray(obs.preview_valid if valid is None else valid, bool).copy()
    for arr, _ in series.values():
        ok &= np.isfinite(arr)
    trusted = int(np.argmin(ok)) if not ok.all() else n1
    out = {}
    for key, (arr, now) in series.items():
        a = np.empty(n1)
        if trusted > 0:
            a[:trusted] = arr[:trusted]
            a[trusted:] = arr[trusted - 1]
        else:
            a[:] = now
        out[key] = a
    if not use_speed_preview:
        out["speed"] = np.full(n1, float(obs.speed_mps))
    out["speed"] = np.maximum(out["speed"], 0.0)
    out["solar"] = np.maximum(out["solar"], 0.0)
    return out, trusted


def nominal_observation(n1: int, k: int = 0) -> Observation:
    """A plausible mid-range observation (warm cabin, sun, moving): for :meth:`NmpcController.warm_up`."""

    def full(v):
        return np.full(n1, v)

    return Observation(
        k=k,
        t_s=0.0,
        t_cab_c=27.0,
        t_int_c=35.0,
        t_shell_c=33.0,
        t_evap_c=6.0,
        t_vent_c=9.0,
        t_amb_c=32.0,
        solar_wm2=700.0,
        speed_mps=15.0,
        mdot_bl_prev_kgps=0.1,
        t_evap_sp_prev_c=6.0,
        preview_t_amb_c=full(32.0),
        preview_solar_wm2=full(700.0),
        preview_speed_mps=full(15.0),
        preview_valid=np.ones(n1, bool),
        pmv_lb=full(-0.5),
        pmv_ub=full(0.5),
    )
