"""The state estimator's models and parameters (``measurements: vehicle``; docs/controller.md section 5).

The grey-box models E1-E5 of the unmeasured cabin temperatures and the vent air,
:class:`EstimatorParams` (identified by ``ceco_controller.estimator_id``, stored in
``config/estimator_params.yaml``) and :class:`EstimatorSettings` (sensor noise, dead
reckoning, resets). Every equation evaluates numpy values and CasADi symbols alike, so
the filter in :mod:`ceco_controller.estimator` takes exact Jacobians from the same code.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
from typing import Any

from ceco_core import yamlio

from . import model as cm

__all__ = [
    "DEFAULT_ESTIMATOR_PARAMS_PATH",
    "M_REF_KGPS",
    "EstimatorParams",
    "EstimatorSettings",
    "load_estimator_params",
    "save_estimator_params",
    "t_vent_c",
    "t_int_next_c",
    "t_shell_next_c",
    "t_glass_next_c",
    "t_duct_next_c",
    "process_step",
]

DEFAULT_ESTIMATOR_PARAMS_PATH = cm.DEFAULT_PARAMS_PATH.parent / "estimator_params.yaml"
"""The identified estimator parameter file in the source tree (``ceco_controller/config``)."""

M_REF_KGPS = 0.1
"""Reference blower flow of the forced-convection term of E1 [kg/s]."""


@dataclasses.dataclass(frozen=True)
class EstimatorParams:
    """Identified coefficients of E1-E3 and the identified process noise (``ceco_controller.estimator_id``)."""

    ts_s: float = 5.0
    """Model step the coefficients are identified at [s]."""
    int_cab: float = 0.002
    """a1: natural convection interior <-> cabin air per step [-]."""
    int_cab_forced: float = 0.004
    """a2: forced convection interior <-> cabin air per step at m_ref [-]."""
    int_shell: float = 0.0014
    """a3: radiation interior <-> shell per step [-]."""
    int_glass: float = 0.001
    """a4: radiation interior <-> glazing per step [-]."""
    int_solar_k_per_wm2: float = 3.6e-5
    """a5: solar gain of the interior through the glazing per step [K/(W/m2)]."""
    int_duct: float = 0.0004
    """a6: conduction interior (instrument panel) <-> HVAC case and ducts per step [-]."""
    shell_cab: float = 0.005
    """b1: shell <-> cabin air per step [-]."""
    shell_int: float = 0.004
    """b2: shell <-> interior (radiation) per step [-]."""
    shell_amb: float = 0.007
    """b3: shell <-> ambient, natural convection, per step [-]."""
    shell_amb_speed: float = 0.007
    """b4: shell <-> ambient, speed-driven convection, per step per (m/s)^0.8 [(m/s)^-0.8]."""
    shell_solar_k_per_wm2: float = 2.4e-4
    """b5: solar gain of the shell per step [K/(W/m2)]."""
    glass_cab: float = 0.0012
    """c1: natural convection glazing <-> cabin air per step [-]."""
    glass_cab_forced: float = 0.0026
    """c2: forced convection glazing <-> cabin air per step at m_ref [-]."""
    glass_int: float = 0.0022
    """c3: glazing <-> interior (radiation) per step [-]."""
    glass_amb: float = 0.0028
    """c4: glazing <-> ambient, natural convection, per step [-]."""
    glass_amb_speed: float = 0.0026
    """c5: glazing <-> ambient, speed-driven convection, per step per (m/s)^0.8 [(m/s)^-0.8]."""
    glass_solar_k_per_wm2: float = 6.7e-5
    """c6: solar absorption of the glazing per step [K/(W/m2)]."""
    duct_int: float = 0.005
    """e1: HVAC case/duct walls <-> instrument panel per step [-]."""
    duct_air_s_per_kg: float = 0.17
    """e2: duct walls <-> supply air per step, linear in the flow [s/kg]."""
    duct_air2_s2_per_kg2: float = -0.22
    """e3: its curvature in the flow [s^2/kg^2]."""
    duct_cab_s_per_kg: float = 0.012
    """e4: bypassed recirculated air in the supply air per step [s/kg]."""
    duct_amb_s_per_kg: float = 0.005
    """e5: bypassed fresh air in the supply air per step [s/kg]."""
    vent_cab: float = 0.0024
    """v1: bypass share of the recirculated cabin air in the vent air [-]."""
    vent_cab_flow_s_per_kg: float = 0.34
    """v2: its growth with the blower flow [s/kg]."""
    vent_amb: float = 0.011
    """v3: bypass share of the fresh air [-]."""
    vent_amb_flow_s_per_kg: float = 0.008
    """v4: its growth with the blower flow [s/kg]."""
    vent_duct: float = 0.24
    """v5: share of the duct-wall temperature picked up by the supply air [-]."""
    vent_duct_flow_s_per_kg: float = -0.35
    """v6: its change with the blower flow [s/kg]."""
    vent_heat_k_kgps: float = 0.013
    """v7: flow-inverse offset (blower heat) [K kg/s]."""
    vent_offset_k: float = -0.16
    """v8: vent offset [K]."""
    vent_flow2_k_s2_per_kg2: float = 7.1
    """v9: blower heat growing with the flow [K s^2/kg^2]."""
    q_cab_k: float = 0.4
    """Process noise std of eq. (1) per model step [K] (identified)."""
    q_int_k: float = 0.01
    """Process noise std of E1 per model step [K] (identified)."""
    q_shell_k: float = 0.01
    """Process noise std of E2 per model step [K] (identified)."""
    q_glass_k: float = 0.01
    """Process noise std of E4 per model step [K] (identified)."""
    q_duct_k: float = 0.01
    """Process noise std of E5 per model step [K] (identified)."""
    vent_residual_k: float = 0.015
    """RMS residual of E3 [K] (identified; added to the vent sensor noise)."""
    provenance: str = "defaults (not identified)"
    """How the values were obtained (command and data); not used in computations."""

    def validate(self) -> EstimatorParams:
        """Raise ValueError naming the field if a value is not usable."""
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "provenance":
                if not isinstance(v, str):
                    raise ValueError("EstimatorParams.provenance must be a string")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"EstimatorParams.{f.name} must be a finite number, got {v!r}")
        if not self.ts_s > 0:
            raise ValueError(f"EstimatorParams.ts_s must be > 0, got {self.ts_s}")
        for name in ("q_cab_k", "q_int_k", "q_shell_k", "q_glass_k", "q_duct_k", "vent_residual_k"):
            if not getattr(self, name) > 0:
                raise ValueError(f"EstimatorParams.{name} must be > 0")
        return self

    def to_dict(self) -> dict:
        """Plain dict of the fields (Python floats; for YAML)."""
        return {k: (v if isinstance(v, str) else float(v)) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict) -> EstimatorParams:
        """Build and validate from a mapping; unknown keys are an error."""
        if not isinstance(data, dict):
            raise ValueError("EstimatorParams: expected a mapping")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"EstimatorParams: unknown field(s) {unknown}")
        kwargs: dict[str, Any] = {k: (v if k == "provenance" else float(v)) for k, v in data.items()}
        return cls(**kwargs).validate()


def load_estimator_params(path: str | pathlib.Path | None = None) -> EstimatorParams:
    """Load the identified estimator parameters (default: the package's ``config/estimator_params.yaml``)."""
    path = pathlib.Path(path) if path is not None else cm.package_config_path("estimator_params.yaml")
    doc = yamlio.load_file(path)
    if not isinstance(doc, dict) or "params" not in doc:
        raise ValueError(f"{path}: expected a mapping with a 'params' key")
    return EstimatorParams.from_dict(doc["params"])


def save_estimator_params(
    params: EstimatorParams, path: str | pathlib.Path, header: str = "", extra: dict | None = None
) -> None:
    """Write the parameters (and optional extra mappings, e.g. the fit report) as YAML."""
    params.validate()
    cm.write_params_yaml(params.to_dict(), path, header, extra)


@dataclasses.dataclass(frozen=True)
class EstimatorSettings:
    """Tuning of the filter that is not identified (sensor accuracy, key-on prior, fault handling)."""

    sensor_std_t_cab_k: float = 0.1
    """Cabin air temperature sensor noise, 1 sigma [K] (aspirated NTC, 0.1 K resolution)."""
    sensor_std_t_vent_k: float = 0.2
    """Vent air temperature sensor noise, 1 sigma [K] (NTC in the turbulent duct stream)."""
    sensor_std_t_evap_k: float = 0.1
    """Evaporator temperature sensor noise, 1 sigma [K] (enters the vent update through E3)."""
    process_std_scale: float = 1.0
    """Factor on the identified process noise std [-] (> 1: less trust in the model)."""
    init_offset_int_k: float = 0.0
    """Key-on prior of T_int relative to the measured cabin air temperature [K]."""
    init_offset_shell_k: float = 0.0
    """Key-on prior of T_shell relative to the measured cabin air temperature [K]."""
    init_offset_glass_k: float = 0.0
    """Key-on prior of T_glass relative to the measured cabin air temperature [K]."""
    init_std_k: float = 5.0
    """Key-on prior std of T_int, T_shell and T_glass [K] (soak offsets of the bundled scenarios: 1.5-5 K)."""
    init_std_duct_k: float = 2.0
    """Key-on prior std of T_duct [K]; its mean is the evaporator sample (the case and ducts soak with the
    HVAC module under the instrument panel)."""
    vent_bias_std_k: float = 0.5
    """Key-on prior std of the vent-channel offset b_vent [K] (vent and evaporator NTC tolerance)."""
    vent_bias_drift_k: float = 0.005
    """Random-walk std of b_vent per model step [K] (0.13 K per hour: slow sensor and duct drift)."""
    max_dead_reckoning_s: float = 60.0
    """Longest time the cabin air temperature may be predicted without a valid sample before the
    estimate is declared invalid (``Estimate.valid`` False) [s]."""
    max_gap_s: float = 300.0
    """A gap between two updates longer than this (or time going backwards) re-initializes [s]."""
    default_t_c: float = 25.0
    """Temperature reported before any valid cabin/ambient sample (estimate invalid) [degC]."""

    def validate(self) -> EstimatorSettings:
        """Raise ValueError naming the field if a setting is not usable."""
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"EstimatorSettings.{f.name} must be a finite number, got {v!r}")
        for name in (
            "sensor_std_t_cab_k",
            "sensor_std_t_vent_k",
            "sensor_std_t_evap_k",
            "process_std_scale",
            "init_std_k",
            "init_std_duct_k",
            "vent_bias_std_k",
            "vent_bias_drift_k",
            "max_dead_reckoning_s",
            "max_gap_s",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"EstimatorSettings.{name} must be > 0")
        if not -40.0 <= self.default_t_c <= 60.0:
            raise ValueError("EstimatorSettings.default_t_c must be in [-40, 60] degC")
        return self


# ---------------------------------------------------------------------------
# Equations (backend-neutral)
# ---------------------------------------------------------------------------


def _forced(mdot_bl_kgps):
    """f(m) = (m / m_ref)^0.8 [-] (forced convection, h ~ m^0.8)."""
    return (mdot_bl_kgps / M_REF_KGPS) ** 0.8


def t_vent_c(q: EstimatorParams, t_evap_c, t_cab_c, t_duct_c, t_amb_c, mdot_bl_kgps):
    """Vent air temperature, E3 [degC] (module docstring; mdot_bl_kgps > 0, in practice >= 0.05)."""
    m = mdot_bl_kgps
    d_cab = t_cab_c - t_evap_c
    d_amb = t_amb_c - t_evap_c
    d_duct = t_duct_c - t_evap_c
    return (
        t_evap_c
        + (q.vent_cab + q.vent_cab_flow_s_per_kg * m) * d_cab
        + (q.vent_amb + q.vent_amb_flow_s_per_kg * m) * d_amb
        + (q.vent_duct + q.vent_duct_flow_s_per_kg * m) * d_duct
        + q.vent_heat_k_kgps / m
        + q.vent_offset_k
        + q.vent_flow2_k_s2_per_kg2 * m * m
    )


def t_int_next_c(q: EstimatorParams, t_int_c, t_cab_c, t_shell_c, t_glass_c, t_duct_c, mdot_bl_kgps, solar_wm2):
    """Interior-mass temperature one model step ahead, E1 [degC] (mdot_bl_kgps >= 0)."""
    return (
        t_int_c
        + (q.int_cab + q.int_cab_forced * _forced(mdot_bl_kgps)) * (t_cab_c - t_int_c)
        + q.int_shell * (t_shell_c - t_int_c)
        + q.int_glass * (t_glass_c - t_int_c)
        + q.int_solar_k_per_wm2 * solar_wm2
        + q.int_duct * (t_duct_c - t_int_c)
    )


def t_shell_next_c(q: EstimatorParams, t_shell_c, t_cab_c, t_int_c, t_amb_c, speed_mps, solar_wm2):
    """Shell temperature one model step ahead, E2 [degC] (speed_mps >= 0)."""
    return (
        t_shell_c
        + q.shell_cab * (t_cab_c - t_shell_c)
        + q.shell_int * (t_int_c - t_shell_c)
        + (q.shell_amb + q.shell_amb_speed * speed_mps**0.8) * (t_amb_c - t_shell_c)
        + q.shell_solar_k_per_wm2 * solar_wm2
    )


def t_glass_next_c(q: EstimatorParams, t_glass_c, t_cab_c, t_int_c, t_amb_c, mdot_bl_kgps, speed_mps, solar_wm2):
    """Glazing temperature one model step ahead, E4 [degC] (mdot_bl_kgps, speed_mps >= 0)."""
    return (
        t_glass_c
        + (q.glass_cab + q.glass_cab_forced * _forced(mdot_bl_kgps)) * (t_cab_c - t_glass_c)
        + q.glass_int * (t_int_c - t_glass_c)
        + (q.glass_amb + q.glass_amb_speed * speed_mps**0.8) * (t_amb_c - t_glass_c)
        + q.glass_solar_k_per_wm2 * solar_wm2
    )


def t_duct_next_c(q: EstimatorParams, t_duct_c, t_int_c, t_cab_c, t_amb_c, t_evap_c, mdot_bl_kgps):
    """HVAC case and duct wall temperature one model step ahead, E5 [degC] (t_evap_c: the step's mean)."""
    m = mdot_bl_kgps
    return (
        t_duct_c
        + q.duct_int * (t_int_c - t_duct_c)
        + (q.duct_air_s_per_kg * m + q.duct_air2_s2_per_kg2 * m * m) * (t_evap_c - t_duct_c)
        + q.duct_cab_s_per_kg * m * (t_cab_c - t_evap_c)
        + q.duct_amb_s_per_kg * m * (t_amb_c - t_evap_c)
    )


def process_step(
    p: cm.ControlModelParams, q: EstimatorParams, x, mdot_bl_kgps, t_evap0_c, t_evap1_c, t_amb_c, solar_wm2, speed_mps
):
    """One model step of the thermal states x = (T_cab, T_int, T_shell, T_glass, T_duct) [degC].

    Eq. (1), E1, E2, E4, E5. ``t_evap0_c``/``t_evap1_c``: evaporator temperature at the start/end of the
    step [degC]; the vent air over the step is E3 at their mean. Returns a tuple of the five next temperatures.
    """
    t_cab, t_int, t_shell, t_glass, t_duct = x[0], x[1], x[2], x[3], x[4]
    t_ev = 0.5 * (t_evap0_c + t_evap1_c)
    t_ain = t_vent_c(q, t_ev, t_cab, t_duct, t_amb_c, mdot_bl_kgps)
    return (
        cm.t_cab_next_c(p, t_cab, t_int, t_shell, t_ain, mdot_bl_kgps),
        t_int_next_c(q, t_int, t_cab, t_shell, t_glass, t_duct, mdot_bl_kgps, solar_wm2),
        t_shell_next_c(q, t_shell, t_cab, t_int, t_amb_c, speed_mps, solar_wm2),
        t_glass_next_c(q, t_glass, t_cab, t_int, t_amb_c, mdot_bl_kgps, speed_mps, solar_wm2),
        t_duct_next_c(q, t_duct, t_int, t_cab, t_amb_c, t_ev, mdot_bl_kgps),
    )
