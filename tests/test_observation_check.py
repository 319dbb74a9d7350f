"""Plausibility of every Observation field (ceco_core.observation_check)."""

import math

import numpy as np
import pytest
from observations import observation

from ceco_core.observation_check import ObservationLimits, check_observation

N1 = 4


def _obs(**kw):
    return observation(N1, **{'k': 3, 't_s': 15.0, **kw})


def test_a_plausible_observation_has_no_problem():
    c = check_observation(_obs())
    assert c.measurements_ok and c.command_ok and not c.info_problems and c.preview_plausible.all()
    assert c.summary() == ""


@pytest.mark.parametrize(
    "field, value",
    [
        ("t_cab_c", math.nan),
        ("t_int_c", 1e6),
        ("t_shell_c", -math.inf),
        ("t_evap_c", 9e18),
        ("t_vent_c", -60.0),
        ("t_amb_c", 70.0),
        ("solar_wm2", 1e4),
        ("speed_mps", -30.0),
    ],
)
def test_each_implausible_measurement_is_named(field, value):
    c = check_observation(_obs(**{field: value}))
    assert not c.measurements_ok and c.command_ok and len(c.measurement_problems) == 1
    assert c.measurement_problems[0].startswith(f"{field}=")


def test_previous_command_comfort_zone_info_and_previews():
    c = check_observation(_obs(mdot_bl_prev_kgps=math.nan, t_evap_sp_prev_c=10.5))
    assert c.measurements_ok and not c.command_ok and len(c.command_problems) == 2
    assert check_observation(_obs(mdot_bl_prev_kgps=0.17 + 5e-7)).command_ok  # within the bound tolerance
    c = check_observation(_obs(pmv_lb=np.array([-0.5, 0.6, -0.5, -0.5])))
    assert c.measurement_problems == ["pmv_lb above pmv_ub"]
    assert not check_observation(_obs(pmv_ub=np.full(N1, math.inf))).measurements_ok
    c = check_observation(_obs(k=-1, t_s=math.nan, met=9.0, clo=-1.0))
    assert c.measurements_ok and c.command_ok and len(c.info_problems) == 4
    c = check_observation(
        _obs(
            preview_t_amb_c=np.array([35.0, 1e9, math.nan, 35.0]), preview_speed_mps=np.array([10.0, 10.0, 10.0, -40.0])
        )
    )
    assert list(c.preview_plausible) == [True, False, False, False]


def test_limits_are_validated():
    with pytest.raises(ValueError, match="ObservationLimits.ambient_c"):
        ObservationLimits(ambient_c=(10.0, 5.0)).validate()
    with pytest.raises(ValueError, match="command_tol"):
        ObservationLimits(command_tol=-1.0).validate()


def test_optional_measurements_are_used_only_when_plausible():
    c = check_observation(_obs(t_glass_c=36.0, rh_cab=0.4))
    assert (c.t_glass_c, c.rh_cab) == (36.0, 0.4) and not c.info_problems
    c = check_observation(_obs())  # not measured: NaN, no problem
    assert math.isnan(c.t_glass_c) and math.isnan(c.rh_cab) and not c.info_problems
    c = check_observation(_obs(t_glass_c=1e6, rh_cab=40.0))  # e.g. RH in percent: treated as not measured
    assert math.isnan(c.t_glass_c) and math.isnan(c.rh_cab) and len(c.info_problems) == 2 and c.measurements_ok
    # the ambient RH (the doors' enthalpy economiser) likewise
    c = check_observation(_obs(rh_amb=0.65))
    assert c.rh_amb == 0.65 and not c.info_problems
    c = check_observation(_obs(rh_amb=65.0))
    assert math.isnan(c.rh_amb) and c.measurements_ok
    assert c.info_problems == ["rh_amb=65.0 outside (0.0, 1.0): treated as not measured"]
