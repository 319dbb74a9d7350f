"""The production automatic climate control (ACC) law: the baseline and the fallback.

What a vehicle's HVAC ECU runs in cooling mode: a PI controller with
anti-windup on the cabin air temperature against a constant set-point
(26 degC, the paper's baseline), whose output, a cooling *demand*
d in [0, 1], is mapped to the two A/C actuators the way production ACCs do
(SAE J2765-style "economy-first" scheduling, e.g. Zhang, Li, Deng,
*Automotive Air Conditioning*, Springer 2016, ch. 5; Kiss & Chaney, SAE
2013-01-0850 for CoolSim's ACC):

* Evaporator set-point first: at low demand the evaporator runs warm
  (10 degC, least compressor work); it is lowered linearly to 3 degC as the
  demand rises to ``d_evap_full``.
* Blower curve: minimum flow up to ``d_blower_start``, then rising linearly
  to the maximum flow at d = 1 (blower noise and draft are the other
  constraints a production curve respects; the flow only rises once the
  evaporator is already cold).
* Pull-down: when the cabin is much warmer than the set-point
  (error > ``pulldown_enter_k``) the ACC commands maximum cooling (d = 1: 3 degC,
  0.17 kg/s) until the error falls below ``pulldown_exit_k``; it then hands
  over to the PI bumplessly (integrator preset so the demand is continuous).
* Anti-windup by back-calculation (Astrom & Hagglund, *Advanced PID control*,
  2006, sec. 3.5) with tracking time ``tt_s``.
* Bumpless transfer (Astrom & Hagglund 2006, sec. 3.6) when the law is the fallback of another
  controller: while that controller is in charge, :meth:`AccLaw.track` is given every applied
  command; the law leaves pull-down mode and presets its integrator so that its PI output is the
  demand d_a that reproduces the applied command best on its own actuator map (least squares in
  normalised units). When it takes over, the difference between the last applied command and
  its own first output is added to its outputs and decays as exp(-t / ``handover_tau_s``), so the
  actuators move continuously.

Two optional additions, off by default (the plain law above is the paper's
baseline and the plant's fallback; docs/benchmark.md, "Baselines"):

* Sun-load and ambient compensation, as production ACCs do (target outlet
  temperature from set-point, cabin, ambient and sun-load sensors, e.g. Mazda's
  "K1 T_set - K2 T_cab - K3 T_amb - K4 solar + C"; Ford EATC: "compensates high
  sun load with higher blower and reduced discharge temperatures"; Nissan: the
  sun-load reading is filtered so that a tunnel changes it slowly):

      S_f(k) = S_f(k-1) + (1 - exp(-dt/tau_sun)) (S(k) - S_f(k-1)),  S_f(0) = S(0)
      T_sp,eff = T_sp - k_sun S_f / 1000 - k_amb (T_amb - T_amb,ref)
      mdot_min,eff = min(mdot_min + k_bl S_f / 1000, mdot_max)

  with S the sun-load sensor [W/m2], T_amb the ambient sensor [degC].
* The pull-down allowance: the same permission the CECO strategies have (PMV
  may follow the occupant's relaxed upper bound ub(t) during the pull-down),
  given to the ECU as a set-point ramp over the relaxed-bound phase:

      T_sp,eff += k_allow max(0, ub(t) - ub_band)

  with k_allow [K/PMV] converting the PMV allowance into air temperature.

Comfort feedback (``feedback='pmv'``, docs/benchmark.md "Baselines"): the same PI, anti-windup,
pull-down, demand map and allowance, with the cabin PMV in place of the cabin air temperature as
the controlled variable:

    e = PMV_meas - PMV_sp                                  (cooling when e > 0)
    d = clip(K_p,PMV e + I, 0, 1),  dI/dt = K_p,PMV / T_i e + (d - v) / T_t
    pull-down while e > ``pulldown_enter_pmv`` (until e < ``pulldown_exit_pmv``)
    PMV_sp,eff = PMV_sp + k_allow,PMV max(0, ub(t) - ub_band)

with PMV_meas the scored comfort model on the controller's observation (:func:`feedback_pmv`; from
the sensors a production car has when the controller runs with ``measurements: vehicle``). The
compensations do not apply to it (the sun is already in the PMV it regulates).

Pure and deterministic, no ROS; stateful object with ``reset()`` and
``step(t_cab_c, dt_s)`` (``step(t_cab_c, dt_s, pmv=...)`` in the PMV mode). A non-finite measurement
never crashes the ECU: the last command is held and the output says ``mode='sensor_fault'``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["FEEDBACKS", "AccSettings", "AccCommand", "AccLaw", "feedback_pmv"]

FEEDBACKS = ("cabin_temperature", "pmv")
"""Controlled variables of the law: the cabin air temperature (production) or the cabin PMV."""


@dataclasses.dataclass(frozen=True)
class AccSettings:
    """Settings of the production ACC law (defaults: tuned on the ceco plant, docs/controller.md)."""

    setpoint_c: float = 26.0
    """Cabin air temperature set-point [degC] (the paper's baseline)."""
    kp_per_k: float = 0.25
    """Proportional gain: demand per kelvin of error [1/K]."""
    ti_s: float = 120.0
    """Integral time [s]."""
    tt_s: float = 60.0
    """Anti-windup back-calculation tracking time [s]."""
    pulldown_enter_k: float = 4.0
    """Error above which maximum cooling (pull-down mode) is commanded [K]."""
    pulldown_exit_k: float = 2.0
    """Error below which the pull-down mode hands over to the PI [K]."""
    d_evap_full: float = 0.5
    """Demand at which the evaporator set-point reaches its minimum [-]."""
    d_blower_start: float = 0.3
    """Demand above which the blower flow rises from its minimum [-]."""
    mdot_bl_min_kgps: float = 0.05
    """Minimum blower flow [kg/s] (paper's actuator bound)."""
    mdot_bl_max_kgps: float = 0.17
    """Maximum blower flow [kg/s] (paper's actuator bound)."""
    t_evap_sp_min_c: float = 3.0
    """Coldest evaporator set-point [degC] (frost protection)."""
    t_evap_sp_max_c: float = 10.0
    """Warmest evaporator set-point [degC]."""
    allowance_k_per_pmv: float = 0.0
    """Pull-down allowance k_allow: set-point rise per PMV of relaxation of the upper bound [K/PMV] (0: off)."""
    band_ub_pmv: float = 0.5
    """Upper PMV bound of the comfort band; only a bound above it is a relaxation [-]."""
    sun_gain_k_per_kwm2: float = 0.0
    """Sun-load compensation k_sun: set-point lowered per kW/m2 of filtered sun load [K/(kW/m2)] (0: off)."""
    ambient_gain_k_per_k: float = 0.0
    """Ambient compensation k_amb: set-point lowered per kelvin of ambient above ambient_ref_c [K/K] (0: off)."""
    ambient_ref_c: float = 25.0
    """Ambient temperature at which the ambient compensation is zero [degC]."""
    sun_blower_gain_kgps_per_kwm2: float = 0.0
    """Sun-load blower compensation k_bl: rise of the minimum blower flow per kW/m2 [(kg/s)/(kW/m2)] (0: off)."""
    sun_filter_tau_s: float = 20.0
    """Time constant of the first-order filter on the sun-load sensor [s]."""
    handover_tau_s: float = 30.0
    """Time constant of the decay of the command difference at a bumpless take-over [s]."""
    feedback: str = "cabin_temperature"
    """Controlled variable: 'cabin_temperature' (production law) or 'pmv' (comfort feedback) [-]."""
    setpoint_pmv: float = 0.0
    """PMV set-point of the comfort-feedback law [-] (feedback 'pmv')."""
    kp_per_pmv: float = 0.8
    """Proportional gain of the comfort-feedback law: demand per unit of PMV error [1/PMV]
    (0.8 ~ kp_per_k / 0.32 PMV/K, the production gain through the plant's set-point sensitivity)."""
    pulldown_enter_pmv: float = 1.2
    """Comfort feedback: PMV error above which maximum cooling is commanded [-] (~4 K x 0.3 PMV/K)."""
    pulldown_exit_pmv: float = 0.6
    """Comfort feedback: PMV error below which the pull-down hands over to the PI [-] (~2 K x 0.3 PMV/K)."""
    allowance_pmv_per_pmv: float = 0.0
    """Comfort feedback: PMV set-point rise per PMV of relaxation of the upper bound [-] (0: off)."""

    @property
    def compensated(self) -> bool:
        """True when any sun-load or ambient compensation gain is non-zero."""
        return bool(self.sun_gain_k_per_kwm2 or self.ambient_gain_k_per_k or self.sun_blower_gain_kgps_per_kwm2)

    def validate(self) -> None:
        """Raise ValueError naming the field if a setting is not usable."""
        if self.feedback not in FEEDBACKS:
            raise ValueError(f"AccSettings.feedback must be one of {FEEDBACKS}, got {self.feedback!r}")
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "feedback":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"AccSettings.{f.name} must be a finite number, got {v!r}")
        for name in ("kp_per_k", "kp_per_pmv", "ti_s", "tt_s", "handover_tau_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"AccSettings.{name} must be > 0")
        if not 0.0 <= self.pulldown_exit_k < self.pulldown_enter_k:
            raise ValueError("AccSettings.pulldown_exit_k must satisfy 0 <= exit < pulldown_enter_k")
        if not 0.0 < self.d_evap_full <= 1.0:
            raise ValueError("AccSettings.d_evap_full must be in (0, 1]")
        if not 0.0 <= self.d_blower_start < 1.0:
            raise ValueError("AccSettings.d_blower_start must be in [0, 1)")
        if not 0.0 < self.mdot_bl_min_kgps < self.mdot_bl_max_kgps:
            raise ValueError("AccSettings.mdot_bl_min_kgps must satisfy 0 < min < mdot_bl_max_kgps")
        if not self.t_evap_sp_min_c < self.t_evap_sp_max_c:
            raise ValueError("AccSettings.t_evap_sp_min_c must be < t_evap_sp_max_c")
        if not 0.0 <= self.pulldown_exit_pmv < self.pulldown_enter_pmv:
            raise ValueError("AccSettings.pulldown_exit_pmv must satisfy 0 <= exit < pulldown_enter_pmv")
        if not -3.0 <= self.setpoint_pmv <= 3.0:
            raise ValueError(f"AccSettings.setpoint_pmv must be in [-3, 3] (the PMV scale), got {self.setpoint_pmv}")
        if self.feedback == "pmv" and self.compensated:
            raise ValueError(
                "AccSettings: the sun/ambient compensation gains apply to feedback 'cabin_temperature' only "
                "(the PMV already contains the sun and the surfaces); set them to 0 with feedback 'pmv'"
            )
        for name in ("allowance_k_per_pmv", "allowance_pmv_per_pmv", "sun_blower_gain_kgps_per_kwm2"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"AccSettings.{name} must be >= 0")
        if not self.sun_filter_tau_s > 0.0:
            raise ValueError("AccSettings.sun_filter_tau_s must be > 0")


@dataclasses.dataclass(frozen=True)
class AccCommand:
    """Output of the ACC law: the two actuator commands and the internal demand."""

    mdot_bl_kgps: float
    """Blower air mass flow [kg/s]."""
    t_evap_sp_c: float
    """Evaporator wall temperature set-point [degC]."""
    demand: float
    """Cooling demand d in [0, 1] [-]."""
    mode: str
    """'pulldown', 'pi', 'sensor_fault' or 'tracking' (another controller in charge)."""
    setpoint_c: float = math.nan
    """Effective cabin set-point of this step (after compensation and allowance) [degC]; NaN with feedback 'pmv'."""
    setpoint_pmv: float = math.nan
    """Effective PMV set-point of this step (after the allowance) [-]; NaN with feedback 'cabin_temperature'."""


class AccLaw:
    """PI with anti-windup on cabin air temperature, mapped to blower and evaporator."""

    def __init__(self, settings: AccSettings | None = None):
        self.settings = settings or AccSettings()
        self.settings.validate()
        self.reset()

    def reset(self) -> None:
        """Back to the key-on state: integrator empty, pull-down armed, sun filter empty."""
        self._integral = 0.0
        self._pulldown = False
        self._sun_f: float | None = None
        self._mdot_min = self.settings.mdot_bl_min_kgps
        self._last = self.map_demand(1.0, "pulldown")
        self._raw = self._last  # the law's own last output (without the take-over offset)
        self._tracking = False  # another controller applied the last command
        self._offset = np.zeros(2)  # bumpless take-over: decaying (mdot, sp) difference

    def map_demand(self, demand: float, mode: str = "pi") -> AccCommand:
        """Map a demand in [0, 1] to (blower flow, evaporator set-point)."""
        s = self.settings
        d = float(np.clip(demand, 0.0, 1.0))
        f_evap = min(d / s.d_evap_full, 1.0)
        t_sp = s.t_evap_sp_max_c - f_evap * (s.t_evap_sp_max_c - s.t_evap_sp_min_c)
        f_bl = max(d - s.d_blower_start, 0.0) / (1.0 - s.d_blower_start)
        mdot = self._mdot_min + f_bl * (s.mdot_bl_max_kgps - self._mdot_min)
        return AccCommand(mdot_bl_kgps=mdot, t_evap_sp_c=t_sp, demand=d, mode=mode)

    def effective_setpoint_c(self, dt_s: float, t_amb_c=None, solar_wm2=None, pmv_ub=None) -> float:
        """The set-point of this step after compensation and allowance [degC] (module docstring).

        Updates the sun-load filter and the compensated blower floor. A missing or
        non-finite sensor reading contributes no compensation; no term is evaluated
        when its gain is 0, so the plain law is unchanged bit for bit.
        """
        s = self.settings
        sp = s.setpoint_c
        if s.sun_gain_k_per_kwm2 or s.sun_blower_gain_kgps_per_kwm2:
            if solar_wm2 is not None and math.isfinite(float(solar_wm2)):
                if self._sun_f is None:
                    self._sun_f = float(solar_wm2)
                else:
                    self._sun_f += -math.expm1(-dt_s / s.sun_filter_tau_s) * (float(solar_wm2) - self._sun_f)
            if self._sun_f is not None:
                sp -= s.sun_gain_k_per_kwm2 * self._sun_f / 1000.0
                self._mdot_min = min(
                    s.mdot_bl_min_kgps + s.sun_blower_gain_kgps_per_kwm2 * self._sun_f / 1000.0, s.mdot_bl_max_kgps
                )
        if s.ambient_gain_k_per_k and t_amb_c is not None and math.isfinite(float(t_amb_c)):
            sp -= s.ambient_gain_k_per_k * (float(t_amb_c) - s.ambient_ref_c)
        if s.allowance_k_per_pmv and pmv_ub is not None and math.isfinite(float(pmv_ub)):
            sp += s.allowance_k_per_pmv * max(0.0, float(pmv_ub) - s.band_ub_pmv)
        return sp

    def effective_setpoint_pmv(self, pmv_ub=None) -> float:
        """The PMV set-point of this step after the allowance [-] (feedback 'pmv')."""
        s = self.settings
        sp = s.setpoint_pmv
        if s.allowance_pmv_per_pmv and pmv_ub is not None and math.isfinite(float(pmv_ub)):
            sp += s.allowance_pmv_per_pmv * max(0.0, float(pmv_ub) - s.band_ub_pmv)
        return sp

    def _loop(self, dt_s, t_cab_c, pmv, t_amb_c, solar_wm2, pmv_ub):
        """(measured y, set-point, kp, pull-down enter, exit) of the controlled variable of this step.

        y is NaN where its sensor reading is missing or not finite.
        """
        s = self.settings
        y = self._measured(t_cab_c, pmv)
        if not math.isfinite(y):  # a fault step leaves the compensation filter as it is
            return y, math.nan, math.nan, math.nan, math.nan
        if s.feedback == "pmv":
            return y, self.effective_setpoint_pmv(pmv_ub), s.kp_per_pmv, s.pulldown_enter_pmv, s.pulldown_exit_pmv
        sp = self.effective_setpoint_c(dt_s, t_amb_c, solar_wm2, pmv_ub)
        return y, sp, s.kp_per_k, s.pulldown_enter_k, s.pulldown_exit_k

    def _measured(self, t_cab_c, pmv) -> float:
        """The controlled variable's reading (cabin temperature [degC] or PMV [-]); NaN if unusable."""
        v = pmv if self.settings.feedback == "pmv" else t_cab_c
        try:
            return math.nan if v is None else float(v)
        except (TypeError, ValueError):
            return math.nan

    def _with_setpoint(self, cmd: AccCommand, sp: float) -> AccCommand:
        if self.settings.feedback == "pmv":
            return dataclasses.replace(cmd, setpoint_pmv=sp)
        return dataclasses.replace(cmd, setpoint_c=sp)

    def demand_of(self, mdot_bl_kgps: float, t_evap_sp_c: float) -> float:
        """The demand whose mapped command is nearest to (mdot_bl [kg/s], T_evap_sp [degC]).

        Distance in units normalised by the actuator ranges; the map is piecewise linear, so the
        minimum is exact per piece.
        """
        s = self.settings
        target = self._normalised(mdot_bl_kgps, t_evap_sp_c)
        knots = sorted({0.0, s.d_blower_start, s.d_evap_full, 1.0})

        def point(d):
            c = self.map_demand(d)
            return self._normalised(c.mdot_bl_kgps, c.t_evap_sp_c)

        best_d, best_e = 0.0, math.inf
        for a, b in zip(knots[:-1], knots[1:]):
            pa, pb = point(a), point(b)
            seg = pb - pa
            t = float(np.clip(np.dot(target - pa, seg) / max(float(np.dot(seg, seg)), 1e-300), 0.0, 1.0))
            e = float(np.sum((pa + t * seg - target) ** 2))
            if e < best_e:
                best_d, best_e = a + t * (b - a), e
        return best_d

    def _normalised(self, mdot, sp) -> np.ndarray:
        s = self.settings
        return np.array(
            [
                (mdot - s.mdot_bl_min_kgps) / (s.mdot_bl_max_kgps - s.mdot_bl_min_kgps),
                (s.t_evap_sp_max_c - sp) / (s.t_evap_sp_max_c - s.t_evap_sp_min_c),
            ]
        )

    def track(
        self,
        mdot_bl_kgps: float,
        t_evap_sp_c: float,
        t_cab_c: float | None = None,
        *,
        dt_s: float | None = None,
        t_amb_c: float | None = None,
        solar_wm2: float | None = None,
        pmv_ub: float | None = None,
        pmv: float | None = None,
    ) -> None:
        """Follow a command another controller applied, so that a later :meth:`step` takes over without a bump.

        (mdot_bl [kg/s], T_evap_sp [degC]) applied at cabin air temperature ``t_cab_c`` [degC]
        (feedback 'pmv': at the measured PMV ``pmv`` [-]); with ``dt_s`` the compensations'
        sensors are followed too (the sun filter stays warm) and the integrator is preset against
        the effective set-point. Non-finite commands are ignored; a non-finite measurement leaves
        the integrator as it is.
        """
        if not (math.isfinite(float(mdot_bl_kgps)) and math.isfinite(float(t_evap_sp_c))):
            return
        s = self.settings
        if dt_s is not None and math.isfinite(dt_s) and dt_s > 0:
            y, sp_eff, kp, _, _ = self._loop(dt_s, t_cab_c, pmv, t_amb_c, solar_wm2, pmv_ub)
        else:
            y = self._measured(t_cab_c, pmv)
            kp = s.kp_per_pmv if s.feedback == "pmv" else s.kp_per_k
            sp_eff = s.setpoint_pmv if s.feedback == "pmv" else s.setpoint_c
        mdot = min(max(float(mdot_bl_kgps), s.mdot_bl_min_kgps), s.mdot_bl_max_kgps)
        sp = min(max(float(t_evap_sp_c), s.t_evap_sp_min_c), s.t_evap_sp_max_c)
        d = self.demand_of(mdot, sp)
        self._pulldown = False
        if math.isfinite(y):
            self._integral = d - kp * (y - sp_eff)
        self._last = self._raw = self._with_setpoint(
            AccCommand(mdot_bl_kgps=mdot, t_evap_sp_c=sp, demand=d, mode="tracking"), sp_eff
        )
        self._tracking = True
        self._offset = np.zeros(2)

    def step(
        self,
        t_cab_c: float,
        dt_s: float,
        *,
        t_amb_c: float | None = None,
        solar_wm2: float | None = None,
        pmv_ub: float | None = None,
        pmv: float | None = None,
    ) -> AccCommand:
        """One ECU step.

        Args:
            t_cab_c: measured cabin air temperature [degC] (the controlled variable of the production law).
            dt_s: step length [s].
            t_amb_c: ambient temperature sensor [degC] (used by the ambient compensation only).
            solar_wm2: sun-load sensor [W/m2] (used by the sun-load compensation only).
            pmv_ub: the occupant's upper PMV bound now [-] (used by the allowance only).
            pmv: the measured cabin PMV [-] (:func:`feedback_pmv`; the controlled
                variable with feedback 'pmv', ignored otherwise).
        """
        if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"AccLaw.step: dt_s must be a finite number > 0, got {dt_s!r}")
        applied = self._last if self._tracking else None
        self._tracking = False
        cmd = self._raw = self._law_step(t_cab_c, dt_s, t_amb_c, solar_wm2, pmv_ub, pmv)
        if applied is not None:  # take-over: start from the applied command
            self._offset = np.array([applied.mdot_bl_kgps - cmd.mdot_bl_kgps, applied.t_evap_sp_c - cmd.t_evap_sp_c])
        elif np.any(self._offset):
            self._offset = self._offset * math.exp(-dt_s / self.settings.handover_tau_s)
            if np.all(np.abs(self._offset) < 1e-9):
                self._offset = np.zeros(2)
        if np.any(self._offset):
            s = self.settings
            cmd = dataclasses.replace(
                cmd,
                mdot_bl_kgps=min(max(cmd.mdot_bl_kgps + self._offset[0], s.mdot_bl_min_kgps), s.mdot_bl_max_kgps),
                t_evap_sp_c=min(max(cmd.t_evap_sp_c + self._offset[1], s.t_evap_sp_min_c), s.t_evap_sp_max_c),
            )
        self._last = cmd
        return cmd

    def _law_step(self, t_cab_c, dt_s, t_amb_c, solar_wm2, pmv_ub, pmv=None) -> AccCommand:
        """The law itself (PI, pull-down, sensor fault), without the take-over offset."""
        y, sp, kp, enter, leave = self._loop(dt_s, t_cab_c, pmv, t_amb_c, solar_wm2, pmv_ub)
        if not math.isfinite(y):
            return dataclasses.replace(self._raw, mode="sensor_fault")
        s = self.settings
        err = y - sp  # > 0: cabin too warm
        if self._pulldown and err < leave:
            self._pulldown = False
            # bumpless hand-over: PI output equals the current demand (1)
            self._integral = 1.0 - kp * err
        elif not self._pulldown and err > enter:
            self._pulldown = True
        if self._pulldown:
            return self._with_setpoint(self.map_demand(1.0, "pulldown"), sp)
        v = kp * err + self._integral
        d = min(max(v, 0.0), 1.0)
        # integrate with back-calculation anti-windup
        self._integral += dt_s * (kp / s.ti_s * err + (d - v) / s.tt_s)
        return self._with_setpoint(self.map_demand(d, "pi"), sp)


def feedback_pmv(
    *,
    t_cab_c,
    t_vent_c,
    t_int_c,
    t_shell_c,
    t_glass_c,
    rh_cab,
    mdot_bl_kgps,
    solar_wm2,
    params,
    pa_pa=None,
    pmv_fn=None,
    t_mr_c=None,
):
    """The cabin PMV the comfort-feedback law regulates [-]: the scored comfort model on the controller's observation.

    ISO 7730 PMV + absorbed sun at the occupant (:func:`ceco_core.cabin_comfort.cabin_pmv`) from the
    cabin air ``t_cab_c`` and vent air ``t_vent_c`` temperatures [degC], the mean radiant temperature
    of the interior, shell and glazing temperatures ``t_int_c``, ``t_shell_c``, ``t_glass_c`` [degC]
    (:func:`~ceco_core.cabin_comfort.cabin_mrt_c`), the cabin humidity ``rh_cab`` [0..1] (vapour
    pressure rh * p_ws(T_cab)), the blower flow the ECU commands ``mdot_bl_kgps`` [kg/s] and the
    sun-load sensor ``solar_wm2`` [W/m2] through SolarCal with the scenario's sun position
    (``params``: :class:`~ceco_core.cabin_comfort.ComfortParams`, occupant met/clo too).

    No car measures its surfaces: with the controllers' ``measurements: vehicle`` (as the benchmark
    runs the PMV families) T_int, T_shell and T_glass are the estimator's, from the sensors a
    production car has (``ceco_controller.estimator``: cabin air, vent air, evaporator, ambient, sun
    load, speed, cabin humidity). ``pa_pa`` [Pa]: the cabin's vapour pressure in place of rh_cab's (None:
    from ``rh_cab``; ``ceco_controller.comfort_feedback.measured_pmv`` passes the paper's 1700 Pa where the
    humidity is not measured). Returns NaN when an input is missing or not finite (the law then holds its
    command). ``pmv_fn``: an evaluator of ``cabin_pmv`` at ``params`` called as ``pmv_fn(t_cab_c, t_vent_c,
    mdot_bl_kgps, t_mr_c, w_rad_wm2, pa_pa)`` (the controllers' compiled one,
    ``ceco_controller.pmv_function.CabinPmvFunction``); None: ``cabin_pmv`` on numpy. ``t_mr_c`` [degC]: the mean
    radiant temperature of these interior, shell and glazing temperatures when the caller has computed it
    (``cabin_mrt_c``, the same equation; ceco-pmv's step has it for its NLP); None: computed here.
    """
    from ceco_core import psychro
    from ceco_core.cabin_comfort import cabin_mrt_c, cabin_pmv, cabin_w_rad_wm2

    vals = (t_cab_c, t_vent_c, t_int_c, t_shell_c, t_glass_c, mdot_bl_kgps, solar_wm2)
    try:
        t_cab, t_vent, t_int, t_shell, t_glass, mdot, solar = (float(v) for v in vals)
        humidity = float(rh_cab if pa_pa is None else pa_pa)  # the RH [-], or the vapour pressure given [Pa]
    except (TypeError, ValueError):
        return math.nan
    finite = all(math.isfinite(v) for v in (t_cab, t_vent, t_int, t_shell, t_glass, mdot, solar, humidity))
    if not finite or mdot < 0.0 or humidity < 0.0 or (pa_pa is None and humidity > 1.0):
        return math.nan
    pa = humidity if pa_pa is not None else float(psychro.vapour_pressure_pa(t_cab, humidity))
    if t_mr_c is None:
        t_mr = float(cabin_mrt_c(t_cab_c=t_cab, t_int_c=t_int, t_shell_c=t_shell, t_glass_c=t_glass, params=params))
    else:
        t_mr = float(t_mr_c)
    w_rad = float(cabin_w_rad_wm2(max(solar, 0.0), params))
    if pmv_fn is not None:
        return float(pmv_fn(t_cab, t_vent, mdot, t_mr, w_rad, pa))
    return float(
        cabin_pmv(
            t_cab_c=t_cab, t_vent_c=t_vent, mdot_bl_kgps=mdot, t_mr_c=t_mr, w_rad_wm2=w_rad, pa_pa=pa, params=params
        )
    )
