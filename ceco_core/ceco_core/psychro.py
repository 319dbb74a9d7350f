"""Psychrometrics of moist air: the one place where the water saturation pressure lives.

Every function evaluates numpy arrays (broadcasting) and CasADi symbols
(``SX``/``MX``, via :func:`ceco_core.mathops.backend`), so the plant, the
comfort model, the scenario loader and an NMPC share the same equations.

References:
    IAPWS SR1-86(1992), Revised supplementary release on saturation properties of
    ordinary water substance; W. Wagner, A. Pruss, J. Phys. Chem. Ref. Data 22
    (1993) 783, eq. (2.5): the saturation pressure of water.
    ASHRAE Handbook - Fundamentals 2017, ch. 1 "Psychrometrics": eqs. (20), (22)
    humidity ratio, eq. (24) relative humidity.
"""

from __future__ import annotations

import math

import numpy as np

from ceco_core import mathops
from ceco_core.units import ZERO_C_K

__all__ = [
    "EPS_W",
    "P_ATM_PA",
    "H_FG_JPKG",
    "saturation_vapour_pressure_pa",
    "vapour_pressure_pa",
    "humidity_ratio",
    "humidity_ratio_from_vapour_pressure",
    "vapour_pressure_from_humidity_ratio_pa",
    "relative_humidity",
    "dew_point_c",
    "moist_air_enthalpy_jpkg",
]

EPS_W = 0.621945
"""Ratio of the molar masses of water and dry air M_w / M_da [-] (ASHRAE Fundamentals 2017 ch. 1, eq. (22))."""

H_FG_JPKG = 2.45e6
"""Latent heat of vaporisation of water near 20 degC [J/kg] (ASHRAE Fundamentals 2017 ch. 1 table 3: 2453.5 kJ/kg at
20 degC); the plant's ``PlantParams.h_fg_jpkg`` default and the NMPC's moisture generation use this value."""

P_ATM_PA = 101325.0
"""Standard atmospheric pressure [Pa] (sea level)."""

CP_DRY_AIR_JPKGK = 1006.0
"""Specific heat of dry air [J/(kg K)] (ASHRAE Fundamentals 2017 ch. 1, eq. (32): 1.006 kJ/(kg K))."""
CP_VAPOUR_JPKGK = 1860.0
"""Specific heat of water vapour [J/(kg K)] (ASHRAE Fundamentals 2017 ch. 1, eq. (32): 1.86 kJ/(kg K))."""
H_G0_JPKG = 2.501e6
"""Enthalpy of saturated water vapour at 0 degC [J/kg] (ASHRAE Fundamentals 2017 ch. 1, eq. (32): 2501 kJ/kg)."""

# IAPWS SR1-86(1992) / Wagner & Pruss (1993), J. Phys. Chem. Ref. Data 22, 783, eq. (2.5):
# ln(p_s / p_c) = (T_c / T) (a1 tau + a2 tau^1.5 + a3 tau^3 + a4 tau^3.5 + a5 tau^4 + a6 tau^7.5),
# tau = 1 - T / T_c; 273.16 K .. T_c; consistent with IAPWS-95 to its accuracy.
_T_C_K = 647.096
"""Critical temperature of water [K] (IAPWS)."""
_P_C_PA = 22.064e6
"""Critical pressure of water [Pa] (IAPWS)."""
_WP = (
    (-7.85951783, 1.0),
    (1.84408259, 1.5),
    (-11.7866497, 3.0),
    (22.6807411, 3.5),
    (-15.9618719, 4.0),
    (1.80122502, 7.5),
)
"""(a_i, exponent of tau) of the Wagner-Pruss saturation-pressure equation."""


def _ln_pws(ops, t_k, slope=True):
    """Ln p_s [ln Pa] at T [K] and its derivative d ln p_s / dT [1/K] (Wagner-Pruss; None if not ``slope``)."""
    tau = 1.0 - t_k / _T_C_K
    f = 0.0
    df = 0.0
    for a, n in _WP:
        f = f + a * ops.power(tau, n)
        if slope:
            df = df + a * n * ops.power(tau, n - 1.0)
    ln_p = np.log(_P_C_PA) + _T_C_K / t_k * f
    if not slope:
        return ln_p, None
    return ln_p, -_T_C_K / (t_k * t_k) * f - df / t_k


_SCALARS = (float, np.float64)
_NP = mathops.backend(0.0)


def _check(ops, name, value):
    if ops.is_casadi:
        return value
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {value!r}")
    return arr


def saturation_vapour_pressure_pa(t_c):
    """Saturation pressure of water vapour over liquid water p_ws [Pa].

    ``ln(p_ws / p_c) = (T_c / T) sum_i a_i tau^n_i``, ``tau = 1 - T / T_c``,
    ``T = t_c + 273.15`` [K], T_c = 647.096 K, p_c = 22.064 MPa (IAPWS SR1-86(1992);
    Wagner & Pruss 1993, eq. (2.5)).

    Where:
        t_c: air (or surface) temperature [degC]; valid from the triple point
            (0.01 degC) to 374 degC; below 0 degC it is used as the pressure over
            supercooled water (the WMO convention for relative humidity).
    Returns p_ws [Pa]; within 1e-4 of IAPWS-95 (CoolProp) over 0.5..95 degC (ceco_core/test/test_psychro.py).
    """
    if type(t_c) in _SCALARS:  # one number (the plant's hot path): the same numpy operations, no array checks
        if not math.isfinite(t_c):
            raise ValueError(f"t_c must be finite (no NaN/inf), got {t_c!r}")
        return _NP.exp(_ln_pws(_NP, np.float64(t_c) + ZERO_C_K, slope=False)[0])
    ops = mathops.backend(t_c)
    return ops.exp(_ln_pws(ops, _check(ops, "t_c", t_c) + ZERO_C_K, slope=False)[0])


def vapour_pressure_pa(t_c, rh):
    """Partial pressure of water vapour p_w = rh * p_ws(t) [Pa] (ASHRAE Fundamentals 2017 ch. 1, eq. (24)).

    Where ``t_c`` is the air temperature [degC] and ``rh`` the relative humidity,
    a 0..1 fraction (ValueError outside it on the numpy path).
    """
    if type(t_c) in _SCALARS and type(rh) in _SCALARS:  # two numbers (the controller's step): no array checks
        if not math.isfinite(rh):
            raise ValueError(f"rh must be finite (no NaN/inf), got {rh!r}")
        if not 0.0 <= rh <= 1.0:
            raise ValueError(f"rh must be a fraction in [0, 1], got {rh!r}")
        return rh * saturation_vapour_pressure_pa(t_c)
    ops = mathops.backend(t_c, rh)
    rh = _check(ops, "rh", rh)
    if not ops.is_casadi and np.any((rh < 0.0) | (rh > 1.0)):
        raise ValueError(f"rh must be a fraction in [0, 1], got {rh!r}")
    return rh * saturation_vapour_pressure_pa(t_c)


def humidity_ratio(t_c, rh, p_atm_pa=P_ATM_PA):
    """Humidity ratio W [kg water / kg dry air] of moist air at ``t_c`` [degC] and ``rh`` [0..1].

    ``W = 0.621945 p_w / (p - p_w)``, ``p_w = rh p_ws(t)`` (ASHRAE Fundamentals 2017
    ch. 1, eqs. (20), (22)); ``p_atm_pa`` is the total pressure p [Pa].
    """
    return humidity_ratio_from_vapour_pressure(vapour_pressure_pa(t_c, rh), p_atm_pa)


def humidity_ratio_from_vapour_pressure(p_w_pa, p_atm_pa=P_ATM_PA):
    """Humidity ratio W = 0.621945 p_w / (p - p_w) [kg/kg] of air with vapour pressure ``p_w_pa`` [Pa] (eq. (22)).

    Plain arithmetic: also on CasADi symbols (the plant's equations).
    """
    return EPS_W * p_w_pa / (p_atm_pa - p_w_pa)


def vapour_pressure_from_humidity_ratio_pa(w_kgkg, p_atm_pa=P_ATM_PA):
    """Partial pressure of water vapour p_w = p W / (0.621945 + W) [Pa] (inverse of eq. (22))."""
    return p_atm_pa * w_kgkg / (EPS_W + w_kgkg)


def relative_humidity(t_c, w_kgkg, p_atm_pa=P_ATM_PA):
    """Relative humidity [0..1 fraction] of moist air at ``t_c`` [degC] with humidity ratio ``w_kgkg`` [kg/kg].

    ``rh = p_w / p_ws(t)`` with ``p_w`` from :func:`vapour_pressure_from_humidity_ratio_pa`
    (ASHRAE Fundamentals 2017 ch. 1, eq. (24)). Not clipped: > 1 means supersaturated.
    """
    return vapour_pressure_from_humidity_ratio_pa(w_kgkg, p_atm_pa) / saturation_vapour_pressure_pa(t_c)


def dew_point_c(p_w_pa, newton_steps=4):
    """Dew-point temperature t_d [degC] of air whose water vapour partial pressure is ``p_w_pa`` [Pa].

    Solves ``p_ws(t_d) = p_w`` (the saturation curve of
    :func:`saturation_vapour_pressure_pa`, so dew point and relative humidity are
    consistent) by ``newton_steps`` Newton steps on ``ln p_ws(t) - ln p_w`` from the
    Magnus estimate ``t0 = 243.04 x / (17.625 - x)``, ``x = ln(p_w / 610.94)``
    (Alduchov & Eskridge 1996). Four steps give |error| < 1e-9 K over -20..60 degC
    (ceco_core/test/test_psychro.py). A fixed step count keeps the function smooth for CasADi.
    ``p_w_pa`` must be > 0.
    """
    ops = mathops.backend(p_w_pa)
    p_w = _check(ops, "p_w_pa", p_w_pa)
    if not ops.is_casadi and np.any(p_w <= 0.0):
        raise ValueError(f"p_w_pa must be > 0, got {p_w_pa!r}")
    ln_pw = ops.log(p_w)
    x = ln_pw - np.log(610.94)
    t_c = 243.04 * x / (17.625 - x)
    for _ in range(newton_steps):
        ln_p, slope = _ln_pws(ops, t_c + ZERO_C_K)
        t_c = t_c - (ln_p - ln_pw) / slope
    return t_c


def moist_air_enthalpy_jpkg(t_c, w_kgkg):
    """Specific enthalpy of moist air [J per kg of dry air], 0 for dry air at 0 degC.

    ``h = 1006 t + W (2.501e6 + 1860 t)`` with ``t_c`` [degC] and the humidity ratio ``w_kgkg`` [kg/kg]
    (ASHRAE Fundamentals 2017 ch. 1, eq. (32)). The evaporator's load of a stream is its mass flow times the
    enthalpy it loses there, so of two inlet airs the one of lower enthalpy is the cheaper to cool once the coil
    is wet.
    """
    return CP_DRY_AIR_JPKGK * t_c + w_kgkg * (H_G0_JPKG + CP_VAPOUR_JPKGK * t_c)
