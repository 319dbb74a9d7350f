"""A controller that sees only the vehicle sensors: the state estimator in front of it.

``measurements: vehicle`` (docs/controller.md section 5): :class:`EstimatingController` runs
:class:`ceco_controller.estimator.CabinStateEstimator` on the production sensors of each
:class:`~ceco_core.contracts.Observation` and hands the wrapped controller (NMPC or baseline) the
observation with the estimated cabin temperatures; :func:`with_measurements` wraps a controller for a
measurement mode.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

from ceco_core.co2_estimator import Co2Estimate, Co2Estimator
from ceco_core.contracts import MEASUREMENT_MODES, Observation

from . import model as cm
from .estimator import CabinStateEstimator, Estimate
from .estimator_model import EstimatorParams, EstimatorSettings

__all__ = ["EstimatingController", "with_measurements"]


class EstimatingController:
    """A controller that sees only the vehicle sensors.

    ``compute(obs)`` ignores ``obs.t_int_c``, ``obs.t_shell_c``, ``obs.t_glass_c`` and ``obs.co2_cab_ppm``, runs
    :class:`CabinStateEstimator` on the vehicle sensors of ``obs`` (cabin RH passed through) and the
    previous command, and :class:`~ceco_core.co2_estimator.Co2Estimator` on the CO2 sensor's reading (NaN: none),
    the door's position, the blower, the speed and the occupants, and calls the wrapped controller with the
    estimated observation.

    Sensors that were valid are passed unchanged (so without faults the wrapped controller sees the
    same cabin, evaporator, vent, ambient, sun-load and speed values as in full mode); missing ones are
    replaced by the estimate. When the estimate is invalid (no valid cabin air sample for
    ``max_dead_reckoning_s``), the wrapped controller gets a non-finite cabin air temperature, i.e. its
    own sensor-fault handling (NMPC: the ACC law; the ACC law: hold the last command). The estimator's
    flags are appended to ``Diagnostics.message``. Other attributes are the wrapped controller's.
    """

    def __init__(self, inner, estimator: CabinStateEstimator):
        self.inner = inner
        """The wrapped controller (``NmpcController`` or ``BaselineController``)."""
        self.estimator = estimator
        """The :class:`CabinStateEstimator`."""
        self.last_estimate: Estimate | None = None
        """The estimate of the last :meth:`compute` call."""
        self.last_co2: Co2Estimate | None = None
        """The CO2 estimate of the last :meth:`compute` call (:class:`~ceco_core.co2_estimator.Co2Estimate`)."""
        self.co2 = Co2Estimator()
        """The cabin CO2 estimate (:class:`ceco_core.co2_estimator.Co2Estimator`): the CO2 sensor's reading and the
        CO2 balance, or the balance alone without a reading."""

    def __getattr__(self, name):
        if name in ("inner", "estimator", "co2", "last_co2"):  # not yet set (copy/pickle): no recursion
            raise AttributeError(name)
        return getattr(self.inner, name)

    def reset(self) -> None:
        """Reset the wrapped controller and the estimator (key-on)."""
        self.inner.reset()
        self.estimator.reset()
        self.co2.reset()
        self.last_estimate = None

    def estimated_observation(self, obs: Observation) -> Observation:
        """Run the estimator on the vehicle sensors of ``obs``; the observation the controller gets."""
        meas = {
            "t_cab_c": obs.t_cab_c,
            "t_vent_c": obs.t_vent_c,
            "t_evap_c": obs.t_evap_c,
            "t_amb_c": obs.t_amb_c,
            "solar_wm2": obs.solar_wm2,
            "speed_mps": obs.speed_mps,
        }
        if math.isfinite(obs.rh_cab):
            meas["rh_cab"] = obs.rh_cab  # NaN there means "not measured": not a sensor fault
        est = self.estimator.update(obs.t_s, meas, (obs.mdot_bl_prev_kgps, obs.t_evap_sp_prev_c))
        self.last_estimate = est
        fields: dict[str, Any] = {
            "t_cab_c": est.t_cab_c if est.valid else math.nan,
            "t_int_c": est.t_int_c,
            "t_shell_c": est.t_shell_c,
            "t_glass_c": est.t_glass_c,
            "t_evap_c": est.t_evap_c,
            "t_vent_c": est.t_vent_c,
            "t_amb_c": est.t_amb_c,
            "solar_wm2": est.solar_wm2,
            "speed_mps": est.speed_mps,
            "rh_cab": est.rh_cab,
            "mdot_bl_prev_kgps": est.mdot_bl_prev_kgps,
            "t_evap_sp_prev_c": est.t_evap_sp_prev_c,
            "co2_cab_ppm": self._co2_estimate(obs).co2_cab_ppm,
        }
        return dataclasses.replace(obs, **fields)

    def _co2_estimate(self, obs: Observation):
        est = self.co2.update(
            obs.t_s, obs.co2_sensor_ppm, obs.recirc_share, obs.mdot_bl_prev_kgps, obs.speed_mps, obs.n_occupants
        )
        self.last_co2 = est
        return est

    def prepare(self, obs: Observation):
        """The wrapped controller's ``prepare`` on the observation :meth:`compute` will see for ``obs``.

        The estimate is taken from a copy of the estimator, so the following ``compute(obs)``
        updates the real one exactly once for that sample.
        """
        if not hasattr(self.inner, "prepare"):  # the ACC law has nothing to prepare
            return None
        probe = EstimatingController(self.inner, copy.deepcopy(self.estimator))
        probe.co2 = copy.deepcopy(self.co2)
        return self.inner.prepare(probe.estimated_observation(obs))

    def compute(self, obs: Observation, t_start: float | None = None):
        """One control step: estimate, then the wrapped controller's ``compute``.

        ``t_start`` is the step's start on the controller's clock [s], passed on so the
        estimate counts against the deadline.
        """
        obs_est = self.estimated_observation(obs)
        cmd, diag = self.inner.compute(obs_est, t_start=t_start)
        assert self.last_estimate is not None
        note = self.last_estimate.describe()
        held = getattr(self, "last_co2", None)
        if held is not None and held.inputs_held:
            note = "; ".join(x for x in (note, f"co2 estimate held {', '.join(held.inputs_held)}") if x)
        if note:
            diag.message = f"{diag.message}; {note}" if diag.message else note
        return cmd, diag


def with_measurements(
    controller,
    measurements: str,
    control_period_s: float,
    model_params: cm.ControlModelParams | None = None,
    params: EstimatorParams | None = None,
    settings: EstimatorSettings | None = None,
):
    """``controller`` for ``measurements='full'``; wrapped in :class:`EstimatingController` for 'vehicle'."""
    if measurements not in MEASUREMENT_MODES:
        raise ValueError(f"measurements must be one of {MEASUREMENT_MODES}, got {measurements!r}")
    if measurements == "full" or isinstance(controller, EstimatingController):
        return controller
    mp = model_params if model_params is not None else getattr(controller, "model_params", None)
    return EstimatingController(controller, CabinStateEstimator(mp, params, settings, control_period_s))
