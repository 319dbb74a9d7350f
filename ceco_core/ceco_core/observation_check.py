"""Plausibility of every :class:`~ceco_core.contracts.Observation` field, before a controller uses it.

A value is plausible when it is a finite number inside the range a vehicle's sensors and the
climate system can produce (:class:`ObservationLimits`, defaults below). The check sorts each
problem by what a controller can still do:

* ``measurement`` (a scalar measurement the NMPC needs, or the comfort zone): not usable, the
  production law takes over for this step;
* ``previous command`` (``mdot_bl_prev_kgps``, ``t_evap_sp_prev_c`` outside the actuator bounds
  or not finite): the controller substitutes the command it applied itself, if any;
* ``preview`` entries marked valid but not plausible: treated as not valid (the controller holds
  the last trusted value, docs/controller.md 4.5);
* optional measurements (``t_glass_c``, ``rh_cab``, ``rh_amb``; NaN when the car has no such sensor): an
  implausible value is reported and treated as not measured (:attr:`ObservationCheck.t_glass_c`,
  :attr:`ObservationCheck.rh_cab`, :attr:`ObservationCheck.rh_amb` are the values to use);
* ``info`` (``k``, ``t_s``, ``met``, ``clo``: not used by any computation of the NMPC): reported.

Pure; no ROS, no solver.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .contracts import ACTUATOR_LIMITS, Observation

__all__ = ["ObservationLimits", "ObservationCheck", "check_observation", "OBSERVATION_LIMITS"]


@dataclasses.dataclass(frozen=True)
class ObservationLimits:
    """Plausible ranges of the observation's fields (inclusive)."""

    temperature_c: tuple[float, float] = (-40.0, 120.0)
    """Cabin air, interior, shell, evaporator and vent temperatures [degC] (a hot-soaked dashboard
    reaches 90-100 degC; sc03_hotsoak starts the interior at 62 degC)."""
    ambient_c: tuple[float, float] = (-40.0, 60.0)
    """Ambient air temperature, measured and previewed [degC]."""
    solar_wm2: tuple[float, float] = (-100.0, 2000.0)
    """Solar load, measured and previewed [W/m2] (negative sensor offsets and preview noise are
    tolerated; the NMPC clips to >= 0)."""
    speed_mps: tuple[float, float] = (-10.0, 90.0)
    """Vehicle speed, measured and previewed [m/s] (reverse tolerated; the NMPC clips to >= 0)."""
    rh: tuple[float, float] = (0.0, 1.0)
    """Cabin relative humidity [-] (a 0-1 fraction)."""
    pmv: tuple[float, float] = (-3.0, 3.0)
    """PMV comfort bounds [-] (ISO 7730 scale)."""
    met: tuple[float, float] = (0.8, 4.0)
    """Metabolic rate [met] (ISO 7730 Clause 4)."""
    clo: tuple[float, float] = (0.0, 2.0)
    """Clothing insulation [clo] (ISO 7730 Clause 4)."""
    command_tol: float = 1e-6
    """Tolerance on the actuator bounds of the previous command [kg/s, degC]."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a range is not an ordered pair of finite numbers."""
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "command_tol":
                if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                    raise ValueError("ObservationLimits.command_tol must be finite and >= 0")
                continue
            if not (len(v) == 2 and all(math.isfinite(x) for x in v) and v[0] < v[1]):
                raise ValueError(f"ObservationLimits.{f.name} must be (low, high) finite with low < high, got {v!r}")


OBSERVATION_LIMITS = ObservationLimits()
"""The default plausibility ranges."""


@dataclasses.dataclass
class ObservationCheck:
    """What :func:`check_observation` found."""

    measurement_problems: list[str]
    """Implausible measurements or comfort bounds (the observation is not usable for the NMPC)."""
    command_problems: list[str]
    """Implausible previous command."""
    info_problems: list[str]
    """Implausible fields no NMPC computation uses (k, t_s, met, clo)."""
    preview_plausible: np.ndarray
    """Per grid point: every previewed quantity plausible (bool, shape (n,))."""
    t_glass_c: float = math.nan
    """The glazing temperature to use [degC]: the measurement if plausible, else NaN (not measured)."""
    rh_cab: float = math.nan
    """The cabin RH to use [-]: the measurement if plausible, else NaN (not measured)."""
    rh_amb: float = math.nan
    """The ambient RH to use [-]: the measurement if plausible, else NaN (not measured)."""

    @property
    def measurements_ok(self) -> bool:
        """No measurement or comfort-bound problem."""
        return not self.measurement_problems

    @property
    def command_ok(self) -> bool:
        """The previous command is finite and inside the actuator bounds."""
        return not self.command_problems

    def summary(self) -> str:
        """All problems, ``;``-joined (empty when there is none)."""
        return "; ".join(self.measurement_problems + self.command_problems + self.info_problems)


def _in(v, lim) -> bool:
    try:
        x = float(v)
    except (TypeError, ValueError, OverflowError):
        return False
    return math.isfinite(x) and lim[0] <= x <= lim[1]


def _arr_in(a, lim) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    return (a >= lim[0]) & (a <= lim[1])  # False for NaN; +-inf is outside any finite range (no warning)


def check_observation(obs: Observation, limits: ObservationLimits = OBSERVATION_LIMITS) -> ObservationCheck:
    """Check every field of ``obs`` against ``limits``; never raises on the values."""
    meas, cmd, info = [], [], []
    for name in ("t_cab_c", "t_int_c", "t_shell_c", "t_evap_c", "t_vent_c"):
        if not _in(getattr(obs, name), limits.temperature_c):
            meas.append(f"{name}={getattr(obs, name)!r} outside {limits.temperature_c}")
    for name, lim in (("t_amb_c", limits.ambient_c), ("solar_wm2", limits.solar_wm2), ("speed_mps", limits.speed_mps)):
        if not _in(getattr(obs, name), lim):
            meas.append(f"{name}={getattr(obs, name)!r} outside {lim}")
    lb_ok, ub_ok = _arr_in(obs.pmv_lb, limits.pmv), _arr_in(obs.pmv_ub, limits.pmv)
    if not (lb_ok.all() and ub_ok.all()):
        meas.append(f"pmv_lb/pmv_ub not finite or outside {limits.pmv}")
    else:
        if (np.asarray(obs.pmv_lb) > np.asarray(obs.pmv_ub)).any():  # both finite here
            meas.append("pmv_lb above pmv_ub")
    act, tol = ACTUATOR_LIMITS, limits.command_tol
    if not _in(obs.mdot_bl_prev_kgps, (act.mdot_bl_min_kgps - tol, act.mdot_bl_max_kgps + tol)):
        cmd.append(f"mdot_bl_prev_kgps={obs.mdot_bl_prev_kgps!r} outside the actuator bounds")
    if not _in(obs.t_evap_sp_prev_c, (act.t_evap_sp_min_c - tol, act.t_evap_sp_max_c + tol)):
        cmd.append(f"t_evap_sp_prev_c={obs.t_evap_sp_prev_c!r} outside the actuator bounds")
    if not (isinstance(obs.k, (int, np.integer)) and obs.k >= 0):
        info.append(f"k={obs.k!r} not an int >= 0")
    if not _in(obs.t_s, (0.0, math.inf)):
        info.append(f"t_s={obs.t_s!r} not finite and >= 0")
    if not _in(obs.met, limits.met):
        info.append(f"met={obs.met!r} outside {limits.met} (not used by the NMPC)")
    if not _in(obs.clo, limits.clo):
        info.append(f"clo={obs.clo!r} outside {limits.clo} (not used by the NMPC)")
    optional = {}
    for name, lim in (("t_glass_c", limits.temperature_c), ("rh_cab", limits.rh), ("rh_amb", limits.rh)):
        v = getattr(obs, name, math.nan)
        try:
            missing = math.isnan(float(v))
        except (TypeError, ValueError, OverflowError):
            missing = False
        if missing or _in(v, lim):
            optional[name] = math.nan if missing else float(v)
        else:
            optional[name] = math.nan
            info.append(f"{name}={v!r} outside {lim}: treated as not measured")
    plausible = (
        _arr_in(obs.preview_t_amb_c, limits.ambient_c)
        & _arr_in(obs.preview_solar_wm2, limits.solar_wm2)
        & _arr_in(obs.preview_speed_mps, limits.speed_mps)
    )
    return ObservationCheck(
        measurement_problems=meas, command_problems=cmd, info_problems=info, preview_plausible=plausible, **optional
    )
