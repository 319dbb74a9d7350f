"""Cabin state estimator for the vehicle-sensor measurement mode (``measurements: vehicle``).

A production car measures the cabin air temperature, the vent (duct) air
temperature, the evaporator temperature, the ambient temperature, the sun load,
the vehicle speed and the cabin relative humidity (:data:`VEHICLE_SENSORS`). The
NMPC's model (docs/controller.md, eqs. 1-3) and its comfort model (T_mr from the
interior, shell-trim and glazing temperatures) also need the interior-mass
temperature T_int, the shell temperature T_shell and the glazing temperature
T_glass, which no production car measures. This module estimates them with an
extended Kalman filter (EKF) on the control-oriented model augmented with
first-order thermal states, so that a complete :class:`Observation` can be
handed to the unchanged NMPC or baseline (:class:`ceco_controller.estimating_controller.EstimatingController`).

State x = (T_cab, T_int, T_shell, T_glass, T_duct [degC], b_vent [K]); one model
step is ``ts_s`` = 5 s (the step the model was identified at). Over step k -> k+1
the inputs are held: the blower flow m = mdot_bl,k [kg/s] (the command applied
over the step), the evaporator temperature (measured at both ends, T_ev,k and
T_ev,k+1; T_ev,mid their mean [degC]), the ambient T_amb [degC], the sun load G
[W/m2] and the speed V [m/s]; f(m) = (m / m_ref)^0.8, m_ref = 0.1 kg/s.

    (E3) T_vent = T_ev + v1 (T_cab - T_ev) + v2 (T_cab - T_ev) m + v3 (T_amb - T_ev) + v4 (T_amb - T_ev) m
                  + v5 (T_duct - T_ev) + v6 (T_duct - T_ev) m + v7 / m + v8 + v9 m^2
    (1)  T_cab(k+1) = T_cab + g1 (T_int - T_cab) + g2 (T_shell - T_cab) + g3 (T_ain - T_cab) m + tau1,
                      T_ain = E3 at T_ev,mid                                    (model.t_cab_next_c)
    (E1) T_int(k+1) = T_int + (a1 + a2 f(m)) (T_cab - T_int) + a3 (T_shell - T_int) + a4 (T_glass - T_int)
                      + a5 G + a6 (T_duct - T_int)
    (E2) T_shell(k+1) = T_shell + b1 (T_cab - T_shell) + b2 (T_int - T_shell) + (b3 + b4 V^0.8)(T_amb - T_shell)
                      + b5 G
    (E4) T_glass(k+1) = T_glass + (c1 + c2 f(m)) (T_cab - T_glass) + c3 (T_int - T_glass)
                      + (c4 + c5 V^0.8)(T_amb - T_glass) + c6 G
    (E5) T_duct(k+1) = T_duct + e1 (T_int - T_duct) + (e2 m + e3 m^2)(T_ev,mid - T_duct)
                      + e4 m (T_cab - T_ev,mid) + e5 m (T_amb - T_ev,mid)
    (B)  b_vent(k+1) = b_vent                                                  (random walk)

Measurements at k+1: y = (T_cab, T_vent), h(x) = (T_cab, E3 at T_ev,k+1 with m = mdot_bl,k, + b_vent).

Where: g1, g2 [-], g3 [s/kg], tau1 [K] are the identified eq. (1) of the NMPC
(``ControlModelParams``). E1, the interior mass (seats, instrument panel, trim):
solar gain through the glazing (a5 [K/(W/m2)] per step), natural + forced
convection with the cabin air (a1, a2 [-]; h ~ m^0.8), radiation to the shell
and glazing (a3, a4 [-]), conduction to the HVAC case and ducts behind the panel
(a6 [-]). E2, the shell: solar gain (b5), the cabin air (b1), radiation from the
interior (b2), natural and speed-driven convection to the ambient (b3 [-],
b4 [(m/s)^-0.8]; h_out ~ V^0.8). E4, the glazing: the same terms (c1..c6). E5,
the HVAC case and duct walls: heated by the panel (e1 [-]), cooled by the supply
air, whose exchange grows with the flow (e2 [s/kg], e3 [s^2/kg^2]; the
evaporator-outlet air is T_ev plus the bypassed share of the recirculated and
fresh air, e4, e5 [s/kg]). E3, the vent air: the evaporator-outlet air (bypass
v1..v4 [-, s/kg]) that picks up a flow-dependent share of the duct-wall
temperature (v5 [-], v6 [s/kg]) and the blower heat (v7 [K kg/s], v9 [K s^2/kg^2]),
v8 [K] an offset. E3 and E5 are what make T_int observable apart from T_shell:
T_cab (eq. 1) sees only g1 T_int + g2 T_shell, the vent air sees the duct wall
(dT_vent/dT_duct = v5 + v6 m = 0.18-0.22), whose temperature follows the panel.
b_vent is the offset of the vent-air channel: the vent and evaporator sensors'
tolerances (NTC, +-0.5 K) and E3's local error; without it a 0.5 K vent-sensor
offset is read as several kelvin of T_int (docs/controller.md section 5.4).
The coefficients are identified by least squares from the excitation runs of
the NMPC model, recorded with the glazing and duct temperatures
(``ceco_controller.estimator_id``), like a calibration on a test vehicle
instrumented with thermocouples. Validity: the identification range (blower
0.05-0.17 kg/s, T_amb 28-35 degC, G 300-850 W/m2, V 0-36 m/s, cabin 20-60 degC).

Noise (additive, Gaussian, white): process std per model step q = (q_cab,
q_int, q_shell, q_glass, q_duct) identified from the models' prediction errors on
the training data (``ceco_controller.estimator_id``; docs/controller.md section
5), q_b and the prior of b_vent from the sensor tolerance, measurement std
r = (r_cab, r_vent) from the sensor accuracy and, for T_vent, E3's residual and
the evaporator sensor's noise through dE3/dT_ev (``EstimatorSettings``).

Every model function evaluates numpy and CasADi alike (``ceco_core.mathops``);
the filter builds CasADi Functions of the step and its Jacobians once and
evaluates them numerically. Deterministic: no randomness, no clock.
Missing data (NaN, inf, outside the physical range) never produce NaN
estimates: a missing T_cab or T_vent skips that measurement update, a missing
T_evap is predicted by eq. (2) (and the vent update skipped), a missing ambient,
sun load or speed holds the last valid value, and every substitution is flagged
in :class:`Estimate`.

Pure logic: numpy, CasADi, dataclasses; no ROS, no plant.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import casadi
import numpy as np

from ceco_core.contracts import ACTUATOR_LIMITS, MEASUREMENT_MODES
from ceco_core.observation_check import OBSERVATION_LIMITS

from . import estimator_model as _estimator_model
from . import model as cm
from .estimator_model import *  # noqa: F403 - this module re-exports estimator_model's API (__all__)
from .estimator_model import (
    EstimatorParams,
    EstimatorSettings,
    load_estimator_params,
    process_step,
    t_vent_c,
)

__all__ = [
    "VEHICLE_SENSORS",
    "ESTIMATED_STATES",
    "MEASUREMENT_MODES",
    "Estimate",
    "CabinStateEstimator",
    "ESTIMATION_SETTLE_S",
    "estimation_errors",
    *_estimator_model.__all__,
]

VEHICLE_SENSORS = ("t_cab_c", "t_vent_c", "t_evap_c", "t_amb_c", "solar_wm2", "speed_mps", "rh_cab")
"""What a production car measures [degC, W/m2, m/s, rh_cab 0..1]: cabin air (aspirated sensor),
vent (duct) air, evaporator, ambient, the sun-load sensor, the vehicle speed, cabin RH."""

ESTIMATED_STATES = ("t_cab_c", "t_int_c", "t_shell_c", "t_glass_c", "t_duct_c", "b_vent_k")
"""The filter's state vector x [degC x 5, K]."""
_N = len(ESTIMATED_STATES)
_B = _N - 1  # index of b_vent

_RANGES = {
    "t_cab_c": OBSERVATION_LIMITS.temperature_c,
    "t_vent_c": OBSERVATION_LIMITS.temperature_c,
    "t_evap_c": OBSERVATION_LIMITS.temperature_c,
    "t_amb_c": OBSERVATION_LIMITS.ambient_c,
    "solar_wm2": OBSERVATION_LIMITS.solar_wm2,
    "speed_mps": OBSERVATION_LIMITS.speed_mps,
    "rh_cab": OBSERVATION_LIMITS.rh,
}
"""Plausible range of each sensor: the NMPC's own (``ceco_core.observation_check``), so a sample
means the same in both measurement modes; outside it a sample counts as missing."""
_NON_NEGATIVE = ("solar_wm2", "speed_mps")
"""Plausible but negative samples (sensor offsets, reverse) enter the model at 0, as in the NMPC."""


# ---------------------------------------------------------------------------
# The filter
# ---------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Estimate:
    """The estimator's output at one control step.

    Every value is finite (``rh_cab``: NaN until measured); substitutions are flagged.
    """

    t_s: float
    """Time of the estimate [s]."""
    t_cab_c: float
    """Cabin air temperature [degC]: the sample if valid, else the filter's prediction."""
    t_int_c: float
    """Estimated interior-mass temperature [degC]."""
    t_shell_c: float
    """Estimated shell temperature [degC]."""
    t_glass_c: float
    """Estimated glazing temperature [degC]."""
    t_duct_c: float
    """Estimated HVAC case and duct wall temperature [degC]."""
    t_evap_c: float
    """Evaporator temperature [degC]: the sample if valid, else predicted by eq. (2)."""
    t_vent_c: float
    """Vent air temperature [degC]: the sample if valid, else predicted by E3."""
    t_amb_c: float
    """Ambient temperature [degC]: the sample if valid, else the last valid one."""
    solar_wm2: float
    """Sun load [W/m2]: the sample if valid, else the last valid one."""
    speed_mps: float
    """Vehicle speed [m/s]: the sample if valid, else the last valid one."""
    rh_cab: float
    """Cabin relative humidity [0..1]: the sample if valid, else the last valid one; NaN before the first
    valid sample (the Observation's "not measured"; the only field that can be NaN). Not used by the filter."""
    mdot_bl_prev_kgps: float
    """Blower flow taken as applied over the last step [kg/s] (the last valid one if the input was not)."""
    t_evap_sp_prev_c: float
    """Evaporator set-point taken as applied over the last step [degC] (idem)."""
    vent_bias_k: float
    """Estimated offset of the vent-air channel b_vent [K]."""
    std_k: tuple
    """1-sigma uncertainty of the state (T_cab, T_int, T_shell, T_glass, T_duct, b_vent) [K]."""
    missing: tuple
    """Names of the inputs that were missing or invalid this step (sensors and previous command)."""
    valid: bool
    """False before the first valid cabin air sample and after ``max_dead_reckoning_s`` without one."""
    dead_reckoning_s: float
    """Time since the last valid cabin air temperature sample [s] (0 when this one is valid)."""
    initialized: bool
    """True on the step the filter was (re)initialized from the sample (key-on, gap, time jump)."""

    def describe(self) -> str:
        """One line for diagnostics ('' when nothing is flagged)."""
        parts = []
        if self.missing:
            parts.append("missing " + ",".join(self.missing))
        if self.dead_reckoning_s > 0:
            parts.append(f"cabin air predicted for {self.dead_reckoning_s:.0f} s")
        if not self.valid:
            parts.append("estimate invalid")
        if self.initialized and self.t_s > 0:
            parts.append("re-initialized")
        return "estimator: " + "; ".join(parts) if parts else ""


class CabinStateEstimator:
    """Extended Kalman filter for (T_cab, T_int, T_shell) from the vehicle sensors.

    Args:
        model_params: the NMPC's identified :class:`ControlModelParams` (eq. 1, eq. 2).
        params: identified :class:`EstimatorParams` (E1-E3, process noise); default: the file.
        settings: :class:`EstimatorSettings`.
        control_period_s: period of :meth:`update` calls [s], a whole multiple of the model step.

    Call :meth:`update` once per control step with the samples at ``t_s`` and the command
    applied since the previous call; it returns an :class:`Estimate`.
    """

    def __init__(
        self,
        model_params: cm.ControlModelParams | None = None,
        params: EstimatorParams | None = None,
        settings: EstimatorSettings | None = None,
        control_period_s: float = 5.0,
    ):
        self.model_params = model_params if model_params is not None else cm.load_params()
        self.model_params.validate()
        self.params = (params if params is not None else load_estimator_params()).validate()
        self.settings = (settings or EstimatorSettings()).validate()
        if abs(self.params.ts_s - self.model_params.ts_s) > 1e-9:
            raise ValueError(
                f"EstimatorParams.ts_s {self.params.ts_s} s differs from the model step {self.model_params.ts_s} s"
            )
        self.n_sub = cm.substeps(self.model_params, control_period_s)
        self.control_period_s = float(control_period_s)
        p, q, s = self.model_params, self.params, self.settings
        x = casadi.SX.sym("x", _N)
        u = casadi.SX.sym("u", 6)  # mdot, t_evap0, t_evap1, t_amb, solar, speed
        xn = casadi.vertcat(*process_step(p, q, x, u[0], u[1], u[2], u[3], u[4], u[5]), x[_B])
        self._f = casadi.Function("est_f", [x, u], [xn, casadi.jacobian(xn, x)])
        yv = t_vent_c(q, u[2], x[0], x[4], u[3], u[0]) + x[_B]
        self._h_vent = casadi.Function("est_h_vent", [x, u], [yv, casadi.jacobian(yv, x), casadi.jacobian(yv, u[2])])
        self._q = np.diag(
            np.append(
                s.process_std_scale * np.array([q.q_cab_k, q.q_int_k, q.q_shell_k, q.q_glass_k, q.q_duct_k]),
                s.vent_bias_drift_k,
            )
            ** 2
        )
        self._r_cab = s.sensor_std_t_cab_k**2
        self._r_vent = s.sensor_std_t_vent_k**2 + q.vent_residual_k**2  # + the evaporator sensor's, per step
        self.reset()

    def reset(self) -> None:
        """Back to key-on: no state, no held values."""
        self._x: np.ndarray | None = None
        self._p: np.ndarray | None = None
        self._t_last: float | None = None
        self._t_cab_valid_s: float | None = None
        self._held: dict = {}
        self._u_prev = (ACTUATOR_LIMITS.mdot_bl_max_kgps, ACTUATOR_LIMITS.t_evap_sp_min_c)

    @property
    def state(self) -> np.ndarray | None:
        """The filter state (:data:`ESTIMATED_STATES`), None before initialization."""
        return None if self._x is None else self._x.copy()

    @property
    def covariance(self) -> np.ndarray | None:
        """The state covariance [K^2], None before initialization."""
        return None if self._p is None else self._p.copy()

    # -------------------------------------------------------------- inputs
    @staticmethod
    def _sample(meas: Mapping, name: str) -> float | None:
        """The sample as a float, or None if absent, not a number, not finite or out of range."""
        try:
            v = float(meas.get(name, math.nan))
        except (TypeError, ValueError):
            return None
        lo, hi = _RANGES[name]
        if not (math.isfinite(v) and lo <= v <= hi):
            return None
        return max(v, 0.0) if name in _NON_NEGATIVE else v

    def _command(self, u_prev, missing: list) -> tuple[float, float]:
        try:
            m, sp = float(u_prev[0]), float(u_prev[1])
        except (TypeError, ValueError, IndexError):
            m = sp = math.nan
        if ACTUATOR_LIMITS.contains(m, sp, tol=OBSERVATION_LIMITS.command_tol):
            self._u_prev = ACTUATOR_LIMITS.clip(m, sp)
        else:
            missing.append("u_prev")
        return self._u_prev

    # ------------------------------------------------------------- update
    def update(self, t_s: float, meas: Mapping, u_prev) -> Estimate:
        """One filter step at ``t_s`` [s].

        Args:
            t_s: time of the samples [s].
            meas: the samples at ``t_s`` (keys of :data:`VEHICLE_SENSORS`; absent or non-finite
                keys count as missing; other keys, e.g. ``t_int_c``, are ignored).
            u_prev: (blower flow [kg/s], evaporator set-point [degC]) applied since the last call.
        """
        s, p = self.settings, self.model_params
        missing: list[str] = []
        y = {name: self._sample(meas, name) for name in VEHICLE_SENSORS}
        for name in VEHICLE_SENSORS:
            # cabin RH is optional (the filter does not use it): flagged only when given and invalid
            if y[name] is None and (name != "rh_cab" or name in meas):
                missing.append(name)
        m, sp = self._command(u_prev, missing)
        try:
            t_s = float(t_s)
        except (TypeError, ValueError):
            t_s = math.nan
        if not math.isfinite(t_s):
            missing.append("t_s")
            t_s = (self._t_last + self.control_period_s) if self._t_last is not None else 0.0
        # exogenous inputs: the sample, else the last valid one, else a default
        ex = {}
        for name, default in (("t_amb_c", s.default_t_c), ("solar_wm2", 0.0), ("speed_mps", 0.0), ("rh_cab", math.nan)):
            if y[name] is not None:
                self._held[name] = y[name]
            ex[name] = self._held.get(name, default)
        n_steps = None  # model steps since the last update; None: (re)initialize
        if self._x is not None and self._t_last is not None:
            dt = t_s - self._t_last
            if 0 <= dt <= s.max_gap_s:
                n_steps = int(round(dt / p.ts_s))
        initialized = False
        if n_steps is None:
            initialized = self._initialize(y, ex)
            t_evap = y["t_evap_c"] if y["t_evap_c"] is not None else self._held.get("t_evap_c", ex["t_amb_c"])
        elif n_steps == 0:
            # less than half a model step since the last update: a correction without time propagation;
            # the elapsed time is propagated by the next update (the reference time stays)
            t_evap = y["t_evap_c"] if y["t_evap_c"] is not None else self._held["t_evap_c"]
            self._correct(y if y["t_evap_c"] is not None else {**y, "t_vent_c": None}, m, t_evap, ex)
            t_s_ref = self._t_last
        else:
            t_evap0 = self._held.get("t_evap_c", ex["t_amb_c"])
            t_evap = y["t_evap_c"]
            if t_evap is None:  # eq. (2) from the last value with the held set-point
                t_evap = t_evap0
                for _ in range(n_steps):
                    t_evap = float(cm.t_evap_next_c(p, t_evap, sp))
            self._predict(n_steps, m, t_evap0, t_evap, ex)
            # without an evaporator sample E3 has no reliable input: no vent update either
            self._correct(y if y["t_evap_c"] is not None else {**y, "t_vent_c": None}, m, t_evap, ex)
        if (
            self._x is not None
            and self._p is not None
            and not (np.all(np.isfinite(self._x)) and np.all(np.isfinite(self._p)))
        ):
            initialized = self._initialize(y, ex)  # defensive: never carry a non-finite state
        if n_steps != 0 or initialized:
            self._held["t_evap_c"] = t_evap
            self._t_last = t_s
        else:
            self._t_last = t_s_ref
        if self._x is not None:
            self._x = np.clip(self._x, [-40.0] * (_N - 1) + [-10.0], [120.0] * (_N - 1) + [10.0])
        if y["t_cab_c"] is not None:
            self._t_cab_valid_s = t_s
        dead = (
            0.0
            if y["t_cab_c"] is not None
            else (t_s - self._t_cab_valid_s if self._t_cab_valid_s is not None else math.inf)
        )
        valid = self._x is not None and dead <= s.max_dead_reckoning_s
        x = self._x if self._x is not None else np.array([ex["t_amb_c"]] * (_N - 1) + [0.0])
        pdiag = (
            np.diag(self._p) if self._p is not None else np.array([s.init_std_k**2] * (_N - 1) + [s.vent_bias_std_k**2])
        )
        t_vent = y["t_vent_c"]
        if t_vent is None:
            t_vent = float(t_vent_c(self.params, t_evap, x[0], x[4], ex["t_amb_c"], m) + x[_B])
        return Estimate(
            t_s=t_s,
            t_cab_c=float(y["t_cab_c"] if y["t_cab_c"] is not None else x[0]),
            t_int_c=float(x[1]),
            t_shell_c=float(x[2]),
            t_glass_c=float(x[3]),
            t_duct_c=float(x[4]),
            t_evap_c=float(t_evap),
            t_vent_c=float(t_vent),
            t_amb_c=float(ex["t_amb_c"]),
            solar_wm2=float(ex["solar_wm2"]),
            speed_mps=float(ex["speed_mps"]),
            rh_cab=float(ex["rh_cab"]),
            mdot_bl_prev_kgps=float(m),
            t_evap_sp_prev_c=float(sp),
            vent_bias_k=float(x[_B]),
            std_k=tuple(float(v) for v in np.sqrt(np.maximum(pdiag, 0.0))),
            missing=tuple(missing),
            valid=bool(valid),
            dead_reckoning_s=float(min(dead, 1e9)),
            initialized=initialized,
        )

    def _initialize(self, y: dict, ex: dict) -> bool:
        """Key-on prior from the cabin air sample; without one, stay uninitialized."""
        s = self.settings
        if y["t_cab_c"] is None:
            self._x = self._p = None
            return False
        t = y["t_cab_c"]
        t_duct = y["t_evap_c"] if y["t_evap_c"] is not None else t
        self._x = np.array(
            [t, t + s.init_offset_int_k, t + s.init_offset_shell_k, t + s.init_offset_glass_k, t_duct, 0.0]
        )
        self._p = np.diag(
            [
                s.sensor_std_t_cab_k**2,
                s.init_std_k**2,
                s.init_std_k**2,
                s.init_std_k**2,
                s.init_std_duct_k**2,
                s.vent_bias_std_k**2,
            ]
        )
        return True

    def _predict(self, n_steps: int, m: float, t_evap0: float, t_evap1: float, ex: dict) -> None:
        assert self._x is not None and self._p is not None
        x, pc = self._x, self._p
        for i in range(n_steps):
            a0 = t_evap0 + (t_evap1 - t_evap0) * i / n_steps
            a1 = t_evap0 + (t_evap1 - t_evap0) * (i + 1) / n_steps
            u = np.array([m, a0, a1, ex["t_amb_c"], ex["solar_wm2"], ex["speed_mps"]])
            xn, jac = self._f(x, u)
            fx = np.array(jac)
            x = np.array(xn).ravel()
            pc = fx @ pc @ fx.T + self._q
        self._x, self._p = x, 0.5 * (pc + pc.T)

    def _correct(self, y: dict, m: float, t_evap: float, ex: dict) -> None:
        """Measurement update with the valid samples: T_cab, then T_vent at the updated state.

        Sequential scalar updates in Joseph form; with independent sensor noise and h linear in x this
        equals the joint update.
        """
        assert self._x is not None
        if y["t_cab_c"] is not None:
            self._scalar_update(y["t_cab_c"], float(self._x[0]), np.eye(_N)[0], self._r_cab)
        if y["t_vent_c"] is not None:
            u = np.array([m, t_evap, t_evap, ex["t_amb_c"], ex["solar_wm2"], ex["speed_mps"]])
            hv, hj, he = self._h_vent(self._x, u)
            r = self._r_vent + (float(he) * self.settings.sensor_std_t_evap_k) ** 2
            self._scalar_update(y["t_vent_c"], float(hv), np.array(hj).ravel(), r)

    def _scalar_update(self, y: float, y_pred: float, h: np.ndarray, r: float) -> None:
        assert self._x is not None and self._p is not None
        p = self._p
        s_inn = float(h @ p @ h) + r
        k = (p @ h) / s_inn
        self._x = self._x + k * (y - y_pred)
        ikh = np.eye(_N) - np.outer(k, h)
        pc = ikh @ p @ ikh.T + r * np.outer(k, k)
        self._p = 0.5 * (pc + pc.T)


ESTIMATION_SETTLE_S = 120.0
"""Key-on transient of the estimator excluded from the late estimation errors [s]."""


def estimation_errors(series: dict, name: str, after_s: float = ESTIMATION_SETTLE_S) -> tuple[float, float, float]:
    """``(RMSE, RMSE from after_s on, max |error|)`` [K] of ``{name}_est_c`` against ``{name}_c``.

    ``series`` holds ``t_s`` [s] and both columns (a closed-loop run's or an identification
    replay's); the late RMSE is NaN without samples after ``after_s``.
    """
    e = np.asarray(series[f"{name}_est_c"], float) - np.asarray(series[f"{name}_c"], float)
    late = e[np.asarray(series["t_s"], float) >= after_s]
    rms = float(np.sqrt(np.mean(e**2)))
    rms_late = float(np.sqrt(np.mean(late**2))) if late.size else math.nan
    return rms, rms_late, float(np.max(np.abs(e)))
