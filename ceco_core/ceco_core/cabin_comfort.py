"""Comfort of a car occupant: the scored PMV, the draught rating and the fog margin.

The method paper's modified PMV (Wang et al., DSCC 2019, Sec. 3: ISO 7730 PMV
with the absorbed sun W_rad on the gain side) evaluated with the cabin's
environment *at the occupant*:

    t_a, v_ar   body-average air temperature and speed in the panel-vent jets
                (:func:`ceco_core.occupant.occupant_air`; replaces the paper's
                T_a = a1 T_cab + a2 T_ain and its linear speed map)
    t_r         mean radiant temperature of glazing, shell trim and interior
                (:func:`ceco_core.occupant.mean_radiant_temperature_c`; replaces T_mr = T_int)
    W_rad       absorbed sun by ASHRAE 55-2020 App. C SolarCal with the
                scenario's sun position and heading (:mod:`ceco_core.solarcal`)
    p_a         the cabin's water vapour pressure (the plant's moisture
                balance) or, as a controller setting, the paper's 1700 Pa

plus the ISO 7730 draught rating in the jet at the upper body
(:mod:`ceco_core.draught`) and the fog margin (inner glazing temperature minus
the cabin dew point). The same functions evaluate numpy arrays (plant, metrics)
and CasADi symbols (NMPC). Parameters, sources and measured consequences:
docs/comfort.md.
"""

import dataclasses
import functools
import math
from typing import Any

import numpy as np

from ceco_core import mathops, psychro
from ceco_core.air_quality import fog_margin_k
from ceco_core.comfort import DEFAULT_SMOOTHING, PmvSmoothing, iso7730_validity, pmv, ppd
from ceco_core.draught import DR_EXACT, draught_rating
from ceco_core.occupant import (
    OccupantAirParams,
    RadiantParams,
    mean_radiant_temperature_c,
    occupant_air,
    shell_inside_surface_c,
)
from ceco_core.solarcal import relative_azimuth_deg, solar_gain

__all__ = [
    "PAPER_PA_PA",
    "GLAZING_TAU",
    "SHELL_U_IN_WM2K",
    "SolarParams",
    "ComfortParams",
    "comfort_params_for",
    "cabin_w_rad_wm2",
    "cabin_mrt_c",
    "cabin_pmv",
    "cabin_draught_pct",
    "OccupantComfort",
    "evaluate_cabin_comfort",
]

PAPER_PA_PA = 1700.0
"""The method paper's constant cabin water vapour pressure [Pa] (Sec. 3, assumption 4)."""

GLAZING_TAU = 0.45
"""Total solar transmittance of the glazing [-]: the ONE value of the plant (``PlantParams.tau_glass``
defaults to it) and of the comfort model (laminated windshield ~0.45-0.5, docs/plant.md)."""

SHELL_U_IN_WM2K = 3.5
"""Conductance shell sheet -> cabin air through trim and inside film [W/(m2 K)]: ``PlantParams.u_shell_in_wm2k``
defaults to it; the comfort model uses it for the trim surface temperature."""


def _number(cls, name, value, lo, hi):
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not lo <= value <= hi
    ):
        raise ValueError(f"{cls}.{name} must be a finite number in [{lo}, {hi}], got {value!r}")


@dataclasses.dataclass(frozen=True)
class SolarParams:
    """Sun on the occupant (ASHRAE 55-2020 App. C SolarCal inputs other than the irradiance)."""

    altitude_deg: float = 60.0
    """Solar altitude [deg], 0..90."""
    sharp_deg: float = 0.0
    """Sun's horizontal angle from the occupant's front (SHARP) [deg], 0..180 (0 = ahead)."""
    glazing_tau: float = GLAZING_TAU
    """Total solar transmittance of the glazing between sun and occupant T_sol [-]."""
    f_bes: float = 0.5
    """Fraction of the possible body surface in direct sun inside the cabin [-]."""
    f_svv: float = 0.0
    """Fraction of the sky vault in the occupant's view [-] (0: a lamp test has no sky; roof shades it)."""
    asw: float = 0.67
    """Short-wave absorptivity of skin and clothing alpha_sw [-]."""
    floor_reflectance: float = 0.6
    """Short-wave reflectance of the sunlit surfaces below the occupant [-] (used only with f_svv > 0)."""

    def validate(self):
        """Raise ValueError naming the first invalid field; return self."""
        _number("SolarParams", "altitude_deg", self.altitude_deg, 0.0, 90.0)
        _number("SolarParams", "sharp_deg", self.sharp_deg, 0.0, 180.0)
        for name in ("glazing_tau", "f_bes", "f_svv", "asw", "floor_reflectance"):
            _number("SolarParams", name, getattr(self, name), 0.0, 1.0)
        return self

    @functools.cached_property
    def w_rad_per_irradiance(self):
        """Absorbed short-wave flux per body area per unit direct irradiance [-] (SolarCal at I_dir = 1 W/m2).

        Computed once per (frozen) parameter set: SolarCal with its input checks is about 85 us, and the controllers
        (and the plant's Python evaluation) read this at every comfort evaluation (:func:`cabin_w_rad_wm2`).
        """
        return float(
            solar_gain(
                sol_altitude_deg=self.altitude_deg,
                sharp_deg=self.sharp_deg,
                sol_radiation_dir_wm2=1.0,
                sol_transmittance=self.glazing_tau,
                f_svv=self.f_svv,
                f_bes=self.f_bes,
                asw=self.asw,
                floor_reflectance=self.floor_reflectance,
            ).w_rad_wm2
        )


@dataclasses.dataclass(frozen=True)
class ComfortParams:
    """Parameters of the occupant comfort evaluation (values and sources: docs/comfort.md)."""

    met: float = 1.2
    """Metabolic rate of the driver [met]."""
    clo: float = 0.5
    """Clothing insulation, summer [clo]."""
    air: OccupantAirParams = OccupantAirParams()
    """Vent-jet exposure of the occupant (air temperature and speed at the occupant)."""
    radiant: RadiantParams = RadiantParams()
    """Angle factors of the occupant to the cabin surfaces (mean radiant temperature)."""
    solar: SolarParams = SolarParams()
    """Sun geometry and optics (SolarCal)."""
    u_shell_in_wm2k: float = SHELL_U_IN_WM2K
    """The plant's shell-to-cabin conductance, for the trim surface temperature [W/(m2 K)]."""
    smoothing: PmvSmoothing = DEFAULT_SMOOTHING
    """Smoothing of the ISO 7730 PMV's non-differentiable terms."""

    def validate(self):
        """Raise ValueError naming the first invalid field; return self."""
        _number("ComfortParams", "met", self.met, 1e-9, 4.0)
        _number("ComfortParams", "clo", self.clo, 0.0, 2.0)
        _number("ComfortParams", "u_shell_in_wm2k", self.u_shell_in_wm2k, 1e-9, self.radiant.h_shell_film_wm2k)
        for name, cls in (
            ("air", OccupantAirParams),
            ("radiant", RadiantParams),
            ("solar", SolarParams),
            ("smoothing", PmvSmoothing),
        ):
            value = getattr(self, name)
            if not isinstance(value, cls):
                raise ValueError(f"ComfortParams.{name} must be a {cls.__name__}, got {value!r}")
            value.validate()
        return self


def comfort_params_for(scenario, *, glazing_tau=GLAZING_TAU, u_shell_in_wm2k=SHELL_U_IN_WM2K) -> ComfortParams:
    """Comfort parameters of a scenario: its occupant (met, clo) and its sun.

    The sun: altitude, and SHARP from the sun's azimuth and the car's heading
    (:func:`ceco_core.solarcal.relative_azimuth_deg`).

    ``glazing_tau`` and ``u_shell_in_wm2k`` are the plant's (``PlantParams.tau_glass``,
    ``PlantParams.u_shell_in_wm2k``); the defaults are the plant's defaults.
    """
    sun = scenario.sun
    solar = SolarParams(
        altitude_deg=float(sun.altitude_deg),
        sharp_deg=float(relative_azimuth_deg(sun.azimuth_deg, sun.heading_deg)),
        glazing_tau=float(glazing_tau),
    )
    return ComfortParams(
        met=scenario.occupant.met, clo=scenario.occupant.clo, solar=solar, u_shell_in_wm2k=float(u_shell_in_wm2k)
    ).validate()


def cabin_w_rad_wm2(solar_wm2, params):
    """Absorbed sun per m2 of body W_rad [W/m2] from the direct irradiance ``solar_wm2`` [W/m2] (SolarCal)."""
    return params.solar.w_rad_per_irradiance * solar_wm2


def cabin_mrt_c(*, t_cab_c, t_int_c, t_shell_c, t_glass_c, params):
    """Mean radiant temperature at the occupant [degC] from the cabin nodes (glazing, shell trim, interior)."""
    t_sh_in = shell_inside_surface_c(t_cab_c, t_shell_c, params.u_shell_in_wm2k, params.radiant.h_shell_film_wm2k)
    return mean_radiant_temperature_c(t_glass_c=t_glass_c, t_shell_in_c=t_sh_in, t_int_c=t_int_c, params=params.radiant)


def cabin_pmv(*, t_cab_c, t_vent_c, mdot_bl_kgps, t_mr_c, w_rad_wm2, pa_pa, params, met=None, clo=None):
    """The scored PMV of the occupant (plant and NMPC): ISO 7730 PMV + W_rad at the occupant's environment.

    Args:
        t_cab_c: mean cabin air temperature [degC].
        t_vent_c: vent (discharge) air temperature, the paper's T_ain [degC].
        mdot_bl_kgps: blower air mass flow [kg/s], >= 0.
        t_mr_c: mean radiant temperature [degC] (:func:`cabin_mrt_c`).
        w_rad_wm2: absorbed sun per body area [W/m2] (:func:`cabin_w_rad_wm2`).
        pa_pa: cabin water vapour pressure [Pa] (measured, or :data:`PAPER_PA_PA`).
        params: :class:`ComfortParams` (validated here).
        met: metabolic rate [met]; default params.met.
        clo: clothing insulation [clo]; default params.clo.

    Returns:
        PMV [-] (numpy array or CasADi expression).
    """
    params.validate()
    air = occupant_air(t_cab_c=t_cab_c, t_vent_c=t_vent_c, mdot_bl_kgps=mdot_bl_kgps, params=params.air)
    return _pmv_at(air, t_mr_c, w_rad_wm2, pa_pa, params, met, clo)


def _pmv_at(air, t_mr_c, w_rad_wm2, pa_pa, params, met=None, clo=None):
    """ISO 7730 PMV + W_rad in the occupant's air ``air`` (:class:`~ceco_core.occupant.OccupantAir`)."""
    return pmv(
        ta_c=air.ta_occ_c,
        tr_c=t_mr_c,
        vel_mps=air.vel_occ_mps,
        pa_pa=pa_pa,
        met=params.met if met is None else met,
        clo=params.clo if clo is None else clo,
        w_rad_wm2=w_rad_wm2,
        smoothing=params.smoothing,
    )


def cabin_draught_pct(*, t_cab_c, t_vent_c, mdot_bl_kgps, params, cap=True, smoothing=None):
    """ISO 7730 draught rating [%] at the occupant: in the vent jet at the upper body (neck and face).

    Local air temperature and mean speed of the jet (:func:`ceco_core.occupant.occupant_air`; in the
    recirculating cabin air instead if ``params.air.dr_in_jet`` is False), turbulence intensity
    ``params.air.tu_pct``. ``cap=False`` gives the uncapped intensity for a
    penalty with a gradient beyond 100 %; ``smoothing`` defaults to the smooth DR (NLP use).
    """
    air = occupant_air(t_cab_c=t_cab_c, t_vent_c=t_vent_c, mdot_bl_kgps=mdot_bl_kgps, params=params.air)
    return _draught_at(air, params, cap, smoothing)


def _draught_at(air, params, cap=True, smoothing=None):
    """ISO 7730 draught rating [%] where ``air`` says it is rated (jet or cabin air)."""
    kw = {} if smoothing is None else {"smoothing": smoothing}
    return draught_rating(air.ta_dr_c, air.vel_dr_mps, params.air.tu_pct, cap=cap, **kw)


@dataclasses.dataclass(frozen=True)
class OccupantComfort:
    """The comfort series of one evaluation (numpy scalars or arrays)."""

    pmv: Any
    """Scored PMV [-]."""
    ppd: Any
    """PPD of that PMV [%]."""
    pa_pa: Any
    """Cabin water vapour pressure used in the PMV [Pa]."""
    t_dew_c: Any
    """Cabin dew point [degC]."""
    fog_margin_k: Any
    """Inner glazing temperature minus cabin dew point [K] (fogging where < 0)."""
    dr_pct: Any
    """ISO 7730 draught rating at the occupant (jet at the upper body by default; exact ISO corners) [%]."""
    ta_occ_c: Any
    """PMV air temperature at the occupant (body average) [degC]."""
    vel_occ_mps: Any
    """PMV air speed at the occupant (body average) [m/s]."""
    t_mr_c: Any
    """PMV mean radiant temperature [degC]."""
    w_rad_wm2: Any
    """PMV absorbed sun [W/m2]."""
    iso7730_valid: Any
    """True where every PMV input and the PMV lie inside ISO 7730 Clause 4 ranges."""
    ta_jet_c: Any
    """Draught rating's local air temperature (jet at the upper body) [degC]."""
    vel_jet_mps: Any
    """Draught rating's local mean air speed (jet at the upper body) [m/s]."""


def evaluate_cabin_comfort(
    *, t_cab_c, t_vent_c, t_int_c, t_shell_c, t_glass_c, rh_cab, mdot_bl_kgps, solar_wm2, params, pa_pa=None
):
    """Every comfort series from the plant's measurements (numpy: plant, metrics; CasADi: compiled plant).

    ``pa_pa`` (the PMV's vapour pressure) defaults to the cabin's, rh_cab * p_ws(T_cab) (the plant's
    moisture balance); pass :data:`PAPER_PA_PA` to score with the paper's constant. The dew point
    and fog margin are always the cabin air's (a scored constant does not wet the windscreen).
    With CasADi inputs every field is an expression (``iso7730_valid`` a 0/1 one).
    """
    params.validate()
    symbolic = mathops.is_casadi(t_cab_c, t_vent_c, t_int_c, t_shell_c, t_glass_c, rh_cab, mdot_bl_kgps, solar_wm2)

    def arr(v):
        return v if symbolic else np.asarray(v, dtype=float)

    t_cab = arr(t_cab_c)
    pa_cab = psychro.vapour_pressure_pa(t_cab, arr(rh_cab))
    pa = pa_cab if pa_pa is None else arr(pa_pa)
    air = occupant_air(t_cab_c=t_cab, t_vent_c=arr(t_vent_c), mdot_bl_kgps=arr(mdot_bl_kgps), params=params.air)
    t_mr = cabin_mrt_c(
        t_cab_c=t_cab, t_int_c=arr(t_int_c), t_shell_c=arr(t_shell_c), t_glass_c=arr(t_glass_c), params=params
    )
    w_rad = cabin_w_rad_wm2(arr(solar_wm2), params)
    y = _pmv_at(air, t_mr, w_rad, pa, params)  # the NMPC's cabin_pmv, in the same air
    t_dew = psychro.dew_point_c(pa_cab)
    valid = iso7730_validity(air.ta_occ_c, t_mr, air.vel_occ_mps, pa, params.met, params.clo, y).all
    dr = _draught_at(air, params, smoothing=DR_EXACT)
    return OccupantComfort(
        pmv=y,
        ppd=ppd(y),
        pa_pa=pa,
        t_dew_c=t_dew,
        fog_margin_k=fog_margin_k(arr(t_glass_c), pa_cab),
        dr_pct=dr,
        ta_occ_c=air.ta_occ_c,
        vel_occ_mps=air.vel_occ_mps,
        t_mr_c=t_mr,
        w_rad_wm2=w_rad,
        iso7730_valid=valid,
        ta_jet_c=air.ta_jet_c,
        vel_jet_mps=air.vel_jet_mps,
    )
