"""The thermal environment at the occupant: vent-jet air speed and temperature, mean radiant temperature.

These turn the plant's lumped states (mean cabin air, vent air, blower flow,
interior / shell / glazing nodes) into the inputs of the PMV (body-average
air temperature and speed, mean radiant temperature) and of the ISO 7730
draught rating (local air temperature and speed in the jet at the upper
body). One implementation for numpy and CasADi (:func:`mathops.backend`);
every function is smooth in the states and inputs.

Vent jets (free turbulent round jets, Pope 2000 sec. 5.1; Hussein, Capp &
George, J. Fluid Mech. 258 (1994) 31-75; Chen & Rodi 1980):

    U_0     = mdot / (rho_vent A_vents)                       outlet speed, rho_vent = p / (R_a T_vent)
    phi     = smooth_min(1, K_u sqrt(A_1) / x)                 centreline speed ratio at the occupant
    v_jet   = phi U_0                                          jet speed at the upper body
    theta   = smooth_min(1, r_T phi)                           jet temperature-excess ratio at the occupant
    t_jet   = T_cab + theta (T_vent - T_cab)                   local air temperature in the jet
    v_room  = v_still + c_room U_0                             recirculating cabin air on the rest of the body

Body average for the PMV (forced convection h_c = 12.1 sqrt(v), ISO 7730
eq. (3)): with a share f_j of the body surface in the jets,

    s       = f_j sqrt(v_jet) + (1 - f_j) sqrt(v_room)
    v_occ   = s^2                                              the uniform speed with the same mean h_c
    t_occ   = T_cab + (f_j sqrt(v_jet) / s) (t_jet - T_cab)    the h_c-weighted mean air temperature

so that sum_i A_i h_c,i (t_cl - t_a,i) = A h_c(v_occ) (t_cl - t_occ) for a
uniform clothing temperature: the exact body average of ISO 7730's forced
convection term.

Mean radiant temperature (ISO 7726:1998, from angle factors F_i and surface
temperatures T_i, absolute):

    T_mr^4 = F_gl T_gl^4 + F_sh T_sh,in^4 + F_int T_int^4,     T_sh,in = T_cab + (U_sh / h_film)(T_sh - T_cab)

T_sh,in is the inside (trim) surface of the shell: the sheet-metal node seen
through the trim, with the series resistance of ``u_shell_in_wm2k``
(which includes the inside film h_film).

Parameter values, sources and the measured consequences: docs/comfort.md.
"""

import dataclasses
import math

from ceco_core import mathops, units
from ceco_core.psychro import P_ATM_PA

__all__ = [
    "R_DRY_AIR_JPKGK",
    "OccupantAirParams",
    "RadiantParams",
    "OccupantAir",
    "vent_speed_mps",
    "occupant_air",
    "shell_inside_surface_c",
    "mean_radiant_temperature_c",
]

R_DRY_AIR_JPKGK = 287.05
"""Specific gas constant of dry air [J/(kg K)] (ASHRAE Fundamentals 2017 ch. 1)."""

_KELVIN = units.ZERO_C_K
"""0 degC in K: the ISO 7726 fourth-power average is taken over absolute temperatures."""


def _positive(obj, names):
    for name in names:
        v = getattr(obj, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ValueError(f"{type(obj).__name__}.{name} must be a finite number > 0, got {v!r}")


def _fraction(obj, names):
    for name in names:
        v = getattr(obj, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 <= v <= 1:
            raise ValueError(f"{type(obj).__name__}.{name} must be in [0, 1], got {v!r}")


@dataclasses.dataclass(frozen=True)
class OccupantAirParams:
    """Vent-jet exposure of the occupant (values and sources: docs/comfort.md, parameter table)."""

    a_vents_m2: float = 0.03
    """Total free area of the panel (face) vents carrying the blower flow [m2]."""
    a_outlet_m2: float = 0.0075
    """Free area of one panel vent (the jet's source) [m2]."""
    x_occupant_m: float = 0.65
    """Distance from the vents to the occupant's upper body along the jet [m]."""
    k_jet: float = 6.5
    """Centreline decay constant of a free round jet in u_c/U_0 = K sqrt(A_1)/x [-]."""
    r_jet_temperature: float = 0.8
    """Jet temperature-excess ratio over velocity ratio, (dT_c/dT_0)/(u_c/U_0) [-]."""
    jet_body_fraction: float = 0.1
    """Share of the body surface inside the vent jets (face, neck, chest, forearms) [-]."""
    v_still_mps: float = 0.1
    """Air speed on the body without blower flow (still cabin air, movement of a seated person) [m/s]."""
    c_room: float = 0.04
    """Speed of the recirculating cabin air over the outlet speed [-]."""
    tu_pct: float = 30.0
    """Turbulence intensity at the draught-rating location, for the draught rating [%]."""
    dr_in_jet: bool = True
    """Where the draught rating is evaluated: True, in the jet at the upper body (panel vents aimed at
    the occupant); False, in the recirculating cabin air (vents aimed away; then also set
    jet_body_fraction = 0)."""
    p_atm_pa: float = P_ATM_PA
    """Pressure of the vent air for its density [Pa]."""
    k_smooth: float = 50.0
    """Sharpness of the smooth caps of phi and theta at 1 [-]; error <= ln2/k = 0.014."""

    def validate(self):
        """Raise ValueError naming the first invalid field; return self."""
        _positive(
            self,
            (
                "a_vents_m2",
                "a_outlet_m2",
                "x_occupant_m",
                "k_jet",
                "r_jet_temperature",
                "v_still_mps",
                "p_atm_pa",
                "k_smooth",
            ),
        )
        _fraction(self, ("jet_body_fraction",))
        if (
            isinstance(self.c_room, bool)
            or not isinstance(self.c_room, (int, float))
            or not math.isfinite(self.c_room)
            or self.c_room < 0
        ):
            raise ValueError(f"OccupantAirParams.c_room must be a finite number >= 0, got {self.c_room!r}")
        if self.a_outlet_m2 > self.a_vents_m2:
            raise ValueError("OccupantAirParams.a_outlet_m2 must not exceed a_vents_m2")
        if not (isinstance(self.tu_pct, (int, float)) and 0.0 <= self.tu_pct <= 100.0):
            raise ValueError(f"OccupantAirParams.tu_pct must be in [0, 100] %, got {self.tu_pct!r}")
        if not isinstance(self.dr_in_jet, bool):
            raise ValueError(f"OccupantAirParams.dr_in_jet must be a bool, got {self.dr_in_jet!r}")
        return self

    @property
    def phi_exact(self):
        """Centreline speed ratio at the occupant, min(1, K sqrt(A_1)/x) [-] (hard cap; for reporting)."""
        return min(1.0, self.k_jet * math.sqrt(self.a_outlet_m2) / self.x_occupant_m)


@dataclasses.dataclass(frozen=True)
class RadiantParams:
    """Angle factors of the seated driver to the cabin surface groups (tools/mrt_view_factors.py)."""

    f_glass: float = 0.22
    """Angle factor to the glazing [-]."""
    f_shell: float = 0.26
    """Angle factor to the shell's inside trim (headliner, door trims, pillars) [-]."""
    f_interior: float = 0.52
    """Angle factor to the interior mass (instrument panel, seats, floor) [-]."""
    h_shell_film_wm2k: float = 8.0
    """Inside surface film coefficient of the shell trim (convective + radiative) [W/(m2 K)]."""

    def validate(self):
        """Raise ValueError naming the first invalid field; return self."""
        _fraction(self, ("f_glass", "f_shell", "f_interior"))
        _positive(self, ("h_shell_film_wm2k",))
        total = self.f_glass + self.f_shell + self.f_interior
        if abs(total - 1.0) > 1e-9:
            raise ValueError(f"RadiantParams.f_interior: the angle factors must sum to 1, got {total!r}")
        return self


@dataclasses.dataclass(frozen=True)
class OccupantAir:
    """Air at the occupant (numpy arrays or CasADi expressions)."""

    ta_occ_c: object
    """Body-average (h_c-weighted) air temperature, the PMV's t_a [degC]."""
    vel_occ_mps: object
    """Body-average air speed, the PMV's v_ar [m/s]."""
    ta_jet_c: object
    """Local air temperature in the jet at the upper body, the draught rating's t_a,l [degC]."""
    vel_jet_mps: object
    """Local mean air speed of the jet at the upper body, the draught rating's v_a,l [m/s]."""
    vel_vent_mps: object
    """Outlet speed of the panel vents U_0 [m/s]."""
    vel_room_mps: object
    """Speed of the recirculating cabin air on the body outside the jets [m/s]."""
    ta_dr_c: object
    """The draught rating's local air temperature [degC]: the jet's, or T_cab (``dr_in_jet``)."""
    vel_dr_mps: object
    """The draught rating's local mean air speed [m/s]: the jet's, or the room air's (``dr_in_jet``)."""


def vent_speed_mps(mdot_bl_kgps, t_vent_c, params):
    """Outlet speed of the panel vents U_0 = mdot / (rho A) [m/s], rho = p / (R_a (T_vent + 273.15))."""
    rho = params.p_atm_pa / (R_DRY_AIR_JPKGK * (t_vent_c + _KELVIN))
    return mdot_bl_kgps / (rho * params.a_vents_m2)


def occupant_air(*, t_cab_c, t_vent_c, mdot_bl_kgps, params):
    """Air temperature and speed at the occupant from the vent jets (equations: module docstring).

    Args:
        t_cab_c: mean cabin air temperature [degC].
        t_vent_c: vent (discharge) air temperature [degC].
        mdot_bl_kgps: blower air mass flow through the panel vents [kg/s], >= 0.
        params: :class:`OccupantAirParams` (validated here).

    Returns:
        :class:`OccupantAir`.
    """
    p = params.validate()
    ops = mathops.backend(t_cab_c, t_vent_c, mdot_bl_kgps)
    u0 = vent_speed_mps(mdot_bl_kgps, t_vent_c, p)
    one = 1.0 + 0.0 * u0
    phi_raw = p.k_jet * math.sqrt(p.a_outlet_m2) / p.x_occupant_m
    phi = mathops.smooth_min(phi_raw + 0.0 * u0, one, p.k_smooth)
    theta = mathops.smooth_min(p.r_jet_temperature * phi, one, p.k_smooth)
    v_jet = phi * u0
    v_room = p.v_still_mps + p.c_room * u0
    t_jet = t_cab_c + theta * (t_vent_c - t_cab_c)
    # sqrt(v_jet) with v_jet -> 0 at zero flow: keep the argument positive (smooth, error << 1e-6 m/s)
    sj = p.jet_body_fraction * ops.sqrt(v_jet + 1e-12)
    sr = (1.0 - p.jet_body_fraction) * ops.sqrt(v_room)
    s = sj + sr
    return OccupantAir(
        ta_occ_c=t_cab_c + (sj / s) * (t_jet - t_cab_c),
        vel_occ_mps=s * s,
        ta_jet_c=t_jet,
        vel_jet_mps=v_jet,
        vel_vent_mps=u0,
        vel_room_mps=v_room,
        ta_dr_c=t_jet if p.dr_in_jet else t_cab_c + 0.0 * u0,
        vel_dr_mps=v_jet if p.dr_in_jet else v_room,
    )


def shell_inside_surface_c(t_cab_c, t_shell_c, u_shell_in_wm2k, h_film_wm2k):
    """Inside (trim) surface temperature of the shell [degC]: T_cab + (U_sh / h_film) (T_sh - T_cab).

    The conductance sheet -> cabin air U_sh = 1 / (R_trim + 1/h_film) puts the
    surface at the fraction (1/h_film) / (1/U_sh) of the way from the air to
    the sheet.
    """
    if not mathops.is_casadi(u_shell_in_wm2k, h_film_wm2k) and not 0 < u_shell_in_wm2k <= h_film_wm2k:
        raise ValueError("shell_inside_surface_c: need 0 < u_shell_in_wm2k <= h_film_wm2k")
    return t_cab_c + (u_shell_in_wm2k / h_film_wm2k) * (t_shell_c - t_cab_c)


def mean_radiant_temperature_c(*, t_glass_c, t_shell_in_c, t_int_c, params):
    """Mean radiant temperature [degC]: T_mr^4 = sum F_i T_i^4 over glazing, shell trim, interior (absolute T)."""
    p = params.validate()
    ops = mathops.backend(t_glass_c, t_shell_in_c, t_int_c)
    t4 = (
        p.f_glass * ops.power(t_glass_c + _KELVIN, 4)
        + p.f_shell * ops.power(t_shell_in_c + _KELVIN, 4)
        + p.f_interior * ops.power(t_int_c + _KELVIN, 4)
    )
    return ops.power(t4, 0.25) - _KELVIN
