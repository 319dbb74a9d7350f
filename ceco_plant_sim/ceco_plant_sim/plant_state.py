"""The plant's state, its outputs per step, and the check of the environment it is driven by.

:class:`PlantState` is the integrator's state vector with names and units,
:class:`PlantOutputs` what one :meth:`ceco_plant_sim.plant.CabinPlant.step` reports
(end-of-step values, step-mean powers, step energies); ``validate_environment``
checks the boundary conditions. The equations are in :mod:`ceco_plant_sim.plant`
(docs/plant.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

from ceco_core.air_quality import (
    CO2_AMB_PPM_DEFAULT,
    RECIRC_SHARE_DEFAULT,
    co2_kgkg_from_ppm,
)
from ceco_core.contracts import check_finite as _check_finite
from ceco_core.psychro import humidity_ratio
from ceco_plant_sim.plant_params import PlantParams

__all__ = ["PlantState", "PlantOutputs", "ENVIRONMENT_FIELDS", "validate_environment"]


_ENV_RANGES = {
    "t_amb_c": (-40.0, 60.0),
    "solar_wm2": (0.0, 1500.0),
    "speed_mps": (0.0, 80.0),
    "rh": (0.0, 1.0),
}

ENVIRONMENT_FIELDS = tuple(_ENV_RANGES)
"""The environment's fields in the plant's order: t_amb_c [degC], solar_wm2 [W/m2], speed_mps [m/s], rh [0..1]."""


def validate_environment(env) -> tuple[float, ...]:
    """Check an environment (any object with t_amb_c, solar_wm2, speed_mps, rh); return the four floats.

    Raises ValueError naming ``env.<field>`` if missing, not finite or out of
    range (t_amb_c [-40, 60] degC, solar_wm2 [0, 1500] W/m2, speed_mps
    [0, 80] m/s, rh [0, 1]).
    """
    out = []
    for name, (lo, hi) in _ENV_RANGES.items():
        if not hasattr(env, name):
            raise ValueError(f"env.{name}: missing")
        v = _check_finite(f"env.{name}", getattr(env, name))
        if not lo <= v <= hi:
            raise ValueError(f"env.{name}: must be in [{lo}, {hi}], got {v}")
        out.append(v)
    return tuple(out)


@dataclass(frozen=True)
class PlantState:
    """Complete dynamic state of the plant (see the module docstring for the meaning of each field)."""

    t_cab_c: float
    """Cabin air temperature [degC]."""
    t_int_c: float
    """Interior mass temperature (seats, dashboard, trim) [degC]."""
    t_shell_c: float
    """Shell temperature (roof, doors, pillars, floor) [degC]."""
    t_glass_c: float
    """Glazing temperature [degC]."""
    t_evap_c: float
    """Evaporator wall temperature [degC]."""
    t_duct_c: float
    """Wall temperature of the HVAC case, doors, ducts and outlets downstream of the evaporator [degC]."""
    w_cab_kgkg: float
    """Cabin humidity ratio [kg water / kg dry air]; beyond saturation vapour + fog (docs/plant.md "cabin humidity")."""
    comp_pi_integral_rpm: float = 0.0
    """Integral part of the A/C ECU's compressor speed PI [rpm]."""
    recirc_share: float = RECIRC_SHARE_DEFAULT
    """Position of the fresh/recirculation door: recirculated share of the blower flow [0..1]."""
    co2_cab_kgkg: float = co2_kgkg_from_ppm(CO2_AMB_PPM_DEFAULT)
    """Cabin CO2 [kg CO2 / kg dry air] (``ceco_core.air_quality.co2_ppm_from_kgkg`` gives ppm)."""

    def validate(self) -> PlantState:
        """Raise ValueError naming the field if it is not finite or physically impossible."""
        for f in fields(self):
            _check_finite(f.name, getattr(self, f.name))
        for name in ("t_cab_c", "t_int_c", "t_shell_c", "t_glass_c", "t_evap_c", "t_duct_c"):
            v = getattr(self, name)
            if not -40.0 <= v <= 120.0:
                raise ValueError(f"{name}: must be in [-40, 120] degC, got {v}")
        if not 0.0 <= self.w_cab_kgkg <= 0.3:  # saturation at 70 degC is 0.28 kg/kg
            raise ValueError(f"w_cab_kgkg: must be in [0, 0.3] kg/kg, got {self.w_cab_kgkg}")
        if not 0.0 <= self.recirc_share <= 1.0:
            raise ValueError(f"recirc_share: must be in [0, 1], got {self.recirc_share}")
        if not 0.0 <= self.co2_cab_kgkg <= 0.05:  # 0.05 kg/kg = 33000 ppm, far beyond any cabin
            raise ValueError(f"co2_cab_kgkg: must be in [0, 0.05] kg/kg, got {self.co2_cab_kgkg}")
        return self

    def as_tuple(self) -> tuple:
        """The state in field order (the integrator's vector)."""
        return tuple(float(getattr(self, f.name)) for f in fields(self))

    @classmethod
    def from_initial(cls, initial, params: PlantParams, env) -> PlantState:
        """Hot-soak (or any) initial state from a scenario's ``initial`` mapping.

        ``initial`` is a mapping or an object with attributes (the scenario's
        ``InitialState``). Required: ``t_cab_c, t_int_c, t_shell_c`` [degC],
        ``rh_cab`` [0..1]. Optional: ``t_glass_c`` (default t_shell_c: the
        scenario's shell temperature covers the glazing too),
        ``t_evap_c`` (default t_cab_c: the HVAC module under the dashboard
        soaks at cabin air temperature), ``t_duct_c`` (default t_evap_c: the
        case and ducts soak with the module), ``co2_cab_ppm`` (default the
        ambient ``params.co2_amb_ppm``: a parked car's leakage has flushed it).
        The compressor PI starts empty, the door at ``params.recirc_fraction``.
        ``env`` is validated (its ambient is not used for the defaults).
        """
        validate_environment(env)
        if not isinstance(initial, Mapping):
            # a scenario's InitialState (or any object with the attributes)
            initial = {
                k: getattr(initial, k)
                for k in (
                    "t_cab_c",
                    "t_int_c",
                    "t_shell_c",
                    "rh_cab",
                    "t_glass_c",
                    "t_evap_c",
                    "t_duct_c",
                    "co2_cab_ppm",
                )
                if hasattr(initial, k)
            }
        for key in ("t_cab_c", "t_int_c", "t_shell_c", "rh_cab"):
            if key not in initial:
                raise ValueError(f"initial.{key}: missing")
        t_cab = _check_finite("initial.t_cab_c", initial["t_cab_c"])
        rh = _check_finite("initial.rh_cab", initial["rh_cab"])
        if not 0.0 <= rh <= 1.0:
            raise ValueError(f"initial.rh_cab: must be in [0, 1], got {rh}")
        state = cls(
            t_cab_c=t_cab,
            t_int_c=_check_finite("initial.t_int_c", initial["t_int_c"]),
            t_shell_c=_check_finite("initial.t_shell_c", initial["t_shell_c"]),
            t_glass_c=_check_finite("initial.t_glass_c", initial.get("t_glass_c", initial["t_shell_c"])),
            t_evap_c=_check_finite("initial.t_evap_c", initial.get("t_evap_c", t_cab)),
            t_duct_c=_check_finite("initial.t_duct_c", initial.get("t_duct_c", initial.get("t_evap_c", t_cab))),
            w_cab_kgkg=humidity_ratio(t_cab, rh, params.p_atm_pa),
            comp_pi_integral_rpm=0.0,
            recirc_share=float(params.recirc_fraction),
            co2_cab_kgkg=co2_kgkg_from_ppm(
                _check_finite("initial.co2_cab_ppm", initial.get("co2_cab_ppm", params.co2_amb_ppm))
            ),
        )
        return state.validate()


@dataclass(frozen=True)
class PlantOutputs:
    """Physics snapshot after one plant step.

    Temperatures, humidity, speeds and refrigerant states are the values at
    the END of the step; powers are MEANS over the step (energy integrated
    over the sub-steps / dt) and energies are the totals over the step.
    """

    t_cab_c: float
    """Cabin air temperature [degC]."""
    t_int_c: float
    """Interior mass temperature [degC]."""
    t_shell_c: float
    """Shell temperature [degC]."""
    t_glass_c: float
    """Glazing temperature [degC]."""
    t_evap_c: float
    """Evaporator wall temperature [degC] (T_evap of the paper)."""
    t_duct_c: float
    """HVAC case and duct wall temperature [degC]."""
    t_vent_c: float
    """Air temperature at the vents [degC] (T_ain of the paper)."""
    t_evap_out_c: float
    """Air temperature leaving the evaporator [degC]."""
    t_evap_sat_c: float
    """Refrigerant evaporating temperature [degC]."""
    t_cond_c: float
    """Refrigerant condensing temperature [degC]."""
    rh_cab: float
    """Cabin relative humidity [0..1] (1 at most: water beyond saturation is fog)."""
    w_cab_kgkg: float
    """Cabin humidity ratio [kg/kg dry air]; beyond saturation vapour + fog."""
    p_comp_w: float
    """Compressor electrical power, step mean [W]."""
    p_blower_w: float
    """Blower electrical power, step mean [W]."""
    p_cond_fan_w: float
    """Condenser fan electrical power, step mean [W]."""
    e_comp_j: float
    """Compressor electrical energy over the step [J]."""
    e_blower_j: float
    """Blower electrical energy over the step [J]."""
    q_evap_w: float
    """Heat removed from the air by the evaporator (sensible + latent), step mean [W]."""
    q_latent_w: float
    """Latent part of q_evap_w (condensation), step mean [W]."""
    q_evap_ref_w: float
    """Heat absorbed by the refrigerant, step mean [W]."""
    cop: float
    """Step-mean refrigerant capacity / step-mean compressor electrical power [-] (0 if the compressor is off)."""
    comp_speed_rpm: float
    """Compressor speed at the end of the step [rpm] (min speed while duty-cycling, 0 when off)."""
    comp_duty: float
    """On-time fraction of the compressor at the end of the step [0..1] (< 1 only below min speed)."""
    capacity_limited: bool
    """True when the compressor PI demands more than the maximum speed or inverter power allows (end of step)."""
    mop_active: bool
    """True when the expansion valve MOP caps the evaporating temperature at the end of the step."""
    mdot_ref_kgps: float
    """Refrigerant mass flow (duty-averaged) at the end of the step [kg/s]."""
    cycle_iterations: int
    """Newton iterations of the last refrigerant-loop solve [-]."""
    m_water_in_kg: float = 0.0
    """Water entering the cabin air over the step: fresh air, infiltration, occupants [kg]."""
    m_water_out_kg: float = 0.0
    """Water leaving with the exfiltrated air (the fresh share of the supply and the leakage) over the step [kg]."""
    m_condensate_kg: float = 0.0
    """Water condensed on the evaporator (drained) and fog deposited from the cabin air over the step [kg]."""
    recirc_share: float = RECIRC_SHARE_DEFAULT
    """Position of the fresh/recirculation door at the end of the step: recirculated share [0..1]."""
    co2_cab_ppm: float = CO2_AMB_PPM_DEFAULT
    """Cabin CO2 at the end of the step [ppm] (mole fraction in dry air)."""
    m_co2_in_kg: float = 0.0
    """CO2 entering the cabin air with the fresh share of the supply and the leakage over the step [kg]."""
    m_co2_out_kg: float = 0.0
    """CO2 leaving with the exfiltrated air over the step [kg]."""
    m_co2_gen_kg: float = 0.0
    """CO2 exhaled by the occupants over the step [kg]."""
