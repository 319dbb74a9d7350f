"""The production automatic recirculation logic: the fresh/recirculation door of the baseline ECU.

What production automatic climate controls do with the air inlet in cooling (a synthesis of owner's and
service manuals, not one OEM's law; sources and the certainty of each in docs/benchmark.md "Baselines: the
door"):

1. Safety overrides, highest priority:
   * fog: the windshield fog margin (inner glass temperature minus cabin dew point,
     :func:`ceco_core.air_quality.fog_margin_k`) below its bound plus ``door_fog_enter_k`` -> fresh air
     (share ``door_fresh_share``) until it is back above the bound plus ``door_fog_exit_k`` (JLR: "admits more
     fresh air" when the dew point nears the glass; VW: recirculation off "if a sensor detects that
     condensation might form");
   * CO2 sensor fitted but not reading (NaN: failed) -> fresh air (the safe default of issue 21).
2. Economiser: while the ambient air is cooler than the cabin air by ``door_economiser_k`` and, where both
   humidities are known, lower in enthalpy (:func:`ceco_core.air_quality.economiser_open`) -> outside air (share
   ``door_fresh_share``): outside air is then the cheaper evaporator inlet and it flushes the soaked cabin (the
   air-side economiser of building HVAC, ASHRAE 90.1 section 6.5.1, with a differential-enthalpy high limit as in
   its table 6.5.1.1.3).
   Not from the car manuals above: it gives
   the baselines the permission the CO2-holding door of the NMPC has (``ceco_core.co2_door``, its
   ``economiser_k``), so no saving comes from a rule only the strategy may use (docs/benchmark.md).
3. Maximum-cooling recirculation: while the cooling demand is high (the ACC law's pull-down, or its demand
   >= ``door_demand_enter``, until it falls below ``door_demand_exit``) or the ambient is warmer than the cabin
   by ``door_amb_above_cab_k`` -> recirculation (share ``door_recirc_share``) (GM, Mitsubishi, Saab: recirculation
   when hot outside or when maximum cooling is not enough; US EPA credit for recirculation above 24 degC).
4. Fresh-air purge inside recirculation:
   * with a CO2 sensor (Bosch CCS 2007: recirculation whenever possible, fresh air above a CO2 threshold):
     a partial purge (share ``door_purge_share``) from ``co2_limit - door_co2_margin_ppm`` until the reading is
     below that minus ``door_co2_hysteresis_ppm``; the margin covers the sensor's accuracy (+-(30 ppm + 3 %),
     75 ppm at 1500) and its lag (t63 60 s behind a rise of up to 7.7 ppm/s with four occupants in full recirculation);
   * without one (timer, BMW/MINI: 12 min recirculation, 1 min fresh air with A/C above 6 degC): the purge share
     for ``door_timer_fresh_s`` after every ``door_timer_recirc_s`` of recirculation.
5. Otherwise (demand met): the normal share ``door_normal_share`` (production: outside air, 0).

A demand-driven switch between 3 and 5 is held at least ``door_min_dwell_s`` (no chatter); the overrides and
the purges act at once. Modes ``none`` (the door is not commanded: the plant keeps its default share) and
``fixed`` (the door held at ``door_fixed_share``, no override: the fixed-share baselines) bypass the logic.

Pure and deterministic, no ROS: ``RecircLaw(settings).step(...) -> RecircCommand``.
"""

from __future__ import annotations

import dataclasses
import math

from ceco_core.air_quality import check_settings, economiser_open, fog_override

__all__ = ["DOOR_MODES", "RecircSettings", "RecircCommand", "RecircLaw"]

DOOR_MODES = ("none", "fixed", "auto", "co2_hold")
"""How the baseline drives the door: not at all (the plant's default share), at a fixed share, by the
production logic, or by the CO2-holding door of the NMPC (``ceco_core.co2_door.Co2DoorLaw``, its default
settings: the door of ``ceco-pmv-aq`` behind a baseline's thermal law; run by the baseline, not by this
logic)."""


@dataclasses.dataclass(frozen=True)
class RecircSettings:
    """Settings of the door logic (field names prefixed ``door_``: they travel with the ACC law's overrides)."""

    door_mode: str = "none"
    """``none`` (not commanded: the plant's default share, the baseline before issue 21), ``fixed``, ``auto`` or
    ``co2_hold`` (:data:`DOOR_MODES`)."""
    door_fixed_share: float = 0.8
    """Recirculated share of mode ``fixed`` [0..1]."""
    door_recirc_share: float = 1.0
    """Share at high cooling demand [0..1] (full recirculation)."""
    door_normal_share: float = 0.0
    """Share when the demand is met [0..1] (production: outside air)."""
    door_fresh_share: float = 0.0
    """Share of the safety overrides (fog, a failed CO2 sensor) [0..1] (outside air)."""
    door_purge_share: float = 0.7
    """Share of a fresh-air purge, by CO2 or by timer [0..1]: tuned once (UDDS and SC03 with 4 occupants, grid
    0, 0.3, 0.5, 0.7, 0.8, 0.9: the least energy that keeps the CO2 under 1500 ppm on both; docs/benchmark.md);
    production cars purge with outside air (0), which costs 26 % more energy on UDDS."""
    door_demand_enter: float = 0.6
    """ACC demand at or above which the door goes to recirculation [-]."""
    door_demand_exit: float = 0.4
    """ACC demand below which it leaves recirculation [-]."""
    door_amb_above_cab_k: float = 2.0
    """Ambient warmer than the cabin by this much also means recirculation [K]."""
    door_co2_margin_ppm: float = 450.0
    """A purge starts at the CO2 limit minus this margin [ppm]: the sensor's accuracy (75 ppm at 1500 ppm) plus its
    lag on the fastest rise (4 occupants in full recirculation: 7.7 ppm/s, t63 60 s); tuned once (docs/benchmark.md:
    400 ppm before the economiser rule, which let the UDDS with four occupants reach 1503 ppm at 400)."""
    door_co2_hysteresis_ppm: float = 300.0
    """A purge ends this far below its start [ppm] (1500 -> 1200 ppm in the literature's logic)."""
    door_timer_recirc_s: float = 720.0
    """Without a CO2 sensor: recirculation time before a fresh-air purge [s] (BMW/MINI: 12 min with A/C)."""
    door_timer_fresh_s: float = 60.0
    """Without a CO2 sensor: length of the timed purge [s] (BMW/MINI: 1 min)."""
    door_fog_enter_k: float = 0.5
    """Fog override when the fog margin is below its bound plus this [K]."""
    door_fog_exit_k: float = 1.5
    """The fog override ends when the margin is back above its bound plus this [K]."""
    door_min_dwell_s: float = 30.0
    """Least time between demand-driven switches [s] (no chatter)."""
    door_economiser_k: float = 1.0
    """Outside air while the ambient is cooler than the cabin by at least this [K] (and lower in enthalpy by c_p,a
    times it where both humidities are known) (> 0; ``inf`` turns the rule off: the logic of before); the
    CO2-holding door's ``economiser_k``."""

    def validate(self) -> RecircSettings:
        """Raise ValueError naming the field if a setting is not usable; return self."""
        if self.door_mode not in DOOR_MODES:
            raise ValueError(f"RecircSettings.door_mode: must be one of {DOOR_MODES}, got {self.door_mode!r}")
        check_settings(self, skip=("door_mode", "door_economiser_k"))
        e = self.door_economiser_k
        if isinstance(e, bool) or not isinstance(e, (int, float)) or not e > 0:  # NaN fails too; inf is "off"
            raise ValueError(f"RecircSettings.door_economiser_k: must be > 0 (inf: off), got {e!r}")
        shares = ("door_fixed_share", "door_recirc_share", "door_normal_share", "door_fresh_share", "door_purge_share")
        for name in shares:
            if not getattr(self, name) <= 1.0:
                raise ValueError(f"RecircSettings.{name}: must be in [0, 1], got {getattr(self, name)}")
        if not self.door_demand_exit < self.door_demand_enter <= 1.0:
            raise ValueError("RecircSettings: must have door_demand_exit < door_demand_enter <= 1")
        if not self.door_fog_enter_k < self.door_fog_exit_k:
            raise ValueError("RecircSettings: must have door_fog_enter_k < door_fog_exit_k")
        if not (self.door_timer_recirc_s > 0 and self.door_timer_fresh_s > 0):
            raise ValueError("RecircSettings: door_timer_recirc_s and door_timer_fresh_s must be > 0")
        return self


@dataclasses.dataclass(frozen=True)
class RecircCommand:
    """The door command of one control step."""

    recirc_share: float
    """Commanded recirculated share [0..1]; NaN in mode ``none`` (not commanded)."""
    mode: str
    """Why: 'none', 'fixed', 'fog', 'co2_sensor_fault', 'co2_purge', 'timer_purge', 'recirc', 'normal'."""


class RecircLaw:
    """The door logic, stepped every control period with the ECU's inputs."""

    def __init__(self, settings: RecircSettings | None = None):
        self.settings = (settings or RecircSettings()).validate()
        self.reset()

    def reset(self) -> None:
        """Back to the key-on state (demand met, no purge, no fog override)."""
        self._recirc = False
        self._since_switch_s = math.inf
        self._co2_purge = False
        self._fog = False
        self._timer_s = 0.0
        """Time in the current phase of the timed purge cycle [s]."""
        self._timer_fresh = False

    def step(
        self,
        dt_s: float,
        *,
        demand: float,
        pulldown: bool,
        t_cab_c: float,
        t_amb_c: float,
        co2_sensor_fitted: bool,
        co2_sensor_ppm: float,
        co2_limit_ppm: float,
        fog_margin_k: float,
        fog_margin_min_k: float,
        rh_cab: float = math.nan,
        rh_amb: float = math.nan,
    ) -> RecircCommand:
        """The door command over the next ``dt_s`` [s].

        ``demand`` the ACC law's cooling demand [0..1] (``pulldown`` its maximum-cooling mode), the cabin and
        ambient air temperatures [degC], the CO2 sensor (``co2_sensor_fitted``; a NaN reading from a fitted
        sensor is a fault) [ppm] with the limit [ppm], the fog margin [K] (NaN: unknown, no override) and its bound,
        the cabin's and the ambient's relative humidity [0..1] (NaN: not measured; the economiser then judges by dry
        bulb alone).
        A non-finite demand or temperature counts as high demand unmet (recirculation is not asked for).
        """
        s = self.settings
        if s.door_mode == "none":
            return RecircCommand(math.nan, "none")
        if s.door_mode == "fixed":
            return RecircCommand(s.door_fixed_share, "fixed")
        if s.door_mode == "co2_hold":
            raise ValueError(
                "RecircLaw: door_mode 'co2_hold' is the CO2-holding door (ceco_core.co2_door), not this logic"
            )
        self._since_switch_s += dt_s
        # 1. safety overrides
        self._fog = fog_override(self._fog, fog_margin_k, fog_margin_min_k, s.door_fog_enter_k, s.door_fog_exit_k)
        if self._fog:
            return RecircCommand(s.door_fresh_share, "fog")
        if co2_sensor_fitted and not math.isfinite(co2_sensor_ppm):
            self._co2_purge = False
            return RecircCommand(s.door_fresh_share, "co2_sensor_fault")
        # 2. economiser: outside air while it is the cooler inlet
        temps_known = math.isfinite(t_amb_c) and math.isfinite(t_cab_c)
        if economiser_open(t_cab_c, t_amb_c, rh_cab, rh_amb, s.door_economiser_k):
            self._co2_purge = False
            return RecircCommand(s.door_fresh_share, "economiser")
        # 3. recirculation at high demand (switches held at least the dwell time)
        hot_outside = temps_known and t_amb_c > t_cab_c + s.door_amb_above_cab_k
        d = demand if math.isfinite(demand) else 0.0
        want = bool(pulldown) or hot_outside or d >= s.door_demand_enter or (self._recirc and d >= s.door_demand_exit)
        if want != self._recirc and self._since_switch_s >= s.door_min_dwell_s:
            self._recirc = want
            self._since_switch_s = 0.0
            self._timer_s = 0.0
            self._timer_fresh = False
        if not self._recirc:
            self._co2_purge = False
            return RecircCommand(s.door_normal_share, "normal")
        # 4. purge by CO2 or by timer
        if co2_sensor_fitted:
            start = co2_limit_ppm - s.door_co2_margin_ppm
            if co2_sensor_ppm >= start:
                self._co2_purge = True
            elif co2_sensor_ppm < start - s.door_co2_hysteresis_ppm:
                self._co2_purge = False
            if self._co2_purge:
                return RecircCommand(s.door_purge_share, "co2_purge")
            return RecircCommand(s.door_recirc_share, "recirc")
        self._timer_s += dt_s
        phase_s = s.door_timer_fresh_s if self._timer_fresh else s.door_timer_recirc_s
        if self._timer_s > phase_s:
            self._timer_fresh = not self._timer_fresh
            self._timer_s = dt_s
        if self._timer_fresh:
            return RecircCommand(s.door_purge_share, "timer_purge")
        return RecircCommand(s.door_recirc_share, "recirc")
