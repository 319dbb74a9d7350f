"""Contracts shared by the plant, the V2X preview, every controller and the nodes.

* the actuator bounds and the supervisory command :class:`AcInput`;
* what the plant hands a controller (:data:`MEASUREMENTS`) and what V2X
  delivers (:class:`Previews`);
* what a controller sees (:class:`Observation`) and reports
  (:class:`Diagnostics`, one row of ``diagnostics.csv``, docs/architecture.md);
* the strategy names (:data:`STRATEGIES`).

A controller (baseline PI, any CECO NMPC) is called once per control period
``Ts`` with an :class:`Observation` built from the measurements at ``t = k*Ts``
and the V2X previews on the grid ``t, t + Ts, ..., t + Np*Ts``. It returns the
command held over ``[t, t + Ts)`` and a :class:`Diagnostics` record.

Pure data: no solver, no ROS.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = [
    "MDOT_BL_MIN_KGPS",
    "MDOT_BL_MAX_KGPS",
    "T_EVAP_SP_MIN_C",
    "T_EVAP_SP_MAX_C",
    "RECIRC_SHARE_MIN",
    "RECIRC_SHARE_MAX",
    "RECIRC_NOT_COMMANDED_WIRE",
    "AcInput",
    "ActuatorLimits",
    "ACTUATOR_LIMITS",
    "MEASUREMENTS",
    "PREVIEW_QUANTITIES",
    "Previews",
    "Observation",
    "Diagnostics",
    "DIAGNOSTICS_CONTRACT_COLUMNS",
    "DIAGNOSTICS_COLUMNS",
    "STRATEGIES",
    "CECO_STRATEGIES",
    "STRATEGY_VARIANTS",
    "NODE_STRATEGIES",
    "NAMED_STRATEGIES",
    "strategy_variant",
    "BASELINE_STRATEGY",
    "MEASUREMENT_MODES",
    "EXTERNAL_STRATEGY",
    "WIRE_STRATEGIES",
    "check_finite",
]

MDOT_BL_MIN_KGPS = 0.05
"""Lower actuator bound of the blower air flow [kg/s] (method paper, eq. 13)."""
MDOT_BL_MAX_KGPS = 0.17
"""Upper actuator bound of the blower air flow [kg/s] (method paper, eq. 13)."""
T_EVAP_SP_MIN_C = 3.0
"""Lower bound of the evaporator wall temperature set-point [degC] (method paper, eq. 13)."""
T_EVAP_SP_MAX_C = 10.0
"""Upper bound of the evaporator wall temperature set-point [degC] (method paper, eq. 13)."""
RECIRC_SHARE_MIN = 0.0
"""Lower bound of the commanded recirculated share of the blower flow [-] (0: fresh air only)."""
RECIRC_SHARE_MAX = 1.0
"""Upper bound of the commanded recirculated share of the blower flow [-] (1: full recirculation)."""
RECIRC_NOT_COMMANDED_WIRE = -1.0
"""AcCommand.recirc_share meaning "the door is not commanded" (the message's default; NaN means the same)."""


CONTROL_PERIOD_RANGE_S = (0.1, 300.0)
"""Ts of every node and every ``ceco`` verb [s]: up to 5 min (the NMPC's transcription grows with Ts / its
substep: configure took 15 s at Ts 600 s on the 2-core machine, 124 s at 3600 s)."""
NOISE_SEED_RANGE = (0, 2**31 - 1)
"""A preview-noise seed [-], in every verb, case file and preview_node (``faults.seed``, a 32-bit parameter whose
-1 means "none")."""

HORIZON_RANGE = (1, 60)
"""Np of the controller and of the preview grid, in every node and every ``ceco`` verb [steps]: configure
took 4 s at Np 60, 31 s at Np 200."""
PLANT_STEP_S = 1.0
"""The plant step of the simulator, plant_node and the whole-drive optimum [s] (``SimSettings.plant_dt_s``,
plant_node's ``plant_dt_s``, ``OracleSettings.plant_dt_s`` default to it); a run lasts a whole number of them."""
DOMAIN_ID_MAX = 232
"""Largest ROS_DOMAIN_ID Fast DDS's default port mapping allows (0..101 are
also clear of Linux's ephemeral ports; docs.ros.org, "The ROS_DOMAIN_ID")."""


CECO_STRATEGIES = ("ceco", "ceco-e", "ceco-c", "ceco-ioch", "ceco-pmv")
"""Names of the NMPC strategies (settings in ``ceco_controller.strategies``): the paper's four and issue 20's
comfort-output strategy ``ceco-pmv``."""

BASELINE_STRATEGY = "baseline"
"""Name of the production climate control used as the baseline."""

STRATEGIES = (BASELINE_STRATEGY,) + CECO_STRATEGIES
"""Every strategy, baseline first: what ``--strategy all`` runs."""

STRATEGY_VARIANTS: dict[str, tuple[str, tuple[tuple[str, object], ...]]] = {
    "ceco-pmv-aq": ("ceco-pmv", (("door_control", "co2_hold"),)),
    "ceco-pmv-door": ("ceco-pmv", (("door_control", "nlp"),)),
}
"""Named variants of a CECO strategy: ``{name: (strategy, ((StrategySettings field, value), ...))}``, the
strategy's settings with these fields set (after the controller file, before a caller's overrides).
``ceco-pmv-aq``: ceco-pmv with the CO2-holding recirculation door beside its NLP (docs/controller.md 4.8);
``ceco-pmv-door``: ceco-pmv with the door a third input of its NLP (4.9). Valid wherever a strategy is named
(mpc_node's ``strategy``, ``--strategy``, ``ceco benchmark``); ``--strategy all`` runs :data:`STRATEGIES`."""

NODE_STRATEGIES = CECO_STRATEGIES + tuple(STRATEGY_VARIANTS)
"""The values of mpc_node's ``strategy`` parameter."""

NAMED_STRATEGIES = STRATEGIES + tuple(STRATEGY_VARIANTS)
"""Every strategy name a run can be asked for (also the values of AcCommand.strategy on the wire)."""

EXTERNAL_STRATEGY = "external"
"""AcCommand.strategy of a third-party controller scored by ``ceco benchmark --controller-cmd``."""

WIRE_STRATEGIES = NAMED_STRATEGIES + (EXTERNAL_STRATEGY,)
"""Every AcCommand.strategy the plant accepts."""


def strategy_variant(name: str) -> tuple[str, tuple[tuple[str, object], ...]]:
    """``(strategy, settings overrides)`` of a strategy name.

    A named variant's (:data:`STRATEGY_VARIANTS`), else ``(name, ())``.
    """
    return STRATEGY_VARIANTS.get(name, (name, ()))


MEASUREMENTS = (
    "t_cab_c",
    "t_int_c",
    "t_shell_c",
    "t_glass_c",
    "t_evap_c",
    "t_vent_c",
    "rh_cab",
    "co2_cab_ppm",
    "co2_sensor_ppm",
    "recirc_share",
)
"""Keys of the measurement mapping that the plant hands to a controller (``ScenarioPlant.meas``; the fields
of ceco_msgs/CabinState): temperatures [degC], cabin RH [0..1], cabin CO2 [ppm] (the plant's), the cabin
CO2 sensor's reading [ppm] (NaN when no sensor is fitted or it failed) and the door's position, the
recirculated share [0..1]."""

MEASUREMENT_MODES = ("full", "vehicle")
"""What a controller reads: ``full``, every plant state it models (the default); ``vehicle``, only the
sensors a production car has, the rest estimated (``ceco_controller.estimator``)."""

PREVIEW_QUANTITIES = ("t_amb_c", "solar_wm2", "speed_mps", "rh")
"""The previewed quantities (arrays of :class:`Previews`)."""


def check_finite(name: str, value) -> float:
    """``float(value)``; ValueError naming ``name`` if it is not a finite number."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return v


@dataclasses.dataclass(frozen=True)
class AcInput:
    """Supervisory command to the A/C, held over one plant step."""

    mdot_bl_kgps: float
    """Blower (supply) air mass flow [kg/s], in [0.05, 0.17]."""
    t_evap_sp_c: float
    """Evaporator wall temperature set-point [degC], in [3, 10]."""
    recirc_share: float = math.nan
    """Commanded recirculated share of the blower flow [-], in [0, 1] (0 fresh air, 1 full recirculation);
    NaN: the door is not commanded, the plant holds its default share (``PlantParams.recirc_fraction``, 0.8)."""

    def __post_init__(self) -> None:
        self.validate()

    @property
    def door_commanded(self) -> bool:
        """True when the command sets the recirculation door (``recirc_share`` is not NaN)."""
        return not math.isnan(self.recirc_share)

    def validate(self) -> AcInput:
        """Raise ValueError naming the field if it is not finite or outside the actuator bounds.

        ``recirc_share`` may be NaN (not commanded); an infinite or out-of-range share is refused.
        """
        m = check_finite("mdot_bl_kgps", self.mdot_bl_kgps)
        if not MDOT_BL_MIN_KGPS <= m <= MDOT_BL_MAX_KGPS:
            raise ValueError(f"mdot_bl_kgps: must be in [{MDOT_BL_MIN_KGPS}, {MDOT_BL_MAX_KGPS}] kg/s, got {m}")
        t = check_finite("t_evap_sp_c", self.t_evap_sp_c)
        if not T_EVAP_SP_MIN_C <= t <= T_EVAP_SP_MAX_C:
            raise ValueError(f"t_evap_sp_c: must be in [{T_EVAP_SP_MIN_C}, {T_EVAP_SP_MAX_C}] degC, got {t}")
        try:
            r = float(self.recirc_share)
        except (TypeError, ValueError):
            raise ValueError(
                f"recirc_share: must be a number or NaN (not commanded), got {self.recirc_share!r}"
            ) from None
        if not math.isnan(r) and not RECIRC_SHARE_MIN <= r <= RECIRC_SHARE_MAX:
            raise ValueError(
                f"recirc_share: must be in [{RECIRC_SHARE_MIN}, {RECIRC_SHARE_MAX}] or NaN (not commanded), got {r}"
            )
        return self


@dataclasses.dataclass(frozen=True)
class ActuatorLimits:
    """Hard actuator bounds of the A/C (paper, Sec. 3.1)."""

    mdot_bl_min_kgps: float = MDOT_BL_MIN_KGPS
    """Lowest blower air mass flow [kg/s]."""
    mdot_bl_max_kgps: float = MDOT_BL_MAX_KGPS
    """Highest blower air mass flow [kg/s]."""
    t_evap_sp_min_c: float = T_EVAP_SP_MIN_C
    """Lowest evaporator wall temperature set-point [degC] (frost margin)."""
    t_evap_sp_max_c: float = T_EVAP_SP_MAX_C
    """Highest evaporator wall temperature set-point [degC]."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a bound is not finite or ordered."""
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"ActuatorLimits.{f.name} must be a finite number, got {v!r}")
        if not 0.0 < self.mdot_bl_min_kgps < self.mdot_bl_max_kgps:
            raise ValueError("ActuatorLimits.mdot_bl_min_kgps must satisfy 0 < min < mdot_bl_max_kgps")
        if not self.t_evap_sp_min_c < self.t_evap_sp_max_c:
            raise ValueError("ActuatorLimits.t_evap_sp_min_c must be < t_evap_sp_max_c")

    def contains(self, mdot_bl_kgps: float, t_evap_sp_c: float, tol: float = 0.0) -> bool:
        """True if the command is finite and inside the bounds widened by ``tol`` (inclusive)."""
        return (
            math.isfinite(mdot_bl_kgps)
            and math.isfinite(t_evap_sp_c)
            and self.mdot_bl_min_kgps - tol <= mdot_bl_kgps <= self.mdot_bl_max_kgps + tol
            and self.t_evap_sp_min_c - tol <= t_evap_sp_c <= self.t_evap_sp_max_c + tol
        )

    def clip(self, mdot_bl_kgps: float, t_evap_sp_c: float) -> tuple[float, float]:
        """The command moved onto the bounds where it lies outside them [kg/s, degC]."""
        return (
            min(max(float(mdot_bl_kgps), self.mdot_bl_min_kgps), self.mdot_bl_max_kgps),
            min(max(float(t_evap_sp_c), self.t_evap_sp_min_c), self.t_evap_sp_max_c),
        )


ACTUATOR_LIMITS = ActuatorLimits()
"""The paper's actuator bounds: 0.05-0.17 kg/s, 3-10 degC."""


@dataclasses.dataclass(frozen=True, eq=False)
class Previews:
    """What the controller receives at ``t0_s``: values on ``t0_s + i*step_s``.

    Entries that are not available are NaN in every array and False in
    ``valid``.
    """

    t0_s: float
    """Time of the first sample (the time the preview is used) [s]."""
    step_s: float
    """Sample spacing [s]."""
    t_amb_c: np.ndarray
    """Forecast ambient temperature [degC]."""
    solar_wm2: np.ndarray
    """Forecast solar irradiance [W/m2]."""
    speed_mps: np.ndarray
    """Forecast vehicle speed [m/s]."""
    rh: np.ndarray
    """Forecast ambient relative humidity [-]."""
    valid: np.ndarray
    """Per-sample availability (bool)."""
    age_s: float
    """Age of the forecast used (t0_s - issue time) [s]; inf if none was received."""
    issued_s: float
    """Issue time of the forecast used [s]; NaN if none was received."""

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.valid.size)

    @property
    def t_s(self) -> np.ndarray:
        """Sample times [s]."""
        return self.t0_s + self.step_s * np.arange(self.n, dtype=float)

    @property
    def trusted_steps(self) -> int:
        """Number of leading valid samples (the usable horizon)."""
        bad = np.flatnonzero(~self.valid)
        return int(bad[0]) if bad.size else self.n


def _as_array(x, name, n=None):
    a = np.asarray(x, dtype=float).reshape(-1)
    if n is not None and a.size != n:
        raise ValueError(f"Observation.{name} must have {n} values, got {a.size}")
    return a


@dataclasses.dataclass(frozen=True)
class Observation:
    """What a controller sees at control step ``k`` (time ``t_s = k * Ts``).

    Measurements are the plant outputs sampled at ``t_s``. Preview arrays are
    on the grid ``t_s + i*Ts, i = 0..n-1`` (``n = Np + 1``); entries may be NaN
    where ``preview_valid`` is False (missing or stale V2X data). The PMV
    bounds are the comfort zone on the same grid (they come from the
    occupant's settings, not from V2X, so they are always valid).
    """

    k: int
    """Control step index [-]."""
    t_s: float
    """Time since the start of the run [s]."""
    t_cab_c: float
    """Measured cabin air temperature [degC]."""
    t_int_c: float
    """Measured cabin interior (seats, dashboard) surface temperature [degC]."""
    t_shell_c: float
    """Measured cabin shell (roof, doors, glazing) temperature [degC]."""
    t_evap_c: float
    """Measured evaporator wall temperature [degC]."""
    t_vent_c: float
    """Measured vent (discharge) air temperature [degC]."""
    t_amb_c: float
    """Measured ambient air temperature now [degC]."""
    solar_wm2: float
    """Measured/estimated solar load now [W/m2]."""
    speed_mps: float
    """Vehicle speed now [m/s]."""
    mdot_bl_prev_kgps: float
    """Blower flow applied over the previous control period [kg/s]."""
    t_evap_sp_prev_c: float
    """Evaporator set-point applied over the previous control period [degC]."""
    preview_t_amb_c: np.ndarray
    """Ambient temperature preview [degC], shape (n,)."""
    preview_solar_wm2: np.ndarray
    """Solar load preview [W/m2], shape (n,)."""
    preview_speed_mps: np.ndarray
    """Vehicle speed preview [m/s], shape (n,)."""
    preview_valid: np.ndarray
    """True where the preview entry is trustworthy, shape (n,)."""
    pmv_lb: np.ndarray
    """PMV lower bound on the preview grid [-], shape (n,)."""
    pmv_ub: np.ndarray
    """PMV upper bound on the preview grid [-], shape (n,)."""
    met: float = 1.2
    """Occupant metabolic rate [met] (seated driving, ISO 7730 Annex B)."""
    clo: float = 0.5
    """Occupant clothing insulation [clo] (summer clothing)."""
    t_glass_c: float = math.nan
    """Measured glazing temperature [degC] (for the mean radiant temperature; NaN if not measured)."""
    rh_cab: float = math.nan
    """Measured cabin relative humidity [0..1] (for the PMV's vapour pressure; NaN if not measured)."""
    rh_amb: float = math.nan
    """Measured ambient relative humidity [0..1] (CabinState ``rh``: the car's sensor or the weather service's current
    value; for the doors' enthalpy economiser, ``ceco_core.air_quality.economiser_open``; NaN if not known)."""
    co2_cab_ppm: float = math.nan
    """Cabin CO2 [ppm]: the plant's (measurements 'full') or the estimate from the sensor and the CO2 balance
    ('vehicle'); NaN if unknown."""
    co2_sensor_ppm: float = math.nan
    """The cabin CO2 sensor's reading [ppm]; NaN when no sensor is fitted or it failed."""
    recirc_share: float = math.nan
    """Measured position of the fresh/recirculation door: recirculated share [0..1] (NaN if not measured)."""
    n_occupants: int = 1
    """People in the car [-] (seat-occupancy detection)."""
    co2_limit_ppm: float = 1500.0
    """The occupant's CO2 limit [ppm] (the scenario's ``air_quality``)."""
    fog_margin_min_k: float = 3.0
    """The smallest acceptable windshield fog margin [K] (the scenario's ``air_quality``)."""

    def __post_init__(self):
        n = np.asarray(self.pmv_lb).size
        for name in ("preview_t_amb_c", "preview_solar_wm2", "preview_speed_mps", "pmv_lb", "pmv_ub"):
            object.__setattr__(self, name, _as_array(getattr(self, name), name, n))
        object.__setattr__(self, "preview_valid", np.asarray(self.preview_valid, dtype=bool).reshape(-1))
        if self.preview_valid.size != n:
            raise ValueError(f"Observation.preview_valid must have {n} values, got {self.preview_valid.size}")

    @property
    def n_preview(self) -> int:
        """Number of points on the preview grid (Np + 1)."""
        return int(self.pmv_lb.size)

    def measurements_finite(self) -> bool:
        """True if every scalar measurement the NMPC needs is finite."""
        vals = (
            self.t_cab_c,
            self.t_int_c,
            self.t_shell_c,
            self.t_evap_c,
            self.t_vent_c,
            self.t_amb_c,
            self.solar_wm2,
            self.speed_mps,
        )
        return all(math.isfinite(float(v)) for v in vals)


DIAGNOSTICS_CONTRACT_COLUMNS = (
    "k",
    "t_s",
    "status",
    "success",
    "iterations",
    "solve_time_ms",
    "cost_energy",
    "cost_comfort",
    "cost_ioch",
    "eps_mean",
    "fallback",
)
"""The contract's columns of ``diagnostics.csv`` (docs/architecture.md); every writer puts them first."""

DIAGNOSTICS_COLUMNS = DIAGNOSTICS_CONTRACT_COLUMNS + (
    # extra columns (allowed after the contract's columns)
    "cost_slack",
    "cost_total",
    "trusted_horizon",
    "pmv_pred_1",
    "t_cab_pred_1_c",
    "mdot_bl_kgps",
    "t_evap_sp_c",
    "message",
)
"""Columns of ``diagnostics.csv``: the architecture contract's first, then extras."""


@dataclasses.dataclass
class Diagnostics:
    """What a controller reports for one control step.

    The baseline leaves the solver fields as None. ``fallback`` is ``""`` when
    the strategy's own solution is applied, ``"shifted_plan"`` when the
    previous plan (shifted by one step) is applied after a failed solve, and
    ``"baseline"`` when the production law is applied.
    """

    k: int
    """Control step index [-]."""
    t_s: float
    """Time [s]."""
    status: str = ""
    """Solver return status (e.g. IPOPT's 'Solve_Succeeded'), or the reason for a fallback."""
    success: bool | None = None
    """Whether the solver reported success (None for the baseline)."""
    iterations: int | None = None
    """Solver iterations (None for the baseline)."""
    solve_time_ms: float | None = None
    """Wall-clock time of the solve [ms] (measurement only; never used for a decision)."""
    cost_energy: float | None = None
    """Energy term of the optimal cost: predicted A/C energy over the horizon [kJ]."""
    cost_comfort: float | None = None
    """Comfort term gamma * sum PMV^2 * Ts [kJ-equivalent] (ceco-c)."""
    cost_ioch: float | None = None
    """IOCH term beta * sum (eta_AC - 1)/(eps + xi) * Ts [kJ-equivalent] (ceco-ioch)."""
    cost_slack: float | None = None
    """Exact-penalty slack term [kJ-equivalent]; > 0 only when the bounds cannot be met."""
    cost_total: float | None = None
    """Total optimal cost [kJ-equivalent]."""
    eps: np.ndarray | None = None
    """IOCH tightening eps over the horizon [PMV] (ceco-ioch)."""
    fallback: str = ""
    """'' (own solution), 'shifted_plan' or 'baseline'."""
    trusted_horizon: int | None = None
    """Number of leading preview points that were valid [-]."""
    pred_pmv: np.ndarray | None = None
    """Predicted PMV on the horizon grid [-]."""
    pred_t_cab_c: np.ndarray | None = None
    """Predicted cabin air temperature on the horizon grid [degC]."""
    mdot_bl_kgps: float | None = None
    """Applied blower flow [kg/s]."""
    t_evap_sp_c: float | None = None
    """Applied evaporator set-point [degC]."""
    message: str = ""
    """Free text (why a fallback happened, preview degradation, ...)."""

    @property
    def eps_mean(self) -> float | None:
        """Mean of eps over the horizon [PMV], None if not an IOCH step."""
        if self.eps is None or np.size(self.eps) == 0:
            return None
        return float(np.mean(self.eps))

    def to_row(self) -> dict:
        """One ``diagnostics.csv`` row (columns :data:`DIAGNOSTICS_COLUMNS`)."""

        def first(a):
            if a is None or np.size(a) < 2:
                return None
            return float(np.asarray(a)[1])

        row = {
            "k": self.k,
            "t_s": self.t_s,
            "status": self.status,
            "success": "" if self.success is None else int(bool(self.success)),
            "iterations": self.iterations,
            "solve_time_ms": self.solve_time_ms,
            "cost_energy": self.cost_energy,
            "cost_comfort": self.cost_comfort,
            "cost_ioch": self.cost_ioch,
            "eps_mean": self.eps_mean,
            "fallback": self.fallback,
            "cost_slack": self.cost_slack,
            "cost_total": self.cost_total,
            "trusted_horizon": self.trusted_horizon,
            "pmv_pred_1": first(self.pred_pmv),
            "t_cab_pred_1_c": first(self.pred_t_cab_c),
            "mdot_bl_kgps": self.mdot_bl_kgps,
            "t_evap_sp_c": self.t_evap_sp_c,
            "message": self.message,
        }
        return {c: ("" if row[c] is None else row[c]) for c in DIAGNOSTICS_COLUMNS}
