"""Unit conversions for ceco: the one place where they live.

The temperature, speed and pressure conversions work elementwise on Python
floats, numpy arrays (broadcasting) and CasADi symbols (``SX``/``MX``/``DM``):
the bodies use only ``+``, ``-`` and ``*``, which all three overload
identically. The time-stamp conversions take Python scalars.
"""

import math

__all__ = [
    "ZERO_C_K",
    "c_to_k",
    "k_to_c",
    "mph_to_mps",
    "kmh_to_mps",
    "mps_to_kmh",
    "kpa_to_pa",
    "pa_to_kpa",
    "STAMP_MAX_S",
    "sec_nanosec_from_s",
    "s_from_sec_nanosec",
    "s_from_stamp",
]

ZERO_C_K = 273.15
"""0 degC expressed in kelvin [K] (exact, SI brochure 9th ed., 2.3.1)."""

_MPH_TO_MPS = 0.44704
"""1 mile per hour in m/s (exact: 1 mile = 1609.344 m, 1 h = 3600 s)."""

_KMH_TO_MPS = 1.0 / 3.6
"""1 km/h in m/s (exact)."""


def c_to_k(t_c):
    """Convert a temperature from degC to kelvin: ``t_k = t_c + 273.15``."""
    return t_c + ZERO_C_K


def k_to_c(t_k):
    """Convert a temperature from kelvin to degC: ``t_c = t_k - 273.15``."""
    return t_k - ZERO_C_K


def mph_to_mps(v_mph):
    """Convert a speed from mile/h to m/s (1 mph = 0.44704 m/s exactly)."""
    return v_mph * _MPH_TO_MPS


def kmh_to_mps(v_kmh):
    """Convert a speed from km/h to m/s (1 km/h = 1/3.6 m/s exactly)."""
    return v_kmh * _KMH_TO_MPS


def mps_to_kmh(v_mps):
    """Convert a speed from m/s to km/h (for display only; the wire is m/s)."""
    return v_mps * 3.6


def kpa_to_pa(p_kpa):
    """Convert a pressure from kPa to Pa."""
    return p_kpa * 1000.0


def pa_to_kpa(p_pa):
    """Convert a pressure from Pa to kPa."""
    return p_pa * 1.0e-3


STAMP_MAX_S = 2**31 - 1
"""Largest time a builtin_interfaces/Time can hold [s] (``sec`` is an int32)."""


def sec_nanosec_from_s(t_s: float) -> tuple[int, int]:
    """Split a time [s] into (sec, nanosec) as builtin_interfaces/Time holds it, exact to the nanosecond.

    ValueError (naming the value) unless ``0 <= t_s <= STAMP_MAX_S`` and finite: a stamp is never
    silently wrapped or clamped.
    """
    if not (isinstance(t_s, (int, float)) and math.isfinite(t_s) and 0.0 <= t_s <= STAMP_MAX_S):
        raise ValueError(f"time {t_s!r} s cannot be a stamp (must be finite, in [0, {STAMP_MAX_S}] s)")
    ns = int(round(t_s * 1e9))
    return ns // 1_000_000_000, ns % 1_000_000_000


def s_from_sec_nanosec(sec: int, nanosec: int) -> float:
    """Seconds from a stamp's (sec, nanosec) [s] (any object's fields: rclpy, rosbags)."""
    return sec + nanosec * 1e-9


def s_from_stamp(stamp) -> float:
    """Seconds [s] of a builtin_interfaces/Time (any object with ``sec`` and ``nanosec``)."""
    return s_from_sec_nanosec(stamp.sec, stamp.nanosec)
