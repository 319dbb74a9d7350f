"""Cabin air quality: CO2 (units, occupants' generation, the balance), the fog margin and the limits.

Written once and evaluated by the plant (numerically and as CasADi symbols: every function here is
plain arithmetic or :mod:`ceco_core.psychro`), the estimator, the baselines and the KPIs:

* CO2 amounts: ppm on the wire and in the limits (mole fraction in dry air x 1e6, the basis of the
  WMO/NOAA background values), kg CO2 per kg dry air inside the plant (the basis of its water
  balance): :func:`co2_kgkg_from_ppm`, :func:`co2_ppm_from_kgkg`;
* the CO2 an occupant exhales, from the metabolic rate (:func:`co2_generation_kgps`, the ASHRAE form
  relating metabolic rate to oxygen consumption);
* the cabin's CO2 balance (:func:`co2_flows_kgps`): fresh air through the HVAC and leakage enter at the
  ambient fraction and leave at the cabin's, occupants add their generation;
* the leakage (infiltration/exfiltration) that grows with vehicle speed (:func:`leakage_kgps`);
* the windshield fog margin (:func:`fog_margin_k`): inner glazing temperature minus the cabin dew point;
* the doors' economiser (:func:`economiser_open`): outside air while it is the cheaper air to cool;
* the limits a run is scored against and a controller constrains (:class:`AirQualityLimits`) and the
  named constraint signals (:data:`AQ_SIGNALS`, :func:`aq_violation`).

Equations, units, sources and the certainty of each value: docs/plant.md ("Cabin air quality").

Pure logic: numpy, dataclasses; no ROS.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

from ceco_core import psychro

__all__ = [
    "M_AIR_KGPMOL",
    "M_CO2_KGPMOL",
    "KGKG_PER_PPM",
    "RHO_CO2_STP_KGM3",
    "MET_WM2",
    "CO2_AMB_PPM_DEFAULT",
    "RECIRC_SHARE_DEFAULT",
    "co2_kgkg_from_ppm",
    "co2_ppm_from_kgkg",
    "co2_generation_kgps",
    "leakage_kgps",
    "Co2Flows",
    "co2_flows_kgps",
    "co2_steady_ppm",
    "coil_outlet_humidity_ratio",
    "WaterFlows",
    "cabin_water_flows_kgps",
    "fog_margin_k",
    "fog_margin_of",
    "fog_override",
    "economiser_open",
    "AQ_SIGNALS",
    "AqSignals",
    "AirQualityLimits",
    "aq_violation",
    "check_settings",
]

M_AIR_KGPMOL = 0.028965
"""Molar mass of dry air [kg/mol] (ASHRAE Fundamentals 2017 ch. 1: 28.966 g/mol)."""
M_CO2_KGPMOL = 0.04401
"""Molar mass of CO2 [kg/mol] (44.0095 g/mol, IUPAC atomic weights)."""
KGKG_PER_PPM = 1e-6 * M_CO2_KGPMOL / M_AIR_KGPMOL
"""kg CO2 per kg dry air of 1 ppm (mole fraction in dry air x 1e6): 1.519e-6."""
RHO_CO2_STP_KGM3 = 1.977
"""Density of CO2 gas at 0 degC, 101.325 kPa [kg/m3] (the STPD volume of respiratory physiology to mass;
real gas; 1.963 if ideal)."""
MET_WM2 = 58.15
"""1 met [W/m2] (ISO 7730:2005; ASHRAE Fundamentals 2017 ch. 9)."""
CO2_AMB_PPM_DEFAULT = 425.0
"""Ambient (background) CO2 [ppm]: WMO Greenhouse Gas Bulletin 21, global mean 423.9 ppm in 2024,
+2.5..3.5 ppm per year (docs/plant.md)."""
RECIRC_SHARE_DEFAULT = 0.8
"""Recirculated share of the blower flow when no controller commands the door [-]: the fixed share of the
plant before issue 21 (``PlantParams.recirc_fraction``)."""

_ASHRAE_O2_KJPL = 21.0
"""ASHRAE Fundamentals ch. 9: M = 21 (0.23 RQ + 0.77) Q_O2 / A_D, M [W/m2], Q_O2 [mL/s] at STP: the
energy equivalent of oxygen, 21 (0.23 RQ + 0.77) kJ per litre (20.2 kJ/L at RQ 0.83)."""


def co2_kgkg_from_ppm(ppm):
    """Mass ratio [kg CO2 / kg dry air] of a CO2 mole fraction in dry air ``ppm`` [ppm]."""
    return ppm * KGKG_PER_PPM


def co2_ppm_from_kgkg(x_kgkg):
    """CO2 mole fraction in dry air [ppm] of a mass ratio ``x_kgkg`` [kg CO2 / kg dry air]."""
    return x_kgkg / KGKG_PER_PPM


def co2_generation_kgps(met, body_area_m2: float = 1.8, rq: float = 0.83):
    """CO2 exhaled by one person [kg/s] at metabolic rate ``met`` [met].

    The ASHRAE relation of metabolic rate and oxygen consumption (Fundamentals 2017 ch. 9; the form
    Persily & de Jonge, Indoor Air 27 (2017) 868, review as the basis of earlier CO2 generation rates):

        Q_O2 = M A_D / (21 (0.23 RQ + 0.77))   [mL/s at 0 degC, 101.325 kPa],  M = 58.15 met [W/m2]
        V_CO2 = RQ Q_O2,   mdot_CO2 = rho_CO2 V_CO2

    Where ``body_area_m2`` is the DuBois body surface area A_D [m2] (1.8: the 70 kg, 1.73 m adult),
    ``rq`` the respiratory quotient [-] (0.83 sedentary, ASHRAE). 1.2 met: 5.17 mL/s, 1.02e-5 kg/s
    (ASTM D6245 gives 0.0052 L/s at 1.2 met). Valid for steady, sedentary to moderate activity.
    """
    q_o2_lps = met * MET_WM2 * body_area_m2 / (_ASHRAE_O2_KJPL * 1000.0 * (0.23 * rq + 0.77))
    return rq * q_o2_lps * 1e-3 * RHO_CO2_STP_KGM3


def leakage_kgps(leak_0_kgps, leak_per_mps_kgps, speed_mps):
    """Leakage air exchange of the closed cabin [kg/s]: ``inf_0 + inf_V V`` (linear in the vehicle speed V [m/s]).

    Infiltration through body seals, the door and the exhaust vents, exfiltrating at the cabin state
    (Knibbs, de Dear & Atkinson, Indoor Air 19 (2009) 303; Ott, Klepeis & Switzer, JESEE 18 (2008) 312:
    linear in speed). Parameters: ``PlantParams.infiltration_0_kgps`` [kg/s],
    ``PlantParams.infiltration_per_mps_kgps`` [kg/s per m/s].
    """
    return leak_0_kgps + leak_per_mps_kgps * speed_mps


class Co2Flows(NamedTuple):
    """CO2 flows of the cabin air [kg/s]."""

    into: Any
    """With the fresh share of the supply and the leakage, at the ambient fraction [kg/s]."""
    out: Any
    """With the exfiltrated air, at the cabin fraction [kg/s]."""
    generated: Any
    """Exhaled by the occupants [kg/s]."""


def co2_flows_kgps(x_cab_kgkg, x_amb_kgkg, fresh_kgps, n_occupants, generation_kgps) -> Co2Flows:
    """The cabin's CO2 flows [kg/s]; ``m_air dX/dt = into - out + generated``.

    ``fresh_kgps`` = (1 - r) mdot_bl + mdot_inf [kg dry air/s]: the fresh share of the blower flow and
    the leakage, which enter at ``x_amb_kgkg`` and, the cabin's mass being constant, leave at
    ``x_cab_kgkg`` [kg CO2/kg dry air] (the recirculated share leaves and returns at the cabin state);
    ``n_occupants`` people exhale ``generation_kgps`` [kg/s] each (:func:`co2_generation_kgps`).
    Nothing else removes CO2 (its solubility in the condensate is negligible).
    """
    return Co2Flows(fresh_kgps * x_amb_kgkg, fresh_kgps * x_cab_kgkg, n_occupants * generation_kgps)


def co2_steady_ppm(co2_amb_ppm, fresh_kgps, n_occupants, generation_kgps):
    """Steady cabin CO2 [ppm] of the balance: ambient + n g / (fresh air + leakage)."""
    return co2_amb_ppm + co2_ppm_from_kgkg(n_occupants * generation_kgps / fresh_kgps)


def coil_outlet_humidity_ratio(w_mix_kgkg, w_sat_wall_kgkg, bypass_factor, fmax):
    """Humidity ratio of the air leaving the evaporator [kg/kg] (bypass-factor coil model).

    The share ``1 - bypass_factor`` of the air touches the wall and, where the mixed air's humidity ratio
    ``w_mix_kgkg`` is above the saturation value at the wall temperature ``w_sat_wall_kgkg``, leaves saturated at
    the wall; the rest passes unchanged: ``W_out = W_mix - (1 - BF) max(W_mix - W_sw, 0)`` (ASHRAE Fundamentals
    2017 ch. 1 and the apparatus dew point / bypass factor method of ASHRAE HVAC Systems and Equipment; the
    plant's docs/plant.md "air loop"). ``fmax(a, b)`` is the backend's max (exact or smooth), so the plant and
    the NMPC evaluate this one expression.
    """
    return w_mix_kgkg - (1.0 - bypass_factor) * fmax(w_mix_kgkg - w_sat_wall_kgkg, 0.0)


class WaterFlows(NamedTuple):
    """The cabin air's water flows [kg/s]: ``m_air dW/dt = into - out - condensate``."""

    into: Any
    """In with the fresh share of the supply, the leakage and the occupants [kg/s]."""
    out: Any
    """Out with the exfiltrated air, at the cabin state [kg/s]."""
    condensate: Any
    """Condensed from the supply air on the coil and drained [kg/s]."""


def cabin_water_flows_kgps(w_cab_kgkg, w_amb_kgkg, w_mix_kgkg, w_out_kgkg, fresh_kgps, mdot_bl_kgps, generation_kgps):
    """The cabin air's water balance [kg/s] (docs/plant.md "cabin humidity").

    ``fresh_kgps`` = (1 - r) mdot_bl + mdot_inf enters at the ambient ``w_amb_kgkg`` and leaves at the cabin's
    ``w_cab_kgkg``; the occupants add ``generation_kgps`` (their latent heat over h_fg); the coil takes
    ``mdot_bl (W_mix - W_out)`` from the supply (:func:`coil_outlet_humidity_ratio`). Identical to
    ``mdot_bl (W_out - W_cab) + mdot_inf (W_amb - W_cab) + generation``.
    """
    return WaterFlows(
        fresh_kgps * w_amb_kgkg + generation_kgps,
        fresh_kgps * w_cab_kgkg,
        mdot_bl_kgps * (w_mix_kgkg - w_out_kgkg),
    )


def fog_margin_k(t_glass_c, p_w_pa):
    """Windshield fog margin [K]: inner glazing temperature ``t_glass_c`` [degC] minus the cabin dew point.

    The dew point of cabin air whose water vapour partial pressure is ``p_w_pa`` [Pa]
    (:func:`ceco_core.psychro.dew_point_c`). Water condenses on the glass where the margin is < 0. The
    plant's lumped glazing node stands for the inner surface (docs/plant.md: the surface lies within
    0.4 K of the node at a 10 K cabin-glass difference).
    """
    return t_glass_c - psychro.dew_point_c(p_w_pa)


AQ_SIGNALS = ("co2_cab_ppm", "fog_margin_k")
"""The air-quality constraint signals, by name: cabin CO2 [ppm] (<= the limit) and the fog margin [K]
(>= its bound)."""


def fog_margin_of(t_cab_c, rh_cab, t_glass_c) -> float:
    """The fog margin [K] of measured cabin air (temperature [degC], RH [0..1]) and glass [degC].

    :func:`fog_margin_k` of the readings; NaN when a reading is missing or implausible (a controller then has no
    fog override, it does not guess).
    """
    try:
        t, rh, tg = float(t_cab_c), float(rh_cab), float(t_glass_c)
    except (TypeError, ValueError, OverflowError):
        return math.nan
    if not (math.isfinite(t) and math.isfinite(tg) and 0.0 < rh <= 1.0):
        return math.nan
    return float(fog_margin_k(tg, psychro.vapour_pressure_pa(t, rh)))


def fog_override(active: bool, fog_margin_k: float, fog_margin_min_k: float, enter_k: float, exit_k: float) -> bool:
    """Whether a door's fog override is on after this reading of the fog margin [K].

    It starts below the bound plus ``enter_k`` [K] and ends above the bound plus ``exit_k`` [K] (hysteresis); an
    unknown (NaN) margin leaves it as it was (``active``).
    """
    if math.isfinite(fog_margin_k):
        if fog_margin_k < fog_margin_min_k + enter_k:
            return True
        if fog_margin_k > fog_margin_min_k + exit_k:
            return False
    return bool(active)


def economiser_open(t_cab_c, t_amb_c, rh_cab, rh_amb, economiser_k: float) -> bool:
    """Whether outside air is the cheaper evaporator inlet now: the economiser of both doors.

    Outside air when it is cooler than the cabin air by ``economiser_k`` [K] (dry bulb, degC) and, where both
    humidities are known (RH in [0, 1]), also lower in enthalpy by ``c_p,a economiser_k``
    (:func:`ceco_core.psychro.moist_air_enthalpy_jpkg`): the "differential enthalpy + fixed dry bulb" high-limit
    control of building economisers (ANSI/ASHRAE/IES Standard 90.1, table 6.5.1.1.3), with the cabin air as the
    return air and the dry-bulb limit differential too. On a humid day the outside air can be cooler than a soaked
    cabin and still carry more heat into a wet coil: at 32 degC and 65 % RH, 82 kJ/kg against 66 kJ/kg for the cabin
    at 34.7 degC and 35 % RH. Unknown temperatures: no economiser; unknown or implausible humidities: the dry-bulb
    rule alone (what the car can still judge). Pure; floats in, bool out.
    """
    try:
        tc, ta = float(t_cab_c), float(t_amb_c)
    except (TypeError, ValueError, OverflowError):
        return False
    if not (math.isfinite(tc) and math.isfinite(ta) and ta <= tc - economiser_k):
        return False
    try:
        rc, ra = float(rh_cab), float(rh_amb)
    except (TypeError, ValueError, OverflowError):
        return True
    if not (0.0 <= rc <= 1.0 and 0.0 <= ra <= 1.0):  # False for NaN too
        return True
    h_cab = psychro.moist_air_enthalpy_jpkg(tc, psychro.humidity_ratio(tc, rc))
    h_amb = psychro.moist_air_enthalpy_jpkg(ta, psychro.humidity_ratio(ta, ra))
    return bool(h_amb <= h_cab - psychro.CP_DRY_AIR_JPKGK * economiser_k)


class AqSignals(NamedTuple):
    """The air-quality constraint signals at one instant (:data:`AQ_SIGNALS`)."""

    co2_cab_ppm: Any
    """Cabin CO2 [ppm]; must stay <= ``AirQualityLimits.co2_limit_ppm``."""
    fog_margin_k: Any
    """Inner glazing temperature minus cabin dew point [K]; must stay >= ``AirQualityLimits.fog_margin_min_k``."""


@dataclasses.dataclass(frozen=True)
class AirQualityLimits:
    """What breathable air and a clear windshield mean in a run (scenario ``air_quality:``; docs/plant.md)."""

    co2_limit_ppm: float = 1500.0
    """Largest acceptable cabin CO2 [ppm] (absolute; DIN 1946-2 / UBA 2008 guide value; 1000 and 2000 are the
    sensitivity values)."""
    fog_margin_min_k: float = 3.0
    """Smallest acceptable fog margin [K]: the glass 3 K above the dew point, RH 80-83 % at the glass (judgement
    for a model without a glass sensor that lumps all glazing; 2-5 K)."""

    def validate(self) -> AirQualityLimits:
        """Raise ValueError naming the field if a limit is not finite or outside its range; return self."""
        for name, lo, hi in (("co2_limit_ppm", 450.0, 10000.0), ("fog_margin_min_k", 0.0, 10.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"AirQualityLimits.{name}: must be a finite number, got {v!r}")
            if not lo <= v <= hi:
                raise ValueError(f"AirQualityLimits.{name}: must be in [{lo}, {hi}], got {v}")
        return self


def aq_violation(signals: AqSignals, limits: AirQualityLimits) -> AqSignals:
    """How far each signal lies beyond its limit (> 0: violated), by name [ppm, K].

    ``co2_cab_ppm - co2_limit_ppm`` and ``fog_margin_min_k - fog_margin_k``: the constraint functions
    g <= 0 of a controller's soft constraints and of the scoring, numeric or symbolic.
    """
    return AqSignals(
        co2_cab_ppm=signals.co2_cab_ppm - limits.co2_limit_ppm,
        fog_margin_k=limits.fog_margin_min_k - signals.fog_margin_k,
    )


def check_settings(obj, positive: tuple = (), skip: tuple = ()) -> None:
    """Raise ValueError naming the field unless the dataclass fields of ``obj`` are finite numbers >= 0.

    Fields in ``skip`` are not checked, those in ``positive`` must be > 0 (the air-quality settings and
    parameters: the CO2 sensor, the CO2 estimator, the door logic).
    """
    owner = type(obj).__name__
    for f in dataclasses.fields(obj):
        if f.name in skip:
            continue
        v = getattr(obj, f.name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ValueError(f"{owner}.{f.name}: must be a finite number >= 0, got {v!r}")
        if f.name in positive and not v > 0:
            raise ValueError(f"{owner}.{f.name}: must be > 0, got {v!r}")
