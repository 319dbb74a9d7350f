"""ceco_ros.params without ROS: the declaration check every node's parameters go through."""

import math

from ceco_ros.params import CONTROL_PERIOD_RANGE_S, HORIZON_RANGE, ParamSpec, check_value, markdown_table

TS = ParamSpec('control_period_s', 5.0, 'control period Ts [s]', float_range=CONTROL_PERIOD_RANGE_S)
NP = ParamSpec('horizon_steps', 6, 'Np [steps]', int_range=HORIZON_RANGE)
MODE = ParamSpec('timing', 'lockstep', 'timing', choices=('lockstep', 'realtime'))


def test_in_range_values_pass_and_an_integer_is_taken_for_a_float():
    assert check_value(TS, 5) == (5.0, None) and isinstance(check_value(TS, 5)[0], float)
    assert check_value(TS, 0.1) == (0.1, None) and check_value(TS, 300.0) == (300.0, None)
    assert check_value(NP, 60) == (60, None) and check_value(MODE, 'realtime') == ('realtime', None)


def test_out_of_range_non_finite_and_unknown_values_are_refused_naming_the_parameter():
    assert check_value(TS, 300.5)[1] == 'invalid parameter control_period_s=300.5: must lie in [0.1, 300.0]'
    assert check_value(TS, 0.0)[1] == 'invalid parameter control_period_s=0.0: must lie in [0.1, 300.0]'
    for bad in (math.nan, math.inf, -math.inf):
        assert check_value(TS, bad)[1] == f'invalid parameter control_period_s={bad!r}: must be a finite number'
    assert check_value(NP, 61)[1] == 'invalid parameter horizon_steps=61: must lie in [1, 60]'
    assert check_value(MODE, 'fast')[1] == 'invalid parameter timing=\'fast\': must be one of lockstep, realtime'


def test_docs_table_rows_carry_range_and_when_settable():
    rows = markdown_table((TS, NP, MODE)).splitlines()
    assert rows[2] == '| `control_period_s` | `5.0` | 0.1 .. 300.0 | no | control period Ts [s] |'
    assert rows[3] == '| `horizon_steps` | `6` | 1 .. 60 | no | Np [steps] |'
    assert rows[4] == "| `timing` | `'lockstep'` | lockstep, realtime | no | timing |"
