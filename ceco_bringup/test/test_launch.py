"""ceco_bringup/launch/ceco.launch.py without the launch packages (they are
not on PyPI; the file was run with the real Jazzy `ros2 launch`, docs/ros.md):
its structure read with `ast`, the executables and parameter files it names
found in the colcon install, and its argument logic executed against small
stand-ins for `launch` / `launch_ros` that record what the file builds, then
compared parameter by parameter with what `ceco run` starts."""

from __future__ import annotations

import ast
import importlib.util
import os
import sys
import types
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_FILE = ROOT / 'ceco_bringup' / 'launch' / 'ceco.launch.py'
ARGUMENTS = {
    'namespace': '',
    'strategy': 'ceco-ioch',
    'timing': 'lockstep',
    'use_sim_time': 'auto',
    'scenario': 'sc03',
    'record': 'false',
}
RUN_NODE = {'preview_node': 'preview', 'mpc_node': 'controller', 'baseline_node': 'controller', 'plant_node': 'plant'}


def _module_constants(tree: ast.Module) -> dict:
    """Module-level NAME = <literal> assignments."""
    out = {}
    for stmt in tree.body:
        if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1 and isinstance(stmt.targets[0], ast.Name):
            try:
                out[stmt.targets[0].id] = ast.literal_eval(stmt.value)
            except ValueError:
                pass
    return out


def _tree() -> ast.Module:
    return ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))


def _install_prefix() -> Path:
    return Path(os.environ.get('COLCON_PREFIX_PATH', str(ROOT / 'ros_ws' / 'install')).split(':')[0])


def test_launch_file_declares_the_documented_arguments():
    tree = _tree()
    consts = _module_constants(tree)
    declared = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', None) == 'DeclareLaunchArgument':
            kw = {k.arg: k.value for k in node.keywords}
            choices = kw.get('choices')
            if isinstance(choices, ast.Call):  # list(STRATEGIES)
                choices = choices.args[0]
            declared[ast.literal_eval(node.args[0])] = (
                ast.literal_eval(kw['default_value']),
                None
                if choices is None
                else (consts[choices.id] if isinstance(choices, ast.Name) else ast.literal_eval(choices)),
                bool(ast.literal_eval(kw['description'])),
            )
    assert list(declared) == list(ARGUMENTS)
    assert {k: v[0] for k, v in declared.items()} == ARGUMENTS
    assert all(v[2] for v in declared.values())  # every argument described
    assert declared['record'][1] == ['true', 'false'] and declared['use_sim_time'][1] == ['auto', 'true', 'false']
    assert declared['namespace'][1] is None and declared['scenario'][1] is None

    from ceco_core.contracts import STRATEGIES
    from ceco_core.control_grid import TIMING_MODES

    assert tuple(declared['strategy'][1]) == STRATEGIES == consts['STRATEGIES']
    assert tuple(declared['timing'][1]) == TIMING_MODES == consts['TIMING_MODES']
    # the docs list the same arguments
    ros_md = (ROOT / 'docs' / 'ros.md').read_text()
    for name in ARGUMENTS:
        assert f'`{name}`' in ros_md, name


def test_launch_file_topics_are_the_recorded_stack_topics():
    interfaces = pytest.importorskip('ceco_ros.interfaces', reason='needs rclpy (the sourced workspace)')
    assert _module_constants(_tree())['TOPICS'] == tuple(interfaces.STACK_TOPICS)


def test_launch_file_executables_and_parameter_files_are_installed():
    from ceco_bringup.supervisor import STACK_NODES

    nodes = _module_constants(_tree())['NODES']
    assert nodes == STACK_NODES  # the launch file and ceco run start the same executables
    assert set(nodes) == {'preview_node', 'mpc_node', 'baseline_node', 'plant_node'}
    prefix = _install_prefix()
    installed = prefix / 'ceco_bringup' / 'share' / 'ceco_bringup' / 'launch' / 'ceco.launch.py'
    assert installed.is_file() and installed.read_text() == LAUNCH_FILE.read_text(), installed
    for node, pkg in nodes.items():
        exe = prefix / pkg / 'lib' / pkg / node
        assert exe.is_file() and os.access(exe, os.X_OK), exe
        params = prefix / pkg / 'share' / pkg / 'config' / f'{node}.yaml'
        doc = yaml.safe_load(params.read_text())
        # keyed /**/<node>: applies under any namespace (a bare key is ignored under /veh1)
        assert list(doc) == [f'/**/{node}'] and doc[f'/**/{node}']['ros__parameters'], params


# ----------------------------------------------------------------------------
# The launch file executed against stand-ins that record its actions.
class _Action:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _stub_modules() -> dict:
    def action(name):
        return type(name, (_Action,), {})

    class LaunchConfiguration:
        def __init__(self, name):
            self.name = name

        def perform(self, context):
            return context[self.name]

    mods = {
        name: types.ModuleType(name)
        for name in (
            'launch',
            'launch.actions',
            'launch.substitutions',
            'launch_ros',
            'launch_ros.actions',
            'ament_index_python',
            'ament_index_python.packages',
        )
    }
    mods['launch'].LaunchDescription = lambda entities: list(entities)
    for name in ('DeclareLaunchArgument', 'ExecuteProcess', 'OpaqueFunction', 'Shutdown'):
        setattr(mods['launch.actions'], name, action(name))
    mods['launch.substitutions'].LaunchConfiguration = LaunchConfiguration
    mods['launch_ros.actions'].Node = action('Node')
    mods['ament_index_python.packages'].get_package_share_directory = lambda pkg: f'/opt/share/{pkg}'
    return mods


@pytest.fixture()
def launch(monkeypatch):
    """run(**arguments) -> the actions the launch file starts for them."""
    for name, mod in _stub_modules().items():
        monkeypatch.setitem(sys.modules, name, mod)
    spec = importlib.util.spec_from_file_location('ceco_launch_under_test', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    defaults = {
        a.args[0]: a.kwargs['default_value'] for a in description if type(a).__name__ == 'DeclareLaunchArgument'
    }
    opaque = [a for a in description if type(a).__name__ == 'OpaqueFunction']
    assert len(opaque) == 1 and defaults == ARGUMENTS

    def run(**arguments):
        unknown = set(arguments) - set(defaults)
        assert not unknown, unknown
        return opaque[0].kwargs['function'](dict(defaults, **arguments))

    return run


def _nodes(actions) -> dict:
    out = {}
    for a in actions:
        if type(a).__name__ == 'Node':
            kw = a.kwargs
            assert kw['executable'] == kw['name']
            params_file, overrides = kw['parameters']
            assert params_file == f'/opt/share/{kw["package"]}/config/{kw["name"]}.yaml'
            out[kw['name']] = (kw['namespace'], overrides)
    return out


def test_default_launch_starts_preview_mpc_and_plant_on_sim_time(launch):
    actions = launch()
    nodes = _nodes(actions)
    assert list(nodes) == ['preview_node', 'mpc_node', 'plant_node'] and len(actions) == 3
    assert nodes['mpc_node'] == (
        '',
        {'scenario': 'sc03', 'timing': 'lockstep', 'use_sim_time': True, 'autostart': True, 'strategy': 'ceco-ioch'},
    )  # managed: self-activates
    assert nodes['preview_node'] == ('', {'scenario': 'sc03', 'timing': 'lockstep', 'use_sim_time': True})
    assert nodes['plant_node'] == ('', {'scenario': 'sc03', 'timing': 'lockstep'})  # drives /clock


def test_launch_arguments_select_controller_clock_and_namespace(launch):
    nodes = _nodes(launch(strategy='baseline', timing='realtime', namespace='/veh1/', scenario='sc03_mild'))
    assert list(nodes) == ['preview_node', 'baseline_node', 'plant_node']
    assert nodes['baseline_node'] == (
        'veh1',
        {'scenario': 'sc03_mild', 'timing': 'realtime', 'use_sim_time': False, 'autostart': True},
    )
    assert {ns for ns, _ in nodes.values()} == {'veh1'}
    assert _nodes(launch(timing='realtime', use_sim_time='true'))['mpc_node'][1]['use_sim_time'] is True
    assert _nodes(launch(use_sim_time='false'))['preview_node'][1]['use_sim_time'] is False


def test_record_adds_ros2_bag_record_of_fully_qualified_topics_and_the_gate(launch):
    actions = launch(record='true', namespace='veh2')
    assert len(actions) == 4
    rec = actions[3]
    assert type(rec).__name__ == 'ExecuteProcess'
    assert rec.kwargs['cmd'] == [
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
    assert [type(a).__name__ for a in rec.kwargs['on_exit']] == ['Shutdown']
    plant = _nodes(actions)['plant_node'][1]
    assert (
        plant['lockstep.min_state_subscribers'],
        plant['lockstep.min_output_subscribers'],
        plant['lockstep.min_command_subscribers'],
    ) == (3, 1, 2)
    realtime = launch(record='true', timing='realtime')[3].kwargs['cmd']
    assert '--use-sim-time' not in realtime and realtime[realtime.index('--topics') + 1] == '/cabin/state'


@pytest.mark.parametrize('strategy', ['ceco-ioch', 'baseline'])
def test_launch_parameters_equal_ceco_run_parameters(launch, strategy):
    """Every parameter `ceco run` passes (default options, sc03, perfect previews)
    has the same value under `ros2 launch ... record:=true` (its own value or the
    installed file's): the same nodes with the same parameters."""
    from ceco_bringup import run
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    args = run.build_parser().parse_args(['--out', 'unused', '--strategy', strategy])
    scenario = load_scenario('sc03')
    _, _, preview, controller, plant = run._params(
        args, scenario, parse_quality('perfect'), strategy, scenario.duration_s
    )
    by_role = {'preview': preview, 'controller': controller, 'plant': plant}
    nodes = _nodes(launch(strategy=strategy, record='true'))
    assert len(nodes) == 3
    for node, (_, overrides) in nodes.items():
        pkg = _module_constants(_tree())['NODES'][node]
        params = yaml.safe_load((ROOT / pkg / 'config' / f'{node}.yaml').read_text())[f'/**/{node}']
        effective = dict(params['ros__parameters'], **overrides)
        for key, value in by_role[RUN_NODE[node]].items():
            got = effective.get(key, False if key == 'use_sim_time' else None)
            if key == 'duration_s':  # 0 in the file: the scenario's
                got = got or scenario.duration_s
            assert got == value, (node, key, got, value)
