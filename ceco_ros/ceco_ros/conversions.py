"""ceco_msgs messages <-> the pure core's data, both directions of each, in one place.

| message            | from the core                 | to the core                             |
|--------------------|-------------------------------|-----------------------------------------|
| CabinState         | :func:`state_msg`             | :func:`state_measurements`              |
| AcCommand          | :func:`command_msg`           | :func:`command_input`                   |
| Weather/TrafficPreview | :func:`previews_to_msgs`, :func:`empty_previews` | :func:`previews`, :func:`align_previews` |
| AcPower            | :func:`power_msg`             |                                         |
| Comfort            | :func:`comfort_msg`           |                                         |
| ControllerDiagnostics | :func:`diagnostics_msg`    |                                         |
| builtin_interfaces/Time | :func:`stamp_from_s`     | :func:`s_from_stamp`                    |

Incoming messages are checked field by field first (:mod:`ceco_ros.checks`);
conversions into the core raise ValueError. No node logic: imports message
types, not rclpy's Node.
"""

from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time

from ceco_core.contracts import MEASUREMENTS, RECIRC_NOT_COMMANDED_WIRE, AcInput, Diagnostics, Previews
from ceco_core.units import s_from_stamp, sec_nanosec_from_s
from ceco_msgs.msg import AcCommand, AcPower, CabinState, Comfort, ControllerDiagnostics, TrafficPreview, WeatherPreview

__all__ = [
    'stamp_from_s',
    's_from_stamp',
    'state_msg',
    'state_measurements',
    'command_msg',
    'command_input',
    'previews_to_msgs',
    'empty_previews',
    'previews',
    'align_previews',
    'power_msg',
    'comfort_msg',
    'diagnostics_msg',
]


# --- time stamps ------------------------------------------------------------------------------
def stamp_from_s(t_s: float) -> Time:
    """builtin_interfaces/Time from seconds, exact to the nanosecond; ValueError outside [0, 2^31 - 1] s."""
    sec, nanosec = sec_nanosec_from_s(t_s)
    return Time(sec=sec, nanosec=nanosec)


# --- CabinState -------------------------------------------------------------------------------
def state_msg(
    n: int, t_s: float, stamp, meas: dict, env, u_prev: AcInput, fallback: bool, recirc_share_cmd: float = math.nan
) -> CabinState:
    """The plant's measurements at step ``n`` (t_s [s]), the environment and the previous command.

    ``recirc_share_cmd`` is the door command the plant applied over the previous period [0..1] (its default share
    where the controller left the door alone; NaN: unknown).
    """
    m = CabinState()
    m.header.stamp = stamp
    m.step_index = int(n)
    m.scenario_time_s = float(t_s)
    for f in MEASUREMENTS:
        setattr(m, f, float(meas[f]))
    m.t_amb_c = float(env.t_amb_c)
    m.solar_wm2 = float(env.solar_wm2)
    m.rh = float(env.rh)
    m.speed_mps = float(env.speed_mps)
    m.mdot_bl_kgps = float(u_prev.mdot_bl_kgps)
    m.t_evap_sp_c = float(u_prev.t_evap_sp_c)
    m.fallback = bool(fallback)
    m.recirc_share_cmd = float(recirc_share_cmd)
    return m


def state_measurements(msg: CabinState) -> dict:
    """The measurement mapping (keys :data:`ceco_core.contracts.MEASUREMENTS`) a CabinState carries."""
    return {f: float(getattr(msg, f)) for f in MEASUREMENTS}


# --- AcCommand --------------------------------------------------------------------------------
def command_msg(
    cmd, k: int, stamp, control_period_s: float, strategy: str, fallback: bool, epoch: int = 0, sequence: int = 0
) -> AcCommand:
    """An AcCommand for control step ``k`` from an :class:`AcInput`.

    ``epoch`` (0: not set) and ``sequence`` identify the sending controller's activation and the command's number.
    """
    m = AcCommand()
    m.epoch = int(epoch)
    m.sequence = int(sequence)
    m.header.stamp = stamp
    m.step_index = int(k)
    m.control_period_s = float(control_period_s)
    m.blower_flow_kgps = float(cmd.mdot_bl_kgps)
    m.evap_setpoint_c = float(cmd.t_evap_sp_c)
    r = float(getattr(cmd, 'recirc_share', math.nan))
    m.recirc_share = RECIRC_NOT_COMMANDED_WIRE if math.isnan(r) else r
    m.strategy = strategy
    m.fallback = bool(fallback)
    return m


def command_input(msg: AcCommand) -> AcInput:
    """AcCommand -> AcInput (the inverse of :func:`command_msg`; the door's -1 is "not commanded", NaN).

    Check the message first with :func:`ceco_ros.checks.check_command` (AcInput raises
    ValueError outside the actuator bounds).
    """
    r = math.nan if msg.recirc_share == RECIRC_NOT_COMMANDED_WIRE else msg.recirc_share
    return AcInput(mdot_bl_kgps=msg.blower_flow_kgps, t_evap_sp_c=msg.evap_setpoint_c, recirc_share=r)


# --- previews ---------------------------------------------------------------------------------
def previews_to_msgs(p: Previews, k: int, stamp, quality_text: str) -> tuple[WeatherPreview, TrafficPreview]:
    """Core Previews -> (WeatherPreview, TrafficPreview) messages on the same grid, tagged with step ``k``."""
    start = stamp_from_s(p.t0_s)
    age_s = float(p.age_s) if math.isfinite(p.age_s) else -1.0
    w = WeatherPreview()
    w.header.stamp = stamp
    w.start = start
    w.step_s = float(p.step_s)
    w.step_index = int(k)
    w.t_amb_c = [float(x) for x in p.t_amb_c]
    w.solar_wm2 = [float(x) for x in p.solar_wm2]
    w.rh = [float(x) for x in p.rh]
    w.valid = [bool(x) for x in p.valid]
    w.age_s = age_s
    w.quality = quality_text
    s = TrafficPreview()
    s.header.stamp = stamp
    s.start = start
    s.step_s = float(p.step_s)
    s.step_index = int(k)
    s.speed_mps = [float(x) for x in p.speed_mps]
    s.valid = [bool(x) for x in p.valid]
    s.age_s = age_s
    s.quality = quality_text
    return w, s


def empty_previews(n: int, step_s: float) -> tuple[WeatherPreview, TrafficPreview]:
    """Previews of ``n`` samples that are all invalid (NaN): what a controller solves with when none came."""
    nan = [math.nan] * n
    w = WeatherPreview(step_s=step_s, t_amb_c=nan, solar_wm2=nan, rh=nan, valid=[False] * n)
    s = TrafficPreview(step_s=step_s, speed_mps=nan, valid=[False] * n)
    return w, s


def align_previews(w: WeatherPreview, s: TrafficPreview, t_s: float, step_s: float):
    """Previews re-gridded to start at t_s.

    Real-time mode, where a preview may be older than the state: shifted by the whole number of steps it is late,
    the tail it does not cover marked invalid (NaN). Returns (w, s), or None
    when the preview starts after t_s or does not reach it.
    """
    lag = (t_s - s_from_stamp(w.start)) / step_s
    j = int(round(lag))
    n = len(w.valid)
    if abs(lag - j) > 1e-6 and lag > 0:
        j = int(math.floor(lag))
    if j < 0 or j >= n:
        return None
    if j == 0:
        return w, s

    def shift(a, fill):
        a = list(a)
        return a[j:] + [fill] * j

    w2 = WeatherPreview(
        header=w.header,
        start=w.start,
        step_s=w.step_s,
        step_index=w.step_index,
        t_amb_c=shift(w.t_amb_c, math.nan),
        solar_wm2=shift(w.solar_wm2, math.nan),
        rh=shift(w.rh, math.nan),
        valid=shift(w.valid, False),
        age_s=w.age_s + j * step_s,
        quality=w.quality,
    )
    s2 = TrafficPreview(
        header=s.header,
        start=s.start,
        step_s=s.step_s,
        step_index=s.step_index,
        speed_mps=shift(s.speed_mps, math.nan),
        valid=shift(s.valid, False),
        age_s=s.age_s + j * step_s,
        quality=s.quality,
    )
    return w2, s2


def previews(w: WeatherPreview, s: TrafficPreview, t_s: float, step_s: float) -> Previews:
    """Checked (and, in real time, aligned) preview messages -> the core's Previews.

    The grid is t_s + i * step_s (the inverse of :func:`previews_to_msgs`); a sample is valid
    when it is valid in both messages.
    """
    age_s = float(w.age_s) if w.age_s >= 0.0 else math.inf
    return Previews(
        t0_s=t_s,
        step_s=step_s,
        t_amb_c=np.asarray(w.t_amb_c, dtype=float),
        solar_wm2=np.asarray(w.solar_wm2, dtype=float),
        speed_mps=np.asarray(s.speed_mps, dtype=float),
        rh=np.asarray(w.rh, dtype=float),
        valid=np.asarray(w.valid, dtype=bool) & np.asarray(s.valid, dtype=bool),
        age_s=age_s,
        issued_s=t_s - age_s if math.isfinite(age_s) else math.nan,
    )


# --- plant outputs ----------------------------------------------------------------------------
def power_msg(
    n: int, stamp, dt_s: float, u: AcInput, out, e_comp_j: float, e_blower_j: float, fallback: bool
) -> AcPower:
    """The A/C powers of plant step ``n`` (step means over dt_s [s]) and the cumulative energies [J]."""
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


COMFORT_SERIES_FIELDS = ("ta_occ_c", "vel_occ_mps", "t_mr_c", "w_rad_wm2", "pa_pa", "t_dew_c", "fog_margin_k", "dr_pct")
"""Comfort message fields copied from ``ceco_core.cabin_comfort.OccupantComfort`` (same names)."""


def comfort_msg(rec, stamp, met: float, clo: float) -> Comfort:
    """The occupant's comfort of one plant step, from its ``ceco_plant_sim.scenario_plant.PlantStepRecord``.

    ``rec`` gives the step index, the scored PMV/PPD and bounds at t_n, the measurements, the command
    held, the environment and the comfort series (``ceco_core.cabin_comfort.OccupantComfort``: the
    occupant-environment, draught and fog fields); ``met`` [met] and ``clo`` [clo] are the occupant's.
    """
    m = Comfort()
    m.header.stamp = stamp
    m.step_index = int(rec.n)
    m.pmv, m.ppd, m.pmv_lb, m.pmv_ub = float(rec.pmv), float(rec.ppd), float(rec.pmv_lb), float(rec.pmv_ub)
    m.t_cab_c = float(rec.meas['t_cab_c'])
    m.t_vent_c = float(rec.meas['t_vent_c'])
    m.t_int_c = float(rec.meas['t_int_c'])
    m.mdot_bl_kgps = float(rec.u.mdot_bl_kgps)
    m.solar_wm2 = float(rec.env.solar_wm2)
    m.met, m.clo = float(met), float(clo)
    series = rec.comfort
    m.iso_valid = bool(series.iso7730_valid) if series is not None else False
    for name in COMFORT_SERIES_FIELDS:
        setattr(m, name, float(getattr(series, name)) if series is not None else math.nan)
    return m


# --- controller diagnostics -------------------------------------------------------------------
def _f(x) -> float:
    return math.nan if x is None else float(x)


def diagnostics_msg(d: Diagnostics, stamp, strategy: str, control_period_s: float) -> ControllerDiagnostics:
    """A controller's :class:`Diagnostics` of one step as a ControllerDiagnostics message."""
    m = ControllerDiagnostics()
    m.header.stamp = stamp
    m.step_index = int(d.k)
    m.strategy = strategy
    m.status = str(d.status)
    m.success = bool(d.success) if d.success is not None else False
    m.iterations = -1 if d.iterations is None else int(d.iterations)
    m.solve_time_s = _f(d.solve_time_ms) * 1e-3
    m.cost_total = _f(d.cost_total)
    m.cost_energy = _f(d.cost_energy)
    m.cost_comfort = _f(d.cost_comfort)
    m.cost_ioch = _f(d.cost_ioch)
    m.prediction_step_s = float(control_period_s)
    m.predicted_pmv = [] if d.pred_pmv is None else [float(x) for x in np.ravel(d.pred_pmv)]
    m.predicted_t_cab_c = [] if d.pred_t_cab_c is None else [float(x) for x in np.ravel(d.pred_t_cab_c)]
    m.eps = [] if d.eps is None else [float(x) for x in np.ravel(d.eps)]
    m.eps_mean = _f(d.eps_mean)
    m.fallback = bool(d.fallback)
    m.fallback_reason = str(d.fallback) + (f': {d.message}' if d.message and d.fallback else '')
    return m
