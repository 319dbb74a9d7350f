"""ceco_msgs interface conventions (REP 103 units, headers, preview grids),
checked on the .msg text; the definitions also parse with rosbags' msg parser."""

import re
from pathlib import Path

import pytest

MSG_DIR = Path(__file__).resolve().parents[1] / 'msg'
MSGS = sorted(p.stem for p in MSG_DIR.glob('*.msg'))
FIELD = re.compile(r'^(?P<type>[\w/]+(\[\d*\])?)\s+(?P<name>\w+)\s*(?P<rest>.*)$')
UNIT = re.compile(r'#.*\[[^\]]+\]')


def _fields(name):
    for line in (MSG_DIR / f'{name}.msg').read_text().splitlines():
        if line.strip() and not line.lstrip().startswith('#'):
            m = FIELD.match(line.strip())
            assert m, f'{name}: unparsable line {line!r}'
            yield m['type'], m['name'], m['rest']


def test_the_seven_interfaces_exist():
    assert MSGS == [
        'AcCommand',
        'AcPower',
        'CabinState',
        'Comfort',
        'ControllerDiagnostics',
        'TrafficPreview',
        'WeatherPreview',
    ]


@pytest.mark.parametrize('name', MSGS)
def test_every_data_field_has_a_unit_comment(name):
    for ftype, fname, rest in _fields(name):
        if ftype == 'std_msgs/Header':
            continue
        assert UNIT.search(rest), f'{name}.{fname}: no "# ... [unit]" comment'


@pytest.mark.parametrize('name', MSGS)
def test_stamped_with_a_header_first(name):
    first = next(_fields(name))
    assert first[:2] == ('std_msgs/Header', 'header')


@pytest.mark.parametrize('name', MSGS)
def test_names_carry_si_unit_suffixes(name):
    for _ftype, fname, rest in _fields(name):
        unit = re.search(r'\[([^\]]+)\]', rest)
        if unit and unit.group(1) == 'degC':
            assert fname.endswith('_c'), f'{name}.{fname}: degC field without _c suffix'
        assert not fname.endswith('_kmh'), f'{name}.{fname}: km/h on the wire'


@pytest.mark.parametrize('name', ['WeatherPreview', 'TrafficPreview'])
def test_previews_carry_their_own_time_grid(name):
    fields = {fname: ftype for ftype, fname, _ in _fields(name)}
    assert fields['start'] == 'builtin_interfaces/Time' and fields['step_s'] == 'float64'
    assert fields['valid'] == 'bool[]'
    arrays = [f for f, t in fields.items() if t == 'float64[]']
    assert arrays and all(a.endswith(('_c', '_wm2', '_mps')) or a == 'rh' for a in arrays)


def test_definitions_parse_and_register_in_a_rosbags_typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name in MSGS:
        types.update(get_types_from_msg((MSG_DIR / f'{name}.msg').read_text(), f'ceco_msgs/msg/{name}'))
    store.register(types)
    cmd = store.types['ceco_msgs/msg/AcCommand']
    names = [f[0] for f in cmd.__dataclass_fields__.items()]
    assert names[:3] == ['header', 'step_index', 'control_period_s']
    assert 'blower_flow_kgps' in names and 'evap_setpoint_c' in names and 'fallback' in names
