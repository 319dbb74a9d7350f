"""The control-step grid t_k = k * Ts shared by every node of the lockstep stack.

preview_node publishes the previews of step k and mpc_node solves step k
on the same states, so both must agree on which scenario times are control
steps. Pure logic: no rclpy, no message types.
"""

from __future__ import annotations

import math

__all__ = [
    "control_step_index",
    "control_step_of",
    "control_step_count",
    "whole_steps",
    "floor_steps",
    "STEP_TOL",
    "TIMING_MODES",
]

TIMING_MODES = ("lockstep", "realtime")
"""The nodes' timing modes: deterministic lockstep on /clock, or wall-clock timers."""

GRID_TOL = 1e-6
"""Tolerance of a control-step time, relative to Ts [-] (scenario times n * dt carry float rounding)."""


def control_step_index(t_s: float, control_period_s: float) -> int | None:
    """Index k of the control step at ``t_s`` = k * Ts [s], or None when ``t_s`` lies between control steps."""
    k = int(round(t_s / control_period_s))
    return k if abs(t_s - k * control_period_s) <= GRID_TOL * control_period_s else None


def control_step_of(t_s: float, control_period_s: float) -> int:
    """Index k of the control step that ``t_s`` belongs to, t_k <= t_s < t_(k+1) [-].

    ``t_s`` = n * dt carries float rounding (0.01 * 30 / 0.1 = 2.9999999999999996): a time within
    :data:`GRID_TOL` * Ts below t_(k+1) counts as t_(k+1), as in :func:`control_step_index`.
    """
    return math.floor(t_s / control_period_s + GRID_TOL)


def control_step_count(duration_s: float, control_period_s: float) -> int:
    """How many control steps a run of ``duration_s`` [s] has: those at t_k = k Ts < ``duration_s`` (at least one)."""
    return max(math.ceil(duration_s / control_period_s - GRID_TOL), 1)


STEP_TOL = 1e-9
"""Tolerance of a whole number of steps, in steps [-] (durations and periods written in decimal)."""


def whole_steps(t_s: float, step_s: float) -> int | None:
    """``t_s / step_s`` [-] when it is a whole number (within :data:`STEP_TOL`), else None.

    The one test of "a whole number of plant steps" (a run's length, Ts) or of model steps (the NMPC's Ts).
    """
    ratio = t_s / step_s
    n = round(ratio)
    return int(n) if abs(ratio - n) <= STEP_TOL else None


def floor_steps(t_s: float, step_s: float) -> int:
    """The whole steps of ``step_s`` in ``t_s`` [-]: floor, with :data:`STEP_TOL` for float grids."""
    return int(math.floor(t_s / step_s + STEP_TOL))
