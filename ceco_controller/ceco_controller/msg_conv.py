"""Messages <-> controller core data (Previews, AcInput, Diagnostics).

The one adapter between ceco_msgs and the controller core: checks each
incoming message (finite numbers, equal-length arrays of the expected length,
matching time grids) and returns a clear reason when it rejects one.
No node logic; imports message types but not rclpy's Node.
"""
from __future__ import annotations

import math

import numpy as np

from ceco_controller.interface import Diagnostics
from ceco_msgs.msg import AcCommand, CabinState, ControllerDiagnostics, TrafficPreview, WeatherPreview
from ceco_v2x_preview.preview import Previews

STATE_FIELDS = ('scenario_time_s', 't_cab_c', 't_int_c', 't_shell_c', 't_evap_c', 't_vent_c',
                't_amb_c', 'solar_wm2', 'rh', 'speed_mps', 'mdot_bl_kgps', 't_evap_sp_c')


def stamp_s(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def check_state(msg: CabinState) -> str | None:
    """None if usable, else the reason (names the field and value)."""
    for name in STATE_FIELDS:
        v = getattr(msg, name)
        if not math.isfinite(v):
            return f'{name}={v!r} is not finite'
    if msg.scenario_time_s < 0.0:
        return f'scenario_time_s={msg.scenario_time_s!r} is negative'
    return None


def check_previews(w: WeatherPreview, s: TrafficPreview, n_expected: int, step_s: float) -> str | None:
    """None if the two previews are usable together, else the reason."""
    for name, msg in (('weather', w), ('traffic', s)):
        if not (math.isfinite(msg.step_s) and abs(msg.step_s - step_s) <= 1e-9 * step_s):
            return f'{name} preview step_s={msg.step_s!r} differs from the control period {step_s}'
    arrays = {'t_amb_c': w.t_amb_c, 'solar_wm2': w.solar_wm2, 'rh': w.rh, 'weather.valid': w.valid,
              'speed_mps': s.speed_mps, 'traffic.valid': s.valid}
    for name, a in arrays.items():
        if len(a) != n_expected:
            return f'preview array {name} has {len(a)} values, expected {n_expected} (Np + 1)'
    if stamp_s(w.start) != stamp_s(s.start):
        return f'weather and traffic previews start at different times ({stamp_s(w.start)} vs {stamp_s(s.start)})'
    valid = np.asarray(w.valid, dtype=bool) & np.asarray(s.valid, dtype=bool)
    for name in ('t_amb_c', 'solar_wm2', 'rh', 'speed_mps'):
        a = np.asarray(arrays[name], dtype=float)
        if np.any(np.isinf(a)):
            return f'preview array {name} holds an infinite value'
        if np.any(np.isnan(a[valid])):
            return f'preview array {name} holds NaN where marked valid'
    return None


def align_previews(w: WeatherPreview, s: TrafficPreview, t_s: float, step_s: float):
    """Previews re-gridded to start at t_s (real-time mode, where a preview may
    be older than the state): shifted by the whole number of steps it is late,
    the tail it does not cover marked invalid (NaN). Returns (w, s), or None
    when the preview starts after t_s or does not reach it."""
    lag = (t_s - stamp_s(w.start)) / step_s
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
    w2 = WeatherPreview(header=w.header, start=w.start, step_s=w.step_s, step_index=w.step_index,
                        t_amb_c=shift(w.t_amb_c, math.nan), solar_wm2=shift(w.solar_wm2, math.nan),
                        rh=shift(w.rh, math.nan), valid=shift(w.valid, False), age_s=w.age_s + j * step_s,
                        quality=w.quality)
    s2 = TrafficPreview(header=s.header, start=s.start, step_s=s.step_s, step_index=s.step_index,
                        speed_mps=shift(s.speed_mps, math.nan), valid=shift(s.valid, False),
                        age_s=s.age_s + j * step_s, quality=s.quality)
    return w2, s2


def previews(w: WeatherPreview, s: TrafficPreview, t_s: float, step_s: float) -> Previews:
    """Checked (and, in real-time mode, aligned) preview messages -> the core's Previews on the grid
    t_s + i * step_s (the inverse of ``preview_node.previews_to_msgs``); a sample is valid when it
    is valid in both messages."""
    age_s = float(w.age_s) if w.age_s >= 0.0 else math.inf
    return Previews(t0_s=t_s, step_s=step_s, t_amb_c=np.asarray(w.t_amb_c, dtype=float),
                    solar_wm2=np.asarray(w.solar_wm2, dtype=float),
                    speed_mps=np.asarray(s.speed_mps, dtype=float), rh=np.asarray(w.rh, dtype=float),
                    valid=np.asarray(w.valid, dtype=bool) & np.asarray(s.valid, dtype=bool),
                    age_s=age_s, issued_s=t_s - age_s if math.isfinite(age_s) else math.nan)


def command_msg(cmd, k: int, stamp, control_period_s: float, strategy: str, fallback: bool) -> AcCommand:
    m = AcCommand()
    m.header.stamp = stamp
    m.step_index = int(k)
    m.control_period_s = float(control_period_s)
    m.blower_flow_kgps = float(cmd.mdot_bl_kgps)
    m.evap_setpoint_c = float(cmd.t_evap_sp_c)
    m.strategy = strategy
    m.fallback = bool(fallback)
    return m


def _f(x) -> float:
    return math.nan if x is None else float(x)


def diagnostics_msg(d: Diagnostics, stamp, strategy: str, control_period_s: float) -> ControllerDiagnostics:
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
