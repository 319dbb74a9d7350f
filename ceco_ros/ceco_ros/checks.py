"""Field-by-field checks of every message a ceco node takes in.

Each check returns None when the message is usable, else the reason, naming the field and
its value. The checks read attributes only (no rclpy, no message import), so they run on
ceco_msgs messages and on any object with the same fields (the pure tests use
``types.SimpleNamespace``). What is checked:

* every float field finite and inside a plausible range (:data:`STATE_RANGES`,
  :data:`PREVIEW_RANGES`; the actuator bounds for commands and for the previous command a
  state carries), NaN only where a preview marks a sample invalid, never +-inf;
* stamps well formed (``nanosec`` < 1e9, seconds inside the stamp range), and in time:
  :func:`check_stamp_equals` (lockstep: a stamp is the scenario time it belongs to) and
  :func:`check_stamp_age` (real time: neither older than a limit nor ahead of the clock);
* grid fields: preview ``step_s`` and command ``control_period_s`` equal to the node's Ts,
  preview arrays of length Np + 1, equal between the two previews;
* names: a command's ``strategy`` one of the controller strategies (never the plant's own
  ``plant-fallback``).

The order of positions (step indices, scenario times) is the sequence gate's business
(:mod:`ceco_core.sequencing`), not a field check.
"""

from __future__ import annotations

import math

from ceco_core.contracts import (
    MDOT_BL_MAX_KGPS,
    MDOT_BL_MIN_KGPS,
    RECIRC_NOT_COMMANDED_WIRE,
    RECIRC_SHARE_MAX,
    RECIRC_SHARE_MIN,
    T_EVAP_SP_MAX_C,
    T_EVAP_SP_MIN_C,
    WIRE_STRATEGIES,
)
from ceco_core.units import STAMP_MAX_S, s_from_stamp

__all__ = [
    'STATE_RANGES',
    'PREVIEW_RANGES',
    'COMMAND_RANGES',
    'check_stamp',
    'check_stamp_equals',
    'check_stamp_age',
    'check_state',
    'check_command',
    'check_preview',
    'check_preview_pair',
    'check_grid_step',
]

_TEMPERATURE_C = (-60.0, 150.0)
_RH = (0.0, 1.0)
_BOUND_TOL = 1e-9

STATE_RANGES: dict[str, tuple[float, float]] = {
    'scenario_time_s': (0.0, float(STAMP_MAX_S)),
    't_cab_c': _TEMPERATURE_C,
    't_int_c': _TEMPERATURE_C,
    't_shell_c': _TEMPERATURE_C,
    't_evap_c': _TEMPERATURE_C,
    't_vent_c': _TEMPERATURE_C,
    't_amb_c': (-60.0, 70.0),
    'solar_wm2': (0.0, 2000.0),
    'speed_mps': (0.0, 120.0),
    'mdot_bl_kgps': (MDOT_BL_MIN_KGPS - _BOUND_TOL, MDOT_BL_MAX_KGPS + _BOUND_TOL),
    't_evap_sp_c': (T_EVAP_SP_MIN_C - _BOUND_TOL, T_EVAP_SP_MAX_C + _BOUND_TOL),
    'co2_cab_ppm': (0.0, 50000.0),
    'recirc_share': (0.0, 1.0),
    'recirc_share_cmd': (0.0, 1.0),
}
"""Plausible range of every float field of CabinState [field unit]: cabin CO2 0..50000 ppm, the door's position and
its applied command 0..1, temperatures -60..150 degC
(a vehicle soaked in the sun stays far inside), ambient -60..70 degC, solar
0..2000 W/m2 (above the solar constant), speed 0..120 m/s, the previous command inside the
actuator bounds, scenario time inside the stamp range. The sensors a car may lack: :data:`STATE_OPTIONAL_RANGES`."""

PREVIEW_RANGES: dict[str, tuple[float, float]] = {
    't_amb_c': STATE_RANGES['t_amb_c'],
    'solar_wm2': STATE_RANGES['solar_wm2'],
    'rh': _RH,
    'speed_mps': STATE_RANGES['speed_mps'],
}
"""Plausible range of the preview samples marked valid (the same as the measured values)."""

STATE_OPTIONAL_RANGES: dict[str, tuple[float, float]] = {
    't_glass_c': _TEMPERATURE_C,
    'rh_cab': _RH,
    'rh': _RH,
    'co2_sensor_ppm': (0.0, 50000.0),
}
"""CabinState fields that may be NaN (not measured: a car without a glazing-temperature, cabin-humidity,
ambient-humidity or CO2 sensor, or one that failed), else inside the range. The controllers take NaN there
as not measured (``ceco_core.observation_check``: the fog override off, the PMV's vapour pressure or the
economiser's enthalpy rule without it); +-inf is refused."""

COMMAND_RANGES: dict[str, tuple[float, float]] = {
    'blower_flow_kgps': (MDOT_BL_MIN_KGPS, MDOT_BL_MAX_KGPS),
    'evap_setpoint_c': (T_EVAP_SP_MIN_C, T_EVAP_SP_MAX_C),
}
"""The actuator bounds an AcCommand must respect (never clamped)."""

COMMAND_OPTIONAL_RANGES: dict[str, tuple[float, float]] = {
    'recirc_share': (RECIRC_SHARE_MIN, RECIRC_SHARE_MAX),
}
"""AcCommand fields that may say "not set" (NaN, or the door's -1 :data:`RECIRC_NOT_COMMANDED_WIRE`), else
inside the actuator range (never clamped)."""

PREVIEW_ARRAYS = {'weather': ('t_amb_c', 'solar_wm2', 'rh'), 'traffic': ('speed_mps',)}
"""The sample arrays of each preview message (besides ``valid``)."""


def check_stamp(name: str, stamp) -> str | None:
    """A stamp is well formed: 0 <= nanosec < 1e9 and 0 <= sec <= 2^31 - 1."""
    if not 0 <= stamp.nanosec < 1_000_000_000:
        return f'{name}.nanosec={stamp.nanosec} is not in [0, 1e9)'
    if not 0 <= stamp.sec <= STAMP_MAX_S:
        return f'{name}.sec={stamp.sec} is not in [0, {STAMP_MAX_S}]'
    return None


def check_stamp_equals(name: str, stamp, t_s: float, tol_s: float = 1e-6) -> str | None:
    """Lockstep: the stamp is the scenario time ``t_s`` [s] it belongs to (within ``tol_s``)."""
    s = s_from_stamp(stamp)
    if abs(s - t_s) > tol_s:
        return f'{name}={s:.9g} s does not match the scenario time {t_s:.9g} s'
    return None


def check_stamp_age(name: str, stamp, now_s: float, max_age_s: float, max_ahead_s: float) -> str | None:
    """Real time: the stamp [s] lies in ``[now_s - max_age_s, now_s + max_ahead_s]`` of the node's clock."""
    s = s_from_stamp(stamp)
    if s > now_s + max_ahead_s:
        return f'{name}={s:.9g} s is {s - now_s:.3g} s ahead of the clock (limit {max_ahead_s} s)'
    if s < now_s - max_age_s:
        return f'{name}={s:.9g} s is {now_s - s:.3g} s old (limit {max_age_s} s)'
    return None


def _check_ranges(msg, ranges: dict[str, tuple[float, float]], nan_ok: bool = False) -> str | None:
    for name, (lo, hi) in ranges.items():
        v = getattr(msg, name)
        if nan_ok and math.isnan(v):
            continue
        if not math.isfinite(v):
            return f'{name}={v!r} is not finite' + (' (NaN means: not set)' if nan_ok else '')
        if not lo <= v <= hi:
            return f'{name}={v!r} is outside the plausible range [{lo:.6g}, {hi:.6g}]'
    return None


def check_state(msg) -> str | None:
    """Check a CabinState: header stamp well formed, every float field finite and plausible.

    The ranges are :data:`STATE_RANGES`, including the previous command inside the actuator bounds, and
    :data:`STATE_OPTIONAL_RANGES` (NaN allowed: the sensors a car may not have).
    """
    return (
        check_stamp('header.stamp', msg.header.stamp)
        or _check_ranges(msg, STATE_RANGES)
        or _check_ranges(msg, STATE_OPTIONAL_RANGES, nan_ok=True)
    )


def check_grid_step(name: str, value: float, control_period_s: float) -> str | None:
    """``value`` [s] equals the control period (relative tolerance 1e-9)."""
    if not (math.isfinite(value) and abs(value - control_period_s) <= 1e-9 * control_period_s):
        return f'{name}={value!r} differs from the control period {control_period_s}'
    return None


def check_command(msg, control_period_s: float) -> str | None:
    """Check an AcCommand: strategy, header stamp, Ts, both inputs.

    The strategy is a controller's (WIRE_STRATEGIES: the strategies and 'external'), the stamp
    well formed, Ts equal to the plant's, both inputs finite and inside the actuator bounds
    (:data:`COMMAND_RANGES`), the door's share -1 or NaN (not commanded) or in [0, 1]
    (:data:`COMMAND_OPTIONAL_RANGES`; any other value is refused, never clamped).
    """
    if msg.strategy not in WIRE_STRATEGIES:
        return f'unknown strategy {msg.strategy!r} (expected one of {", ".join(WIRE_STRATEGIES)})'
    return (
        check_stamp('header.stamp', msg.header.stamp)
        or check_grid_step('control_period_s', msg.control_period_s, control_period_s)
        or _check_ranges(msg, COMMAND_RANGES)
        or (
            None
            if msg.recirc_share == RECIRC_NOT_COMMANDED_WIRE
            else _check_ranges(msg, COMMAND_OPTIONAL_RANGES, nan_ok=True)
        )
    )


def check_preview(msg, kind: str, n_expected: int, control_period_s: float) -> str | None:
    """Check a WeatherPreview (``kind`` 'weather') or a TrafficPreview ('traffic') on its own.

    Stamps well formed, ``step_s`` = Ts, every array of length ``n_expected`` (Np + 1),
    ``age_s`` finite and >= 0 (or -1: none received), samples marked valid finite and
    plausible, no infinite sample anywhere.
    """
    why = (
        check_stamp('header.stamp', msg.header.stamp)
        or check_stamp('start', msg.start)
        or check_grid_step('step_s', msg.step_s, control_period_s)
    )
    if why:
        return why
    names = PREVIEW_ARRAYS[kind] + ('valid',)
    for name in names:
        n = len(getattr(msg, name))
        if n != n_expected:
            return f'{name} has {n} values, expected {n_expected} (Np + 1)'
    if not (math.isfinite(msg.age_s) and (msg.age_s >= 0.0 or msg.age_s == -1.0)):
        return f'age_s={msg.age_s!r} is neither >= 0 nor -1 (none received)'
    # element by element in Python: Np + 1 values per array, where numpy's per-call cost (about 1-4 us a call,
    # eight calls an array) made this check a tenth of the control step (docs/controller.md 4.6)
    valid = [bool(ok) for ok in msg.valid]
    for name in PREVIEW_ARRAYS[kind]:
        a = [float(x) for x in getattr(msg, name)]
        if any(map(math.isinf, a)):
            return f'{name} holds an infinite value'
        v = [x for x, ok in zip(a, valid) if ok]
        if any(map(math.isnan, v)):
            return f'{name} holds NaN where marked valid'
        lo, hi = PREVIEW_RANGES[name]
        if v and (min(v) < lo or max(v) > hi):
            return f'{name} holds {min(v) if min(v) < lo else max(v):.6g} where marked valid, outside [{lo}, {hi}]'
    return None


def check_preview_pair(w, s) -> str | None:
    """The weather and traffic previews used together share their grid (start and length)."""
    if (w.start.sec, w.start.nanosec) != (s.start.sec, s.start.nanosec):
        t_w, t_s = s_from_stamp(w.start), s_from_stamp(s.start)
        return f'weather and traffic previews start at different times ({t_w} vs {t_s} s)'
    if len(w.valid) != len(s.valid):
        return f'weather and traffic previews have {len(w.valid)} and {len(s.valid)} samples'
    return None
