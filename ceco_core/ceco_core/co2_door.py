"""The fresh/recirculation door beside the NMPC: hold the cabin CO2 just under its limit with the least fresh air.

Issue 21 part 2, ``StrategySettings.door_control = "co2_hold"`` (docs/controller.md "The door beside the NLP").
On a hot day every kilogram of fresh air is a cooling load (its enthalpy is above the cabin's), so with the
thermal commands given the cheapest door is the largest recirculated share that keeps the CO2 at or under a
target; fresh air is only let in for the occupants' CO2. Over one control period with the blower flow and the
speed held, the cabin CO2 balance (:mod:`ceco_core.air_quality`, the estimator's model) is linear with the exact
solution

    C(t + dt) = C_ss + (C - C_ss) exp(-(F + L) dt / m_air),   C_ss = C_amb + n g / ((F + L) k)

with F = (1 - r) mdot_bl the fresh air [kg/s], L = leakage(V) [kg/s], n g the occupants' CO2 [kg/s], k = 1.519e-6
kg/kg per ppm, m_air the cabin's air [kg]. C(t + dt) falls monotonically as F grows, so the share is the largest r
in [0, 1] with C(t + dt) <= C_target = limit - ``margin_ppm`` (bisection; 0 when even fresh air cannot reach it).
C is the estimate of :class:`ceco_core.co2_estimator.Co2Estimator` on the CO2 sensor's reading (never the plant's
value), so the door sees what the production logic sees.

Safe defaults, ahead of the CO2 rule: fresh air (share 0) while the fog margin is below its bound +
``fog_enter_k`` (until bound + ``fog_exit_k``), while a fitted CO2 sensor does not read, or while the estimate is
not finite; fresh air also when the ambient is cooler than the cabin by ``economiser_k`` (fresh air is free cooling
then). The door as a third input of the NLP (``door_control = "nlp"``, docs/controller.md 4.9) uses this law's
estimate and safe modes (:meth:`Co2DoorLaw.observe`), its NLP parameters (:meth:`Co2DoorLaw.nlp_parameters`) and
:func:`co2_after_ppm` as the NLP's CO2 prediction; its rule (:meth:`Co2DoorLaw.hold`) when there is no plan.

Pure and deterministic, no ROS: ``Co2DoorLaw(settings).step(...) -> Co2DoorCommand``.
"""

from __future__ import annotations

import dataclasses
import math

from ceco_core.air_quality import (
    KGKG_PER_PPM,
    check_settings,
    co2_generation_kgps,
    co2_steady_ppm,
    economiser_open,
    fog_margin_of,
    fog_override,
    leakage_kgps,
)
from ceco_core.co2_estimator import Co2Estimator, Co2EstimatorParams
from ceco_core.mathops import backend

__all__ = ["Co2DoorSettings", "Co2DoorCommand", "Co2DoorLaw", "co2_after_ppm", "hold_share"]


@dataclasses.dataclass(frozen=True)
class Co2DoorSettings:
    """Settings of the CO2-holding door."""

    margin_ppm: float = 150.0
    """The target is the limit minus this [ppm]: the estimate's error (within 120 ppm of the truth after the first
    minute with the NDIR sensor, tests/test_air_quality.py) plus the door's travel."""
    fog_enter_k: float = 0.5
    """Fresh air while the fog margin is below its bound plus this [K] (the production logic's value)."""
    fog_exit_k: float = 1.5
    """... until it is back above its bound plus this [K]."""
    economiser_k: float = 1.0
    """Fresh air when the ambient is cooler than the cabin by at least this [K] (and lower in enthalpy by c_p,a times
    it where both humidities are known: :func:`ceco_core.air_quality.economiser_open`)."""

    def validate(self) -> Co2DoorSettings:
        """Raise ValueError naming the field if a setting is not usable; return self."""
        check_settings(self)
        if not self.fog_enter_k < self.fog_exit_k:
            raise ValueError("Co2DoorSettings: must have fog_enter_k < fog_exit_k")
        return self


@dataclasses.dataclass(frozen=True)
class Co2DoorCommand:
    """The door command of one control step."""

    recirc_share: float
    """Commanded recirculated share [0..1]."""
    mode: str
    """Why: 'fog', 'co2_sensor_fault', 'co2_unknown', 'economiser', 'recirc' (the target is met in full
    recirculation), 'co2_hold' (fresh air for the CO2), 'co2_max_fresh' (even fresh air cannot reach the target)."""
    co2_estimate_ppm: float
    """The CO2 estimate the command was computed from [ppm]."""


def co2_after_ppm(co2_ppm, co2_amb_ppm, fresh_kgps, leak_kgps, generation_ppm_kgps, m_air_kg, dt_s):
    """Cabin CO2 [ppm] after ``dt_s`` [s] with the flows held (the exact solution of the module docstring).

    ``generation_ppm_kgps`` = n g / k [ppm kg/s]; ``fresh_kgps`` + ``leak_kgps`` > 0. Backend-neutral: floats,
    numpy arrays or CasADi symbols (the NLP's CO2 prediction of ``door_control`` 'nlp' is this function).
    """
    q = fresh_kgps + leak_kgps
    c_ss = co2_steady_ppm(co2_amb_ppm, q, 1, generation_ppm_kgps * KGKG_PER_PPM)
    arg = -q * dt_s / m_air_kg
    decay = math.exp(arg) if isinstance(arg, (int, float)) else backend(arg).exp(arg)  # math.exp: floats as before
    return c_ss + (co2_ppm - c_ss) * decay


def hold_share(co2_ppm, target_ppm, co2_amb_ppm, mdot_bl_kgps, leak_kgps, generation_ppm_kgps, m_air_kg, dt_s):
    """The largest recirculated share in [0, 1] whose CO2 after ``dt_s`` is at or under ``target_ppm``.

    0 when even fresh air does not reach it. Bisection to 1e-4 of the share.
    """

    def after(r):
        fresh = (1.0 - r) * mdot_bl_kgps
        return co2_after_ppm(co2_ppm, co2_amb_ppm, fresh, leak_kgps, generation_ppm_kgps, m_air_kg, dt_s)

    if after(1.0) <= target_ppm:
        return 1.0
    if after(0.0) > target_ppm:
        return 0.0
    lo, hi = 0.0, 1.0  # after(lo) <= target < after(hi)
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        if after(mid) <= target_ppm:
            lo = mid
        else:
            hi = mid
    return lo


class Co2DoorLaw:
    """The CO2-holding door, stepped every control period (owns its CO2 estimator on the sensor's reading)."""

    def __init__(self, settings: Co2DoorSettings | None = None, model: Co2EstimatorParams | None = None):
        self.settings = (settings or Co2DoorSettings()).validate()
        self.model = (model or Co2EstimatorParams()).validate()
        """The cabin's CO2 model: the estimator's (docs/plant.md's nominal values)."""
        self.estimator = Co2Estimator(self.model)
        self.reset()

    def reset(self) -> None:
        """Back to the key-on state (no fog override, a fresh estimate)."""
        self._fog = False
        self.estimator.reset()

    def observe(
        self,
        *,
        t_s: float,
        co2_sensor_fitted: bool,
        co2_sensor_ppm: float,
        recirc_share: float,
        mdot_bl_prev_kgps: float,
        speed_mps: float,
        n_occupants: int,
        fog_margin_k: float,
        fog_margin_min_k: float,
    ) -> tuple[float, str | None]:
        """Update the CO2 estimate and the fog override: ``(estimate [ppm], safe mode or None)``.

        The safe mode, when not None, is why the door must be at fresh air now, ahead of any CO2 rule or plan:
        'fog', 'co2_sensor_fault' (a fitted sensor does not read) or 'co2_unknown' (the estimate is not finite).
        ``recirc_share`` (the measured door), ``mdot_bl_prev_kgps`` (the blower flow of the period that just ended)
        and ``speed_mps`` are the estimator's inputs over that period (:meth:`ceco_core.co2_estimator.Co2Estimator.
        update`). Raises ValueError when time goes back.
        """
        s = self.settings
        est = self.estimator.update(t_s, co2_sensor_ppm, recirc_share, mdot_bl_prev_kgps, speed_mps, n_occupants)
        c = est.co2_cab_ppm
        self._fog = fog_override(self._fog, fog_margin_k, fog_margin_min_k, s.fog_enter_k, s.fog_exit_k)
        if self._fog:
            return c, "fog"
        if co2_sensor_fitted and not math.isfinite(co2_sensor_ppm):
            return c, "co2_sensor_fault"
        if not math.isfinite(c):
            return c, "co2_unknown"
        return c, None

    def nlp_parameters(self, co2_ppm: float, co2_limit_ppm: float, n_occupants: int) -> dict:
        """The CO2 parameters of the NLP of ``door_control`` 'nlp' (:data:`ceco_controller.nlp_layout.PARAM_DOOR`).

        ``co2_ppm`` the estimate (its initial value; a non-finite estimate enters as the target, the door being
        held at fresh air by :meth:`observe`'s safe mode then); the target is ``co2_limit_ppm`` - ``margin_ppm``.
        """
        m = self.model
        target = float(co2_limit_ppm) - self.settings.margin_ppm
        return {
            "co2_0": float(co2_ppm) if math.isfinite(co2_ppm) else target,
            "co2_amb": m.co2_amb_ppm,
            "co2_gen": max(int(n_occupants), 0) * co2_generation_kgps(m.met) / KGKG_PER_PPM,
            "co2_max": target,
            "leak_0": m.leak_0_kgps,
            "leak_v": m.leak_per_mps_kgps,
            "m_air": m.m_air_kg,
        }

    def hold(
        self,
        co2_ppm: float,
        *,
        dt_s: float,
        co2_limit_ppm: float,
        mdot_bl_kgps: float,
        speed_mps: float,
        n_occupants: int,
        t_cab_c: float,
        t_amb_c: float,
        rh_cab: float = math.nan,
        rh_amb: float = math.nan,
    ) -> Co2DoorCommand:
        """The economiser and the CO2-holding rule on the estimate ``co2_ppm`` [ppm] (no safe mode active).

        ``rh_cab``, ``rh_amb`` [0..1] the cabin's and the ambient's relative humidity (NaN: not measured, the
        economiser judges by dry bulb alone).
        """
        s, m, c = self.settings, self.model, co2_ppm
        if economiser_open(t_cab_c, t_amb_c, rh_cab, rh_amb, s.economiser_k):
            return Co2DoorCommand(0.0, "economiser", c)
        leak = leakage_kgps(m.leak_0_kgps, m.leak_per_mps_kgps, max(float(speed_mps), 0.0))
        gen = int(n_occupants) * co2_generation_kgps(m.met) / KGKG_PER_PPM
        target = co2_limit_ppm - s.margin_ppm
        r = hold_share(c, target, m.co2_amb_ppm, max(float(mdot_bl_kgps), 0.0), leak, gen, m.m_air_kg, dt_s)
        mode = "recirc" if r >= 1.0 else ("co2_max_fresh" if r <= 0.0 else "co2_hold")
        return Co2DoorCommand(r, mode, c)

    def step(
        self,
        *,
        t_s: float,
        dt_s: float,
        co2_sensor_fitted: bool,
        co2_sensor_ppm: float,
        co2_limit_ppm: float,
        recirc_share: float,
        mdot_bl_prev_kgps: float,
        mdot_bl_kgps: float,
        speed_mps: float,
        n_occupants: int,
        t_cab_c: float,
        t_amb_c: float,
        fog_margin_k: float,
        fog_margin_min_k: float,
        rh_cab: float = math.nan,
        rh_amb: float = math.nan,
    ) -> Co2DoorCommand:
        """The door command over the next ``dt_s`` [s]: :meth:`observe`, then its safe mode or :meth:`hold`.

        ``recirc_share`` the measured door and ``mdot_bl_prev_kgps`` the blower flow of the period that just ended
        (the estimator's inputs over that period), ``mdot_bl_kgps`` the blower flow of the next period (the
        controller's command: the share is computed for it), ``fog_margin_k`` [K] (NaN: unknown, no override).
        """
        c, safe = self.observe(
            t_s=t_s,
            co2_sensor_fitted=co2_sensor_fitted,
            co2_sensor_ppm=co2_sensor_ppm,
            recirc_share=recirc_share,
            mdot_bl_prev_kgps=mdot_bl_prev_kgps,
            speed_mps=speed_mps,
            n_occupants=n_occupants,
            fog_margin_k=fog_margin_k,
            fog_margin_min_k=fog_margin_min_k,
        )
        if safe is not None:
            return Co2DoorCommand(0.0, safe, c)
        return self.hold(
            c,
            dt_s=dt_s,
            co2_limit_ppm=co2_limit_ppm,
            mdot_bl_kgps=mdot_bl_kgps,
            speed_mps=speed_mps,
            n_occupants=n_occupants,
            t_cab_c=t_cab_c,
            t_amb_c=t_amb_c,
            rh_cab=rh_cab,
            rh_amb=rh_amb,
        )

    def step_observation(self, obs, *, dt_s: float, mdot_bl_kgps: float, co2_sensor_fitted: bool) -> Co2DoorCommand:
        """:meth:`step` from a controller's observation (:class:`ceco_core.contracts.Observation`).

        ``mdot_bl_kgps`` the blower command of the next period [kg/s]; the fog margin is the measured glass
        temperature against the dew point of the measured cabin air. Used by the NMPC (``door_control:
        co2_hold``) and by the baselines with ``door_mode: co2_hold``: one door, two thermal laws.
        """
        return self.step(
            t_s=float(obs.t_s),
            dt_s=dt_s,
            co2_sensor_fitted=co2_sensor_fitted,
            co2_sensor_ppm=float(obs.co2_sensor_ppm),
            co2_limit_ppm=float(obs.co2_limit_ppm),
            recirc_share=float(obs.recirc_share),
            mdot_bl_prev_kgps=float(obs.mdot_bl_prev_kgps),
            mdot_bl_kgps=float(mdot_bl_kgps),
            speed_mps=float(obs.speed_mps),
            n_occupants=int(obs.n_occupants),
            t_cab_c=float(obs.t_cab_c),
            t_amb_c=float(obs.t_amb_c),
            fog_margin_k=fog_margin_of(obs.t_cab_c, obs.rh_cab, obs.t_glass_c),
            fog_margin_min_k=float(obs.fog_margin_min_k),
            rh_cab=float(obs.rh_cab),
            rh_amb=float(obs.rh_amb),
        )
