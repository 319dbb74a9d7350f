"""The baseline strategy: the production ACC law (or its comfort-feedback mode) behind the controller interface.

The law itself (PI + anti-windup on T_cab vs 26 degC, demand mapped to the
evaporator set-point and the blower curve) is :mod:`ceco_core.acc_law`:
it is the vehicle ECU's code, which the plant side also uses as the fallback.
This wrapper only converts an :class:`Observation` into its input and its
output into ``(AcInput, Diagnostics)``. It uses no preview. A cabin air temperature outside the
plausible range (:class:`ceco_core.observation_check.ObservationLimits`) counts as a sensor fault:
the law holds its last command.

With ``AccSettings.feedback == 'pmv'`` the law regulates the cabin PMV of the observation
(:func:`ceco_controller.comfort_feedback.measured_pmv`, as ceco-pmv measures it: the scored comfort model on the
measured cabin air, vent air, surfaces, humidity and sun load, the ECU's own blower command; the interior in
place of a glazing and the paper's 1700 Pa in place of a humidity the car does not measure), with the scenario's
occupant and sun geometry (``comfort_params``). Behind ``measurements: vehicle`` the surfaces are the estimator's, from
the sensors a production car has.

The fresh/recirculation door (issue 21) is driven by :class:`ceco_core.recirc_law.RecircLaw` with the ACC
law's demand, the cabin and ambient temperatures, the CO2 sensor's reading and the fog margin of the
observation (measured glass temperature against the dew point of the measured cabin air); its default
mode ``none`` leaves the door to the plant (the baseline before issue 21). With ``door_mode: co2_hold`` the
door is the NMPC's CO2-holding door instead (:class:`ceco_core.co2_door.Co2DoorLaw`, the door of
``ceco-pmv-aq``, on the law's blower command): the benchmark's ``*-doorco2`` families, so that a strategy's
door is never a permission its baselines lack.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ceco_core.acc_law import AccLaw, AccSettings
from ceco_core.air_quality import fog_margin_of
from ceco_core.cabin_comfort import ComfortParams
from ceco_core.co2_door import Co2DoorLaw
from ceco_core.co2_estimator import Co2EstimatorParams
from ceco_core.contracts import ACTUATOR_LIMITS, AcInput, Diagnostics, Observation
from ceco_core.observation_check import OBSERVATION_LIMITS, ObservationLimits, check_observation
from ceco_core.recirc_law import RecircCommand, RecircLaw, RecircSettings

from .comfort_feedback import measured_pmv

__all__ = ["BaselineController"]


class BaselineController:
    """``compute(obs) -> (AcInput, Diagnostics)`` running the production ACC law every ``Ts``."""

    def __init__(
        self,
        settings: AccSettings | None = None,
        control_period_s: float = 5.0,
        observation_limits: ObservationLimits = OBSERVATION_LIMITS,
        comfort_params: ComfortParams | None = None,
        door: RecircSettings | None = None,
        co2_sensor_fitted: bool = True,
        co2_model: Co2EstimatorParams | None = None,
    ):
        if not (math.isfinite(control_period_s) and control_period_s > 0):
            raise ValueError(f"control_period_s must be finite and > 0, got {control_period_s!r}")
        self.law = AccLaw(settings)
        self.control_period_s = float(control_period_s)
        observation_limits.validate()
        self.observation_limits = observation_limits
        self.comfort_params = (comfort_params or ComfortParams()).validate()
        """Occupant and sun geometry of the comfort-feedback law's PMV (unused by the temperature law)."""
        self._pmv_fn = None
        """The PMV law's compiled PMV at ``comfort_params`` (:mod:`.pmv_function`; CasADi imported only for it)."""
        if self.law.settings.feedback == "pmv":
            from .pmv_function import CabinPmvFunction

            self._pmv_fn = CabinPmvFunction(self.comfort_params)
        self.door = RecircLaw(door)
        """The door logic (mode ``none``: the door is left to the plant)."""
        self.co2_door = Co2DoorLaw(model=co2_model) if self.door.settings.door_mode == "co2_hold" else None
        """The CO2-holding door (``door_mode: co2_hold``; its CO2 balance ``co2_model``, default the nominal values),
        else None."""
        self.co2_sensor_fitted = bool(co2_sensor_fitted)
        """Whether the car has a cabin CO2 sensor (a NaN reading is then a fault, and the door goes to fresh air)."""

    def reset(self) -> None:
        """Back to the key-on state."""
        self.law.reset()
        self.door.reset()
        if self.co2_door is not None:
            self.co2_door.reset()

    def compute(self, obs: Observation, t_start: float | None = None):
        """One control step from the measured cabin air temperature (never raises on its value).

        ``t_start`` is accepted for the controllers' common interface (the NMPC's step deadline);
        the law's cost is bounded and fixed, so it is not used.

        The ambient and sun-load sensors and the occupant's current upper PMV bound
        go to the law too; the plain law (the default settings) ignores them.
        """
        lo, hi = self.observation_limits.temperature_c
        try:
            t_cab = float(obs.t_cab_c)
        except (TypeError, ValueError, OverflowError):
            t_cab = math.nan
        pmv_ub = float(obs.pmv_ub[0]) if np.size(obs.pmv_ub) else None
        t_cab = t_cab if lo <= t_cab <= hi else math.nan
        pmv = None
        if self.law.settings.feedback == "pmv":
            # the observation's PMV as ceco-pmv measures it, from the checked optional sensors (NaN: not measured)
            chk = check_observation(obs, self.observation_limits)
            pmv = measured_pmv(
                dataclasses.replace(obs, t_cab_c=t_cab), self.comfort_params, chk.t_glass_c, chk.rh_cab, self._pmv_fn
            )
        cmd = self.law.step(
            t_cab,
            self.control_period_s,
            t_amb_c=obs.t_amb_c,
            solar_wm2=obs.solar_wm2,
            pmv_ub=pmv_ub,
            pmv=pmv,
        )
        if not ACTUATOR_LIMITS.contains(cmd.mdot_bl_kgps, cmd.t_evap_sp_c):
            raise AssertionError(f"ACC law produced an out-of-bounds command {cmd}")
        door = self._door(obs, cmd, t_cab)
        diag = Diagnostics(
            k=obs.k,
            t_s=obs.t_s,
            status=cmd.mode,
            mdot_bl_kgps=cmd.mdot_bl_kgps,
            t_evap_sp_c=cmd.t_evap_sp_c,
            message=(
                f"demand={cmd.demand:.3f} setpoint_c={cmd.setpoint_c:.3f}"
                if pmv is None
                else f"demand={cmd.demand:.3f} setpoint_pmv={cmd.setpoint_pmv:.3f} pmv_measured={pmv:.3f}"
            )
            + ("" if door.mode == "none" else f" door={door.recirc_share:.2f} door_mode={door.mode}"),
        )
        return AcInput(mdot_bl_kgps=cmd.mdot_bl_kgps, t_evap_sp_c=cmd.t_evap_sp_c, recirc_share=door.recirc_share), diag

    def _door(self, obs: Observation, cmd, t_cab: float):
        """The door command of this step: the production logic, a fixed share, none, or the CO2-holding door."""
        if self.co2_door is None:
            return self.door.step(
                self.control_period_s,
                demand=cmd.demand,
                pulldown=cmd.mode == "pulldown",
                t_cab_c=t_cab,
                t_amb_c=float(obs.t_amb_c),
                co2_sensor_fitted=self.co2_sensor_fitted,
                co2_sensor_ppm=float(obs.co2_sensor_ppm),
                co2_limit_ppm=float(obs.co2_limit_ppm),
                fog_margin_k=fog_margin_of(t_cab, obs.rh_cab, obs.t_glass_c),
                fog_margin_min_k=float(obs.fog_margin_min_k),
                rh_cab=float(obs.rh_cab),
                rh_amb=float(obs.rh_amb),
            )
        try:  # the cabin temperature as the law reads it (NaN when implausible: no economiser on a bad sensor)
            c = self.co2_door.step_observation(
                dataclasses.replace(obs, t_cab_c=t_cab),
                dt_s=self.control_period_s,
                mdot_bl_kgps=cmd.mdot_bl_kgps,
                co2_sensor_fitted=self.co2_sensor_fitted,
            )
        except ValueError as exc:  # e.g. time going back: fresh air, the safe default, and said so
            return RecircCommand(0.0, f"co2_door_error ({exc}; fresh air)")
        return RecircCommand(c.recirc_share, c.mode)
