"""Short-wave (solar) gain on an occupant: ANSI/ASHRAE Standard 55-2020, Normative Appendix C (SolarCal).

One implementation for numpy arrays and CasADi symbols (via
:func:`mathops.backend`). In the NMPC the solar geometry and irradiance are
preview *parameters*, never decision variables, so the piecewise-bilinear
projected-area factor (exactly the standard's interpolation of its table) is
acceptable there; it is continuous but not differentiable on the 15-degree
grid lines.

Equations (ASHRAE 55-2020 App. C; Arens et al. 2015):

    E_diff  = f_eff f_svv 0.5 T_sol I_diff                       diffuse sky
    E_dir   = f_eff f_p  T_sol f_bes I_dir                       direct beam
    E_refl  = f_eff f_svv 0.5 T_sol (I_dir sin(beta) + I_diff) R_floor   reflected
    E_solar = E_diff + E_dir + E_refl                            [W/m2 of body]
    ERF     = E_solar alpha_sw / alpha_lw                        effective radiant field
    dMRT    = ERF / (f_eff h_r)                                  mean-radiant-temperature rise

with I_diff = 0.2 I_dir, alpha_lw = 0.95, h_r = 6 W/(m2 K), f_eff = 0.696
(seated) or 0.725 (standing), and f_p(beta, SHARP) the projected area factor
of the posture (table below, bilinear in solar altitude beta and SHARP, the
sun's horizontal angle relative to the front of the person). The absorbed
short-wave flux per m2 of body (DuBois) area is W_rad = alpha_sw E_solar
= alpha_lw ERF: the paper's W_rad in the modified PMV.

References:
    ANSI/ASHRAE Standard 55-2020, Thermal Environmental Conditions for Human
    Occupancy, Normative Appendix C "Procedure for calculating comfort impact
    of solar gain on occupants" (C2, Tables C2-1..).
    Arens, E., Hoyt, T., Zhou, X., Huang, L., Zhang, H., Schiavon, S.,
    "Modeling the comfort effects of short-wave solar radiation indoors",
    Building and Environment 88 (2015) 3-9 (SolarCal).
    Test reference: pythermalcomfort 4.8.0 ``models.solar_gain`` (Tartarini &
    Schiavon, SoftwareX 12 (2020) 100578), via tests/data/solarcal_reference.csv.
"""

import dataclasses

import casadi
import numpy as np

from ceco_core import mathops

__all__ = [
    "ALPHA_LW",
    "H_R_SOLARCAL_WM2K",
    "DIFFUSE_FRACTION",
    "F_EFF",
    "FP_ALTITUDES_DEG",
    "FP_SHARPS_DEG",
    "FP_TABLES",
    "SolarGain",
    "projected_area_factor",
    "solar_gain",
    "relative_azimuth_deg",
]

ALPHA_LW = 0.95
"""Long-wave absorptivity of skin and clothing alpha_lw [-] (ASHRAE 55-2020 App. C)."""
H_R_SOLARCAL_WM2K = 6.0
"""Radiation heat transfer coefficient of SolarCal's dMRT h_r [W/(m2 K)] (ASHRAE 55-2020 App. C)."""
DIFFUSE_FRACTION = 0.2
"""Diffuse sky irradiance as a fraction of the direct-beam irradiance, I_diff = 0.2 I_dir [-] (as SolarCal)."""
F_EFF = {"sitting": 0.696, "standing": 0.725}
"""Fraction of the body surface exchanging radiation with the surroundings f_eff [-] (ASHRAE 55-2020 App. C)."""

FP_ALTITUDES_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)
"""Solar altitudes of the projected-area-factor table [deg] (columns)."""
FP_SHARPS_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0, 105.0, 120.0, 135.0, 150.0, 165.0, 180.0)
"""SHARP angles of the projected-area-factor table [deg] (rows); 0 = sun in front, 180 = behind."""

FP_TABLES = {
    # ASHRAE 55-2020 App. C projected area factors f_p(SHARP row, altitude column), as tabulated for
    # SolarCal (Arens et al. 2015) and in pythermalcomfort 4.8.0; verified through
    # tests/data/solarcal_reference.csv (tests/test_solarcal.py)
    "sitting": (
        (0.290, 0.324, 0.305, 0.303, 0.262, 0.224, 0.177),
        (0.292, 0.328, 0.294, 0.288, 0.268, 0.227, 0.177),
        (0.288, 0.332, 0.298, 0.290, 0.264, 0.222, 0.177),
        (0.274, 0.326, 0.294, 0.289, 0.252, 0.214, 0.177),
        (0.254, 0.308, 0.280, 0.276, 0.241, 0.202, 0.177),
        (0.230, 0.282, 0.262, 0.260, 0.233, 0.193, 0.177),
        (0.216, 0.260, 0.248, 0.244, 0.220, 0.186, 0.177),
        (0.234, 0.258, 0.236, 0.227, 0.208, 0.180, 0.177),
        (0.262, 0.260, 0.224, 0.208, 0.196, 0.176, 0.177),
        (0.280, 0.260, 0.210, 0.192, 0.184, 0.170, 0.177),
        (0.298, 0.256, 0.194, 0.174, 0.168, 0.168, 0.177),
        (0.306, 0.250, 0.180, 0.156, 0.156, 0.166, 0.177),
        (0.300, 0.240, 0.168, 0.152, 0.152, 0.164, 0.177),
    ),
    "standing": (
        (0.350, 0.350, 0.314, 0.258, 0.206, 0.144, 0.082),
        (0.342, 0.342, 0.310, 0.252, 0.200, 0.140, 0.082),
        (0.330, 0.330, 0.300, 0.244, 0.190, 0.132, 0.082),
        (0.310, 0.310, 0.275, 0.228, 0.175, 0.124, 0.082),
        (0.283, 0.283, 0.251, 0.208, 0.160, 0.114, 0.082),
        (0.252, 0.252, 0.228, 0.188, 0.150, 0.108, 0.082),
        (0.230, 0.230, 0.214, 0.180, 0.148, 0.108, 0.082),
        (0.242, 0.242, 0.222, 0.180, 0.153, 0.112, 0.082),
        (0.274, 0.274, 0.245, 0.203, 0.165, 0.116, 0.082),
        (0.304, 0.304, 0.270, 0.220, 0.174, 0.121, 0.082),
        (0.328, 0.328, 0.290, 0.234, 0.183, 0.125, 0.082),
        (0.344, 0.344, 0.304, 0.244, 0.190, 0.128, 0.082),
        (0.347, 0.347, 0.308, 0.246, 0.191, 0.128, 0.082),
    ),
}
"""Projected area factor tables f_p [-] by posture: rows SHARP (FP_SHARPS_DEG), columns altitude (FP_ALTITUDES_DEG)."""

_GRID_STEP_DEG = 15.0


@dataclasses.dataclass(frozen=True)
class SolarGain:
    """SolarCal results (arrays of the broadcast shape, or CasADi expressions)."""

    e_solar_wm2: object
    """Short-wave flux incident on the body per m2 of body surface, E_solar [W/m2]."""
    erf_wm2: object
    """Effective radiant field ERF = E_solar alpha_sw / alpha_lw [W/m2]."""
    delta_mrt_k: object
    """Rise of the mean radiant temperature equivalent to the sun, ERF / (f_eff h_r) [K]."""
    w_rad_wm2: object
    """Absorbed short-wave flux per m2 of body surface, alpha_sw E_solar [W/m2] (the PMV's W_rad)."""


def _hat(ops, x, centre):
    """Piecewise-linear hat function of width 15 deg centred on ``centre`` (bilinear interpolation weights)."""
    return ops.fmax(1.0 - ops.fabs(x - centre) / _GRID_STEP_DEG, 0.0 * x)


def projected_area_factor(sol_altitude_deg, sharp_deg, posture="sitting"):
    """Projected area factor f_p [-] of a seated or standing person (ASHRAE 55-2020 App. C table).

    Bilinear interpolation of :data:`FP_TABLES` in solar altitude (0..90 deg)
    and SHARP (0..180 deg, the sun's horizontal angle from the person's
    front), written as a sum of hat functions so that numpy and CasADi share
    it. Inputs outside the table are clipped to its edges (numpy raises on
    them, see :func:`solar_gain`).
    """
    if posture not in FP_TABLES:
        raise ValueError(f"posture must be one of {sorted(FP_TABLES)}, got {posture!r}")
    ops = mathops.backend(sol_altitude_deg, sharp_deg)
    alt = ops.fmin(ops.fmax(sol_altitude_deg, 0.0 * sol_altitude_deg), 90.0 + 0.0 * sol_altitude_deg)
    sharp = ops.fmin(ops.fmax(sharp_deg, 0.0 * sharp_deg), 180.0 + 0.0 * sharp_deg)
    table = FP_TABLES[posture]
    w_alt = [_hat(ops, alt, a) for a in FP_ALTITUDES_DEG]
    fp = 0.0
    for i, s in enumerate(FP_SHARPS_DEG):
        w_s = _hat(ops, sharp, s)
        row = 0.0
        for j, w_a in enumerate(w_alt):
            row = row + table[i][j] * w_a
        fp = fp + w_s * row
    return fp


def _check(name, value, lo, hi):
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {value!r}")
    if np.any((arr < lo) | (arr > hi)):
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value!r}")
    return arr


def solar_gain(
    *,
    sol_altitude_deg,
    sharp_deg,
    sol_radiation_dir_wm2,
    sol_transmittance,
    f_svv,
    f_bes,
    asw=0.7,
    floor_reflectance=0.6,
    posture="sitting",
):
    """Solar gain on an occupant, ASHRAE 55-2020 App. C (SolarCal); equations in the module docstring.

    Args:
        sol_altitude_deg: solar altitude beta [deg], 0..90.
        sharp_deg: SHARP, the sun's horizontal angle relative to the front
            of the person [deg], 0..180 (symmetric left/right; 0 = in front).
        sol_radiation_dir_wm2: direct-beam irradiance normal to the beam I_dir [W/m2], >= 0.
        sol_transmittance: total solar transmittance T_sol of the glazing
            (and shades) between sun and occupant [-], 0..1.
        f_svv: fraction of the sky vault in the occupant's view [-], 0..1.
        f_bes: fraction of the possible body surface exposed to the direct sun [-], 0..1.
        asw: short-wave absorptivity of skin and clothing alpha_sw [-], 0..1.
        floor_reflectance: short-wave reflectance of the floor (the sunlit
            surfaces below the occupant) R_floor [-], 0..1.
        posture: ``"sitting"`` or ``"standing"``.

    Returns:
        :class:`SolarGain` (numpy arrays, or CasADi expressions if any input is symbolic).

    Raises:
        ValueError: (numpy inputs) non-finite or out-of-range values, unknown posture.
    """
    if posture not in F_EFF:
        raise ValueError(f"posture must be one of {sorted(F_EFF)}, got {posture!r}")
    args = dict(
        sol_altitude_deg=sol_altitude_deg,
        sharp_deg=sharp_deg,
        sol_radiation_dir_wm2=sol_radiation_dir_wm2,
        sol_transmittance=sol_transmittance,
        f_svv=f_svv,
        f_bes=f_bes,
        asw=asw,
        floor_reflectance=floor_reflectance,
    )
    ops = mathops.backend(*args.values())
    if ops.is_casadi:
        args = {k: (casadi.DM(v) if isinstance(v, np.ndarray) else v) for k, v in args.items()}
    else:
        limits = dict(
            sol_altitude_deg=(0.0, 90.0),
            sharp_deg=(0.0, 180.0),
            sol_radiation_dir_wm2=(0.0, np.inf),
            sol_transmittance=(0.0, 1.0),
            f_svv=(0.0, 1.0),
            f_bes=(0.0, 1.0),
            asw=(0.0, 1.0),
            floor_reflectance=(0.0, 1.0),
        )
        args = {k: _check(k, v, *limits[k]) for k, v in args.items()}
        try:
            np.broadcast_shapes(*(a.shape for a in args.values()))
        except ValueError as exc:
            raise ValueError(
                "input shapes do not broadcast: " + ", ".join(f"{k}{a.shape}" for k, a in args.items())
            ) from exc
    a = args
    f_eff = F_EFF[posture]
    i_dir = a["sol_radiation_dir_wm2"]
    i_diff = DIFFUSE_FRACTION * i_dir
    tau = a["sol_transmittance"]
    fp = projected_area_factor(a["sol_altitude_deg"], a["sharp_deg"], posture)
    sin_beta = ops.sin(a["sol_altitude_deg"] * (np.pi / 180.0))
    e_diff = f_eff * a["f_svv"] * 0.5 * tau * i_diff
    e_dir = f_eff * fp * tau * a["f_bes"] * i_dir
    e_refl = f_eff * a["f_svv"] * 0.5 * tau * (i_dir * sin_beta + i_diff) * a["floor_reflectance"]
    e_solar = e_diff + e_dir + e_refl
    erf = e_solar * (a["asw"] / ALPHA_LW)
    return SolarGain(
        e_solar_wm2=e_solar, erf_wm2=erf, delta_mrt_k=erf / (H_R_SOLARCAL_WM2K * f_eff), w_rad_wm2=a["asw"] * e_solar
    )


def relative_azimuth_deg(sun_azimuth_deg, heading_deg):
    """SHARP of a forward-facing occupant [deg], 0..180, from compass angles (numpy).

    ``sun_azimuth_deg`` and ``heading_deg`` are compass bearings (0 = north,
    90 = east) of the sun and of the car's direction of travel; the driver
    faces the heading. The result folds the difference into 0..180 (SolarCal's
    f_p is symmetric left/right): 0 = sun straight ahead, 180 = behind.
    """
    az = np.asarray(sun_azimuth_deg, dtype=float)
    hd = np.asarray(heading_deg, dtype=float)
    if not (np.all(np.isfinite(az)) and np.all(np.isfinite(hd))):
        raise ValueError("sun_azimuth_deg and heading_deg must be finite")
    d = np.mod(az - hd, 360.0)
    return 180.0 - np.abs(180.0 - d)
