"""Psychrometrics (ceco_core.psychro): ASHRAE table values, IAPWS, inverse pairs, CasADi equals numpy."""

import casadi
import CoolProp.CoolProp as CP
import numpy as np
import pytest

from ceco_core import psychro


def test_saturation_pressure_against_ashrae_table_and_iapws():
    # ASHRAE Fundamentals 2017 ch. 1 table 3 (from IAPWS-95): p_ws at 0.01, 25, 35, 60 degC [kPa]
    table = {0.01: 0.61165, 25.0: 3.1699, 35.0: 5.6291, 60.0: 19.946}
    for t_c, p_kpa in table.items():
        assert psychro.saturation_vapour_pressure_pa(t_c) == pytest.approx(1000.0 * p_kpa, rel=3e-4)
    t = np.linspace(0.5, 95.0, 60)
    iapws = np.array([CP.PropsSI("P", "T", x + 273.15, "Q", 0.0, "Water") for x in t])
    assert np.abs(psychro.saturation_vapour_pressure_pa(t) / iapws - 1.0).max() < 1e-4


def test_humidity_ratio_relative_humidity_and_dew_point_are_inverse():
    t = np.linspace(5.0, 55.0, 11)
    rh = np.linspace(0.05, 1.0, 11)
    w = psychro.humidity_ratio(t, rh)
    assert psychro.relative_humidity(t, w) == pytest.approx(rh, rel=1e-12)
    # ASHRAE Fundamentals 2017 ch. 1 table 2: W_s at 35 degC, 101.325 kPa = 0.036605 kg/kg; the table
    # includes the enhancement factor f ~ 1.004 (real-gas mixing), which the ideal-gas eq. (22) omits
    assert psychro.humidity_ratio(35.0, 1.0) == pytest.approx(0.036605, rel=1.5e-3)
    assert psychro.humidity_ratio(35.0, 1.0) < 0.036605
    t_d = np.linspace(-20.0, 60.0, 81)
    p_w = psychro.saturation_vapour_pressure_pa(t_d)
    assert np.abs(psychro.dew_point_c(p_w) - t_d).max() < 1e-9
    # a cabin at 25 degC and 40 % RH has its dew point near 10.5 degC (ASHRAE chart)
    assert psychro.dew_point_c(psychro.vapour_pressure_pa(25.0, 0.4)) == pytest.approx(10.5, abs=0.1)


def test_casadi_equals_numpy_and_bad_input_is_named():
    x = casadi.SX.sym("x")
    f = casadi.Function("f", [x], [psychro.saturation_vapour_pressure_pa(x), psychro.dew_point_c(x)])
    ps, td = f(25.0)
    assert float(ps) == pytest.approx(float(psychro.saturation_vapour_pressure_pa(25.0)), rel=1e-14)
    assert float(td) == pytest.approx(float(psychro.dew_point_c(25.0)), rel=1e-12)
    with pytest.raises(ValueError, match="t_c"):
        psychro.saturation_vapour_pressure_pa(np.nan)
    with pytest.raises(ValueError, match="rh"):
        psychro.vapour_pressure_pa(25.0, 1.2)
    with pytest.raises(ValueError, match="p_w_pa"):
        psychro.dew_point_c(0.0)


def test_the_scalar_path_equals_the_array_path_to_the_bit_and_refuses_the_same_input():
    # vapour_pressure_pa on two numbers (the controller's step) skips the array checks: same value, same refusals
    for t_c in (0.0, 12.5, 25.3, 40.1, np.float64(33.3)):
        for rh in (0.0, 0.31, 0.77, 1.0, np.float64(0.5)):
            scalar = psychro.vapour_pressure_pa(t_c, rh)
            assert type(scalar) is np.float64
            assert scalar == float(psychro.vapour_pressure_pa(np.array([t_c]), np.array([rh]))[0])
    assert psychro.vapour_pressure_pa(25.0, 0.5) == pytest.approx(0.5 * 3169.9, rel=3e-4)
    for t_c, rh, name in ((25.0, 1.0 + 1e-12, "rh"), (25.0, -1e-12, "rh"), (25.0, np.nan, "rh"), (25.0, np.inf, "rh")):
        with pytest.raises(ValueError, match=name):
            psychro.vapour_pressure_pa(t_c, rh)
        with pytest.raises(ValueError, match=name):
            psychro.vapour_pressure_pa(np.array([t_c]), np.array([rh]))
    for t_c in (np.nan, -np.inf):
        with pytest.raises(ValueError, match="t_c"):
            psychro.vapour_pressure_pa(t_c, 0.5)
