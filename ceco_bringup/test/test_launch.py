"""ceco_bringup's launch files (ceco.launch.py and the XML front-end ceco.launch.xml) without the
launch packages (they are not on PyPI; both were run with the real Jazzy `ros2 launch`, docs/ros.md).

The Python file is executed against small stand-ins for `launch` / `launch_ros` that evaluate its
substitutions and conditions as launch does; the XML file is read with ElementTree and its `$(...)`
substitutions evaluated the same way. For every combination of arguments tried, both give the same
processes (node, namespace, parameter files, parameters, enclave; the recorder's command line),
and those equal what `ceco run` starts, parameter by parameter."""

from __future__ import annotations

import ast
import importlib.util
import itertools
import os
import re
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_DIR = ROOT / 'ceco_bringup' / 'launch'
LAUNCH_FILE, XML_FILE = LAUNCH_DIR / 'ceco.launch.py', LAUNCH_DIR / 'ceco.launch.xml'
ARGUMENTS = {
    'namespace': '',
    'strategy': 'ceco-ioch',
    'timing': 'lockstep',
    'use_sim_time': 'auto',
    'scenario': 'sc03',
    'record': 'false',
    'autostart': 'true',
    'security': 'false',
    'keystore': '',
}
RUN_NODE = {'preview_node': 'preview', 'mpc_node': 'controller', 'baseline_node': 'controller', 'plant_node': 'plant'}
SHARE = '/opt/share'
LAUNCH_ENVIRON: dict[str, str] = {}
"""The environment of the launch process, as `$(env ...)` / EnvironmentVariable see it (a test sets it)."""
SECURITY_VARS = ('ROS_SECURITY_ENABLE', 'ROS_SECURITY_STRATEGY', 'ROS_SECURITY_KEYSTORE')


def _constants() -> dict:
    """Module-level NAME = <literal> assignments of the Python launch file."""
    out = {}
    for stmt in ast.parse(LAUNCH_FILE.read_text()).body:
        if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1 and isinstance(stmt.targets[0], ast.Name):
            try:
                out[stmt.targets[0].id] = ast.literal_eval(stmt.value)
            except ValueError:
                pass
    return out


def _install_prefix() -> Path:
    return Path(os.environ.get('COLCON_PREFIX_PATH', str(ROOT / 'ros_ws' / 'install')).split(':')[0])


def _truth(text: str) -> bool:
    """launch's boolean rule for conditions and `and` / `not` / `if`."""
    assert text.lower() in ('true', 'false', '1', '0'), f'not a boolean: {text!r}'
    return text.lower() in ('true', '1')


def _bool(value: bool) -> str:
    return 'true' if value else 'false'


# ----------------------------------------------------------------------------
# The Python file executed against stand-ins that evaluate what it builds.
def perform(sub, ctx) -> str:
    if isinstance(sub, str):
        return sub
    if isinstance(sub, list | tuple):
        return ''.join(perform(s, ctx) for s in sub)
    return sub.perform(ctx)


class _Sub:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _stub_modules() -> dict:
    def sub(name, fn):
        return type(name, (_Sub,), {'perform': lambda self, ctx: fn(ctx, *self.args, **self.kwargs)})

    def action(name):
        return type(name, (_Sub,), {})

    mods = {
        name: types.ModuleType(name)
        for name in (
            'launch',
            'launch.actions',
            'launch.conditions',
            'launch.substitutions',
            'launch_ros',
            'launch_ros.actions',
            'launch_ros.event_handlers',
            'launch_ros.parameter_descriptions',
            'launch_ros.substitutions',
        )
    }
    mods['launch'].LaunchDescription = lambda entities: list(entities)
    for name in (
        'DeclareLaunchArgument',
        'ExecuteProcess',
        'LogInfo',
        'RegisterEventHandler',
        'SetEnvironmentVariable',
        'SetLaunchConfiguration',
        'Shutdown',
    ):
        setattr(mods['launch.actions'], name, action(name))
    mods['launch.conditions'].IfCondition = sub('IfCondition', lambda c, x: _truth(perform(x, c)))
    mods['launch.conditions'].UnlessCondition = sub('UnlessCondition', lambda c, x: not _truth(perform(x, c)))
    s = mods['launch.substitutions']
    s.LaunchConfiguration = sub('LaunchConfiguration', lambda c, name: c[name])
    s.EnvironmentVariable = sub(
        'EnvironmentVariable', lambda c, name, default_value=None: LAUNCH_ENVIRON.get(name, default_value)
    )
    s.EqualsSubstitution = sub('EqualsSubstitution', lambda c, a, b: _bool(perform(a, c) == perform(b, c)))
    s.IfElseSubstitution = sub(
        'IfElseSubstitution', lambda c, x, a, b: perform(a, c) if _truth(perform(x, c)) else perform(b, c)
    )
    s.AndSubstitution = sub('AndSubstitution', lambda c, a, b: _bool(_truth(perform(a, c)) and _truth(perform(b, c))))
    s.NotSubstitution = sub('NotSubstitution', lambda c, a: _bool(not _truth(perform(a, c))))
    s.PythonExpression = sub('PythonExpression', lambda c, parts: str(eval(perform(parts, c))))
    s.PathJoinSubstitution = sub('PathJoinSubstitution', lambda c, parts: os.path.join(*(perform(p, c) for p in parts)))
    mods['launch_ros.substitutions'].FindPackageShare = sub('FindPackageShare', lambda c, pkg: f'{SHARE}/{pkg}')
    pd = mods['launch_ros.parameter_descriptions']
    pd.ParameterFile = sub('ParameterFile', lambda c, path: perform(path, c))
    pd.ParameterValue = sub(
        'ParameterValue', lambda c, v, value_type=str: _truth(perform(v, c)) if value_type is bool else perform(v, c)
    )
    mods['launch_ros.actions'].Node = action('Node')
    mods['launch_ros.actions'].LifecycleNode = action('LifecycleNode')
    mods['launch_ros.event_handlers'].OnStateTransition = action('OnStateTransition')
    return mods


def _enabled(entity, ctx) -> bool:
    cond = entity.kwargs.get('condition')
    return cond is None or cond.perform(ctx)


def _python_description(monkeypatch):
    for name, mod in _stub_modules().items():
        monkeypatch.setitem(sys.modules, name, mod)
    spec = importlib.util.spec_from_file_location('ceco_launch_under_test', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def _run_python(description, **arguments) -> dict:
    """What the launch starts for ``arguments``: {'env': ..., 'nodes': {name: ...}, 'recorder': cmd, 'kinds': ...}."""
    ctx, out = {}, {'env': {}, 'nodes': {}, 'recorder': None, 'recorder_env': None, 'kinds': {}}
    for e in description:
        kind = type(e).__name__
        if kind == 'DeclareLaunchArgument':
            name = e.args[0]
            ctx[name] = arguments.pop(name, e.kwargs['default_value'])
            choices = e.kwargs.get('choices')
            assert choices is None or ctx[name] in choices, (name, ctx[name])
        elif not _enabled(e, ctx):
            continue
        elif kind == 'SetLaunchConfiguration':
            ctx[e.args[0]] = perform(e.args[1], ctx)
        elif kind == 'SetEnvironmentVariable':
            out['env'][e.args[0]] = perform(e.args[1], ctx)
        elif kind in ('Node', 'LifecycleNode'):
            kw = e.kwargs
            assert kw['executable'] == kw['name'] and kw['output'] == 'screen'
            *files, params = kw['parameters']
            out['nodes'][kw['name']] = {
                'package': kw['package'],
                'namespace': perform(kw['namespace'], ctx),
                'files': [perform(f, ctx) for f in files],
                'params': {
                    k: v.perform(ctx)
                    if isinstance(v, _Sub) and type(v).__name__ == 'ParameterValue'
                    else perform(v, ctx)
                    for k, v in params.items()
                },
                'ros_args': [perform(a, ctx) for a in kw['ros_arguments']],
                'env': {perform(k, ctx): perform(v, ctx) for k, v in kw.get('additional_env', {}).items()},
            }
            out['kinds'][kw['name']] = kind
        elif kind == 'ExecuteProcess':
            assert out['recorder'] is None, 'two recorders enabled at once'
            assert [type(a).__name__ for a in e.kwargs['on_exit']] == ['Shutdown'] and e.kwargs['name'] == 'recorder'
            out['recorder'] = [perform(c, ctx) for c in e.kwargs['cmd']]
            out['recorder_env'] = {perform(k, ctx): perform(v, ctx) for k, v in e.kwargs['additional_env'].items()}
    assert not arguments, f'unknown arguments {arguments}'
    return out


@pytest.fixture()
def launch(monkeypatch):
    """run(**arguments) -> what ceco.launch.py starts for them."""
    description = _python_description(monkeypatch)
    return lambda **arguments: _run_python(description, **arguments)


# ----------------------------------------------------------------------------
# The XML front-end: ElementTree plus the `$(...)` substitutions it uses.
def _xml_sub(text: str, ctx) -> str:
    """Evaluate launch's `$(name args)` substitutions in ``text`` (innermost first)."""
    inner = re.compile(r'\$\((\w[\w-]*)((?:\s+(?:"[^"]*"|[^\s()$"]+))*)\s*\)')
    while (m := inner.match(text, text.rfind('$('))) is not None:  # the last `$(` is an innermost one
        name, args = m[1], [_unquote(a) for a in re.findall(r'"[^"]*"|[^\s"]+', m[2])]
        if name == 'var':
            value = ctx[args[0]]
        elif name == 'equals':
            value = _bool(args[0] == args[1])
        elif name == 'if':
            value = args[1] if _truth(args[0]) else args[2]
        elif name == 'and':
            value = _bool(all(_truth(a) for a in args))
        elif name == 'not':
            value = _bool(not _truth(args[0]))
        elif name == 'eval':
            value = str(eval(args[0]))
        elif name == 'env':
            value = LAUNCH_ENVIRON.get(args[0], args[1] if len(args) > 1 else None)
            assert value is not None, f'$(env {args[0]}) without a default and not set'
        elif name == 'find-pkg-share':
            value = f'{SHARE}/{args[0]}'
        else:
            raise AssertionError(f'substitution $({name}) not evaluated by this test')
        outer = re.match(r'\$\((\w[\w-]*)', text[text.rfind('$(', 0, m.start()) :])
        if not value and outer and outer[1] != 'eval':  # an empty argument of the enclosing substitution
            value = "''"
        text = text[: m.start()] + value + text[m.end() :]
    return text


def _unquote(arg: str) -> str:
    return arg[1:-1] if len(arg) >= 2 and arg[0] == arg[-1] and arg[0] in '\'"' else arg


def _run_xml(**arguments) -> dict:
    ctx, out = {}, {'env': {}, 'nodes': {}, 'recorder': None, 'recorder_env': None, 'kinds': {}}
    for e in ET.parse(XML_FILE).getroot():
        if e.tag == 'arg':
            choices = [c.get('value') for c in e.findall('choice')]
            ctx[e.get('name')] = arguments.pop(e.get('name'), e.get('default'))
            assert not choices or ctx[e.get('name')] in choices
            continue
        if e.get('if') is not None and not _truth(_xml_sub(e.get('if'), ctx)):
            continue
        if e.get('unless') is not None and _truth(_xml_sub(e.get('unless'), ctx)):
            continue
        if e.tag == 'let':
            ctx[e.get('name')] = _xml_sub(e.get('value'), ctx)
        elif e.tag == 'set_env':
            out['env'][e.get('name')] = _xml_sub(e.get('value'), ctx)
        elif e.tag == 'node':
            assert e.get('exec') == e.get('name') and e.get('output') == 'screen'
            params = {}
            for p in e.findall('param'):
                if p.get('name') is not None:
                    value = _xml_sub(p.get('value'), ctx)  # launch types a param value as YAML does
                    params[p.get('name')] = yaml.safe_load(value) if value in ('true', 'false') else value
            out['nodes'][e.get('name')] = {
                'package': e.get('pkg'),
                'namespace': _xml_sub(e.get('namespace'), ctx),
                'files': [_xml_sub(p.get('from'), ctx) for p in e.findall('param') if p.get('from')],
                'params': params,
                'ros_args': _xml_sub(e.get('ros_args'), ctx).split(),
                'env': {v.get('name'): _xml_sub(v.get('value'), ctx) for v in e.findall('env')},
            }
            out['kinds'][e.get('name')] = 'Node'
        elif e.tag == 'executable':
            assert out['recorder'] is None and e.get('on_exit') == 'shutdown' and e.get('name') == 'recorder'
            out['recorder'] = _xml_sub(e.get('cmd'), ctx).split()
            out['recorder_env'] = {v.get('name'): _xml_sub(v.get('value'), ctx) for v in e.findall('env')}
        else:
            raise AssertionError(f'<{e.tag}> not evaluated by this test')
    assert not arguments, f'unknown arguments {arguments}'
    return out


# ----------------------------------------------------------------------------
def test_both_launch_files_declare_the_documented_arguments(monkeypatch):
    declared = {
        e.args[0]: (e.kwargs['default_value'], e.kwargs.get('choices'), e.kwargs['description'])
        for e in _python_description(monkeypatch)
        if type(e).__name__ == 'DeclareLaunchArgument'
    }
    assert list(declared) == list(ARGUMENTS) and {k: v[0] for k, v in declared.items()} == ARGUMENTS
    assert all(v[2] for v in declared.values())  # every argument described
    assert declared['record'][1] == ['true', 'false'] and declared['use_sim_time'][1] == ['auto', 'true', 'false']
    assert declared['namespace'][1] is None and declared['scenario'][1] is None and declared['keystore'][1] is None

    from ceco_core.contracts import NAMED_STRATEGIES
    from ceco_core.control_grid import TIMING_MODES

    assert tuple(declared['strategy'][1]) == NAMED_STRATEGIES and tuple(declared['timing'][1]) == TIMING_MODES
    xml = {
        a.get('name'): (a.get('default'), [c.get('value') for c in a.findall('choice')] or None, a.get('description'))
        for a in ET.parse(XML_FILE).getroot().findall('arg')
    }
    assert xml == declared  # the XML front-end: same names, defaults, choices, descriptions, order
    ros_md = (ROOT / 'docs' / 'ros.md').read_text()
    for name in ARGUMENTS:
        assert f'`{name}`' in ros_md, name


def test_launch_description_is_inspectable_and_starts_managed_nodes_as_lifecycle_nodes(launch):
    tree = ast.parse(LAUNCH_FILE.read_text())
    called = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    # no OpaqueFunction: every process is in the description (ros2 launch --print-description)
    assert 'OpaqueFunction' not in called and 'OpaqueFunction' not in LAUNCH_FILE.read_text()
    assert launch()['kinds'] == {'preview_node': 'Node', 'mpc_node': 'LifecycleNode', 'plant_node': 'Node'}
    assert launch(strategy='baseline')['kinds']['baseline_node'] == 'LifecycleNode'


def test_launch_file_topics_are_the_recorded_stack_topics():
    interfaces = pytest.importorskip('ceco_ros.interfaces', reason='needs rclpy (the sourced workspace)')
    assert _constants()['TOPICS'] == tuple(interfaces.STACK_TOPICS)


def test_launch_files_executables_and_parameter_files_are_installed():
    from ceco_bringup.supervisor import STACK_NODES

    nodes = _constants()['NODES']
    assert nodes == STACK_NODES  # the launch file and ceco run start the same executables
    prefix = _install_prefix()
    share = prefix / 'ceco_bringup' / 'share' / 'ceco_bringup'
    for src in (LAUNCH_FILE, XML_FILE):
        installed = share / 'launch' / src.name
        assert installed.is_file() and installed.read_text() == src.read_text(), installed
    for record in ('true', 'false'):
        assert (share / 'config' / f'recorder_gate_{record}.yaml').is_file()
    for node, pkg in nodes.items():
        exe = prefix / pkg / 'lib' / pkg / node
        assert exe.is_file() and os.access(exe, os.X_OK), exe
        params = prefix / pkg / 'share' / pkg / 'config' / f'{node}.yaml'
        doc = yaml.safe_load(params.read_text())
        # keyed /**/<node>: applies under any namespace (a bare key is ignored under /veh1)
        assert list(doc) == [f'/**/{node}'] and doc[f'/**/{node}']['ros__parameters'], params


def test_recorder_gate_files_are_the_nodes_defaults_and_ceco_runs_gate():
    from ceco_bringup import run
    from ceco_controller.controller_params import controller_parameters
    from ceco_plant_sim.plant_io import PLANT_PARAMETERS
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.preview_io import PREVIEW_PARAMETERS
    from ceco_v2x_preview.scenario import load_scenario

    defaults = {
        'preview_node': {s.name: s.default for s in PREVIEW_PARAMETERS},
        'plant_node': {s.name: s.default for s in PLANT_PARAMETERS},
        'mpc_node': {s.name: s.default for s in controller_parameters()},
        'baseline_node': {s.name: s.default for s in controller_parameters('baseline')},
    }
    config = ROOT / 'ceco_bringup' / 'config'
    off = yaml.safe_load((config / 'recorder_gate_false.yaml').read_text())
    on = yaml.safe_load((config / 'recorder_gate_true.yaml').read_text())
    assert set(off) == set(on) == {f'/**/{n}' for n in defaults}
    for node, table in defaults.items():
        values = off[f'/**/{node}']['ros__parameters']
        assert values == {k: table[k] for k in values}  # record:=false changes nothing
        assert set(on[f'/**/{node}']['ros__parameters']) == set(values)
    args = run.build_parser().parse_args(['--out', 'unused', '--scenario', 'sc03'])
    sc = load_scenario('sc03')
    params = run._params(args, sc, parse_quality('perfect'), 'ceco-ioch', sc.duration_s)
    for node, ran in (('plant_node', params[4]), ('preview_node', params[2])):
        gate = on[f'/**/{node}']['ros__parameters']
        assert gate == {k: ran[k] for k in gate}  # what ceco run sets


def test_default_launch_starts_preview_mpc_and_plant_on_sim_time(launch):
    started = launch()
    nodes = started['nodes']
    assert list(nodes) == ['preview_node', 'mpc_node', 'plant_node'] and started['recorder'] is None
    gate_off = f'{SHARE}/ceco_bringup/config/recorder_gate_false.yaml'
    assert nodes['mpc_node'] == {
        'package': 'ceco_controller',
        'namespace': '',
        'files': [f'{SHARE}/ceco_controller/config/mpc_node.yaml', gate_off],
        'params': {
            'scenario': 'sc03',
            'timing': 'lockstep',
            'use_sim_time': True,
            'autostart': True,
            'strategy': 'ceco-ioch',
        },
        'ros_args': ['--enclave', '/ceco/mpc_node'],
        'env': dict.fromkeys(SECURITY_VARS, ''),  # launch's own (unset here): no DDS security unless asked
    }
    assert nodes['preview_node']['params'] == {'scenario': 'sc03', 'timing': 'lockstep', 'use_sim_time': True}
    # drives /clock; realtime.start_gate: only a recorder makes a real-time plant wait before step 0
    assert nodes['plant_node']['params'] == {'scenario': 'sc03', 'timing': 'lockstep', 'realtime.start_gate': False}
    assert started['env'] == {}


def test_launch_arguments_select_controller_clock_namespace_and_autostart(launch):
    nodes = launch(strategy='baseline', timing='realtime', namespace='/veh1/', scenario='sc03_mild')['nodes']
    assert list(nodes) == ['preview_node', 'baseline_node', 'plant_node']
    assert nodes['baseline_node']['params'] == {
        'scenario': 'sc03_mild',
        'timing': 'realtime',
        'use_sim_time': False,
        'autostart': True,
    }
    assert {n['namespace'] for n in nodes.values()} == {'/veh1/'}  # launch_ros makes it absolute: /veh1
    assert launch(timing='realtime', use_sim_time='true')['nodes']['mpc_node']['params']['use_sim_time'] is True
    assert launch(use_sim_time='false')['nodes']['preview_node']['params']['use_sim_time'] is False
    assert launch(autostart='false')['nodes']['mpc_node']['params']['autostart'] is False


def test_record_adds_ros2_bag_record_of_fully_qualified_topics_and_the_gate(launch):
    started = launch(record='true', namespace='veh2')
    assert started['recorder'] == [
        'ros2',
        'bag',
        'record',
        '-s',
        'mcap',
        '--use-sim-time',
        '--topics',
        '/veh2/cabin/state',
        '/veh2/cabin/comfort',
        '/veh2/hvac/power',
        '/veh2/hvac/command',
        '/veh2/controller/diagnostics',
        '/veh2/v2x/weather_preview',
        '/veh2/v2x/traffic_preview',
        '/clock',
        '/rosout',
    ]
    gate_on = f'{SHARE}/ceco_bringup/config/recorder_gate_true.yaml'
    assert all(started['nodes'][n]['files'][-1] == gate_on for n in ('mpc_node', 'plant_node'))
    # the plant waits for the recorder in real time too (realtime.start_gate), so the bag has step 0
    assert started['nodes']['plant_node']['params']['realtime.start_gate'] is True
    assert launch(timing='realtime')['nodes']['plant_node']['params']['realtime.start_gate'] is False
    realtime = launch(record='true', timing='realtime', namespace='/a/b/')['recorder']
    assert '--use-sim-time' not in realtime and realtime[realtime.index('--topics') + 1] == '/a/b/cabin/state'
    assert launch(record='true')['recorder'][7] == '/cabin/state'


def test_security_runs_every_node_in_its_enclave_of_the_keystore(launch):
    started = launch(security='true', keystore='/keys/ceco')
    secured = {'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': 'Enforce', 'ROS_SECURITY_KEYSTORE': '/keys/ceco'}
    assert {n: v['env'] for n, v in started['nodes'].items()} == dict.fromkeys(started['nodes'], secured)
    assert {n: v['ros_args'] for n, v in started['nodes'].items()} == {
        n: ['--enclave', f'/ceco/{n}'] for n in ('preview_node', 'mpc_node', 'plant_node')
    }
    from ceco_bringup.security import ENCLAVES

    assert set(ENCLAVES) >= {f'/ceco/{n}' for n in _constants()['NODES']}  # the keystore has each enclave


def test_security_is_in_the_nodes_environment_never_in_launchs_own(monkeypatch, launch):
    """A ROS_SECURITY_* SetEnvironmentVariable (<set_env>) at the launch-description level changes
    launch's own environment: launch_ros's internal node (the lifecycle handling of LifecycleNode)
    was then created under DDS security and `ros2 launch ... security:=true` stopped before any
    node started ("error creating node: This Fast DDS version doesn't have the security
    libraries"). Each node process gets the variables (additional_env / <env>) instead."""
    for arguments in ({}, {'security': 'true', 'keystore': '/k'}, {'security': 'true', 'timing': 'realtime'}):
        assert launch(**arguments)['env'] == {} and _run_xml(**arguments)['env'] == {}
    tree = ast.parse(LAUNCH_FILE.read_text())
    called = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert 'SetEnvironmentVariable' not in called
    description = _python_description(monkeypatch)
    assert not [e for e in description if type(e).__name__ == 'SetEnvironmentVariable' and e.args[0] in SECURITY_VARS]
    assert not [e for e in ET.parse(XML_FILE).getroot().iter('set_env') if e.get('name') in SECURITY_VARS]
    # security:=false passes launch's own values on unchanged (as before: nothing was set then)
    monkeypatch.setitem(LAUNCH_ENVIRON, 'ROS_SECURITY_ENABLE', 'true')
    for started in (launch(), _run_xml()):
        env = started['nodes']['plant_node']['env']
        assert env == {'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': '', 'ROS_SECURITY_KEYSTORE': ''}


@pytest.mark.parametrize('timing', ['lockstep', 'realtime'])
def test_the_recorder_runs_secured_in_the_tools_enclave_with_security_on(monkeypatch, launch, timing):
    """security:=true record:=true: the plant waits for the recorder's subscriptions, and the recorder (`ros2 bag
    record`, which takes no --enclave) had none of the nodes' ROS_SECURITY_* variables, so it could never match a
    secured node and the plant waited for it without end. It now gets them and ROS_SECURITY_ENCLAVE_OVERRIDE, the
    ceco tools' enclave of `ceco security create-keystore`; with security off, launch's own values pass on."""
    from ceco_bringup.security import ENCLAVES

    secure = {'security': 'true', 'keystore': '/k', 'record': 'true', 'timing': timing}
    for started in (launch(**secure), _run_xml(**secure)):
        assert started['recorder'][:3] == ['ros2', 'bag', 'record']
        assert started['recorder_env'] == dict(
            started['nodes']['plant_node']['env'], ROS_SECURITY_ENCLAVE_OVERRIDE='/ceco/ceco'
        )
        assert started['nodes']['plant_node']['env']['ROS_SECURITY_KEYSTORE'] == '/k'
    assert '/ceco/ceco' in ENCLAVES  # the keystore has that enclave
    monkeypatch.setitem(LAUNCH_ENVIRON, 'ROS_SECURITY_ENCLAVE_OVERRIDE', '/mine')
    for started in (launch(record='true', timing=timing), _run_xml(record='true', timing=timing)):
        assert started['recorder_env'] == dict(
            started['nodes']['plant_node']['env'], ROS_SECURITY_ENCLAVE_OVERRIDE='/mine'
        )


COMBINATIONS = [
    dict(zip(('strategy', 'timing', 'use_sim_time', 'record', 'namespace'), combo, strict=True))
    for combo in itertools.product(
        ('ceco-ioch', 'baseline'), ('lockstep', 'realtime'), ('auto', 'false'), ('false', 'true'), ('', 'veh1')
    )
]


@pytest.mark.parametrize('arguments', COMBINATIONS, ids=lambda a: '-'.join(v or 'root' for v in a.values()))
def test_xml_front_end_starts_what_the_python_file_starts(launch, arguments):
    py, xml = launch(**arguments), _run_xml(**arguments)
    assert xml['nodes'] == py['nodes'] and xml['recorder'] == py['recorder'] and xml['env'] == py['env']
    secure = dict(arguments, security='true', keystore='/k', autostart='false', scenario='sc03_mild')
    assert _run_xml(**secure) == dict(launch(**secure), kinds=_run_xml(**secure)['kinds'])


@pytest.mark.parametrize('strategy', ['ceco-ioch', 'baseline'])
def test_launch_parameters_equal_ceco_run_parameters(launch, strategy):
    """Every parameter `ceco run` passes (default options, sc03, perfect previews)
    has the same value under `ros2 launch ... record:=true` (its own value or the
    installed files'): the same nodes with the same parameters."""
    from ceco_bringup import run
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    args = run.build_parser().parse_args(['--out', 'unused', '--scenario', 'sc03', '--strategy', strategy])
    scenario = load_scenario('sc03')
    _, _, preview, controller, plant = run._params(
        args, scenario, parse_quality('perfect'), strategy, scenario.duration_s
    )
    by_role = {'preview': preview, 'controller': controller, 'plant': plant}
    nodes = launch(strategy=strategy, record='true')['nodes']
    assert len(nodes) == 3
    for node, started in nodes.items():
        effective = {}
        for path in started['files']:  # the installed files, in order, then the launch's own values
            pkg, name = Path(path).parts[-3], Path(path).name
            doc = yaml.safe_load((ROOT / pkg / 'config' / name).read_text())
            effective.update(doc.get(f'/**/{node}', {}).get('ros__parameters', {}))
        effective.update(started['params'])
        for key, value in by_role[RUN_NODE[node]].items():
            got = effective.get(key, False if key == 'use_sim_time' else None)
            if key == 'duration_s':  # 0 in the file: the scenario's
                got = got or scenario.duration_s
            assert got == value, (node, key, got, value)
