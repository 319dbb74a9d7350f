"""Plausible test inputs: a hot-day controller Observation, and the fields of a key-on CabinState message."""

from __future__ import annotations

import numpy as np

from ceco_core.contracts import Observation


def observation(n1: int, k: int = 0, *, t_cab: float = 28.0, speed: float = 10.0, valid=None, **fields) -> Observation:
    """Step ``k`` at t = 5 k s with ``n1`` preview points; ``fields`` override any Observation field."""
    d = dict(
        k=k,
        t_s=5.0 * k,
        t_cab_c=t_cab,
        t_int_c=40.0,
        t_shell_c=38.0,
        t_evap_c=6.0,
        t_vent_c=9.0,
        t_amb_c=35.0,
        solar_wm2=800.0,
        speed_mps=speed,
        mdot_bl_prev_kgps=0.1,
        t_evap_sp_prev_c=5.0,
        preview_t_amb_c=np.full(n1, 35.0),
        preview_solar_wm2=np.full(n1, 800.0),
        preview_speed_mps=np.full(n1, speed),
        preview_valid=np.ones(n1, bool) if valid is None else valid,
        pmv_lb=np.full(n1, -0.5),
        pmv_ub=np.full(n1, 0.5),
    )
    d.update(fields)
    return Observation(**d)


KEY_ON_STATE = dict(
    t_cab_c=45.0,
    t_int_c=50.0,
    t_shell_c=55.0,
    t_glass_c=55.0,
    t_evap_c=45.0,
    t_vent_c=45.0,
    rh_cab=0.2,
    t_amb_c=35.0,
    solar_wm2=800.0,
    rh=0.4,
    speed_mps=10.0,
    mdot_bl_kgps=0.17,
    t_evap_sp_c=3.0,
    co2_cab_ppm=425.0,
    co2_sensor_ppm=431.0,
    recirc_share=0.8,
    recirc_share_cmd=0.8,
)
"""The measured fields of a plausible CabinState at key-on on a hot day (and the key-on command)."""
