"""The ceco node stack for `ros2 launch` on a ROS 2 Jazzy install (apt, Docker).

    ros2 launch ceco_bringup ceco.launch.py strategy:=ceco-ioch
    ros2 launch ceco_bringup ceco.launch.py namespace:=veh1 timing:=realtime record:=true
    ros2 launch ceco_bringup ceco.launch.py --show-args
    ros2 launch ceco_bringup ceco.launch.py --print-description

Starts the nodes `ceco run` starts with the same parameter files
(share/<package>/config/<node>.yaml, keyed `/**/<node>` so they apply in
any namespace): preview_node, the controller (mpc_node; baseline_node for
strategy:=baseline; a managed node, a launch_ros LifecycleNode) and plant_node.
In lockstep the plant drives /clock and the other two follow it (use_sim_time).
record:=true adds `ros2 bag record` (mcap) of the stack's topics, fully
qualified, and makes the plant wait for the recorder's subscriptions as under
`ceco run` (share/ceco_bringup/config/recorder_gate_true.yaml; in real time
also the plant's realtime.start_gate), so the bag starts at step 0 (if the
recorder exits, everything stops). security:=true runs every node in its SROS2
enclave of keystore:=DIR (`ceco security create-keystore DIR`): the
ROS_SECURITY_* variables go into each node's environment only, never into
launch's own (launch_ros's internal node, which drives the lifecycle, would be
secured too and fail without the keystore's enclave or, on a Fast DDS built
without security, stop the launch before any node starts). Every choice is a
substitution or a condition, so `--print-description` shows every process.
Unlike `ceco run` it computes no metrics and keeps running after the drive (the
plant idles); Ctrl-C stops every process. ceco.launch.xml is the same stack in the XML front-end. Arguments:
docs/ros.md, "Launch".
"""

from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    ExecuteProcess,
    LogInfo,
    RegisterEventHandler,
    SetLaunchConfiguration,
    Shutdown,
)
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import (
    AndSubstitution,
    EnvironmentVariable,
    EqualsSubstitution,
    IfElseSubstitution,
    LaunchConfiguration,
    NotSubstitution,
    PathJoinSubstitution,
    PythonExpression,
)
from launch_ros.actions import LifecycleNode, Node
from launch_ros.event_handlers import OnStateTransition
from launch_ros.parameter_descriptions import ParameterFile, ParameterValue
from launch_ros.substitutions import FindPackageShare

# Equal to ceco_core.contracts.NAMED_STRATEGIES, ceco_core.control_grid.TIMING_MODES and
# ceco_ros.interfaces.STACK_TOPICS (ceco_bringup/test/test_launch.py checks all three).
STRATEGIES = ('baseline', 'ceco', 'ceco-e', 'ceco-c', 'ceco-ioch', 'ceco-pmv', 'ceco-pmv-aq', 'ceco-pmv-door')
TIMING_MODES = ('lockstep', 'realtime')
TOPICS = (
    'cabin/state',
    'cabin/comfort',
    'hvac/power',
    'hvac/command',
    'controller/diagnostics',
    'v2x/weather_preview',
    'v2x/traffic_preview',
    '/clock',
    '/rosout',
)
# node name = executable name -> package; its parameters in share/<package>/config/<node>.yaml
NODES = {
    'preview_node': 'ceco_v2x_preview',
    'mpc_node': 'ceco_controller',
    'baseline_node': 'ceco_controller',
    'plant_node': 'ceco_plant_sim',
}
ARGUMENTS = (
    (
        'namespace',
        '',
        None,
        'ROS namespace of the nodes and their topics, e.g. veh1 (one vehicle of several in one domain)',
    ),
    ('strategy', 'ceco-ioch', STRATEGIES, 'controller: baseline (baseline_node) or a CECO strategy (mpc_node)'),
    ('timing', 'lockstep', TIMING_MODES, 'lockstep: accelerated, the plant drives /clock; realtime: wall-clock timers'),
    (
        'use_sim_time',
        'auto',
        ('auto', 'true', 'false'),
        'preview node and controller on /clock; auto: true in lockstep',
    ),
    ('scenario', 'sc03', None, 'scenario name (bundled) or path of a scenario YAML file'),
    (
        'record',
        'false',
        ('true', 'false'),
        'true: ros2 bag record (mcap) of the stack topics into ./rosbag2_<date-time>',
    ),
    (
        'autostart',
        'true',
        ('true', 'false'),
        'true: the controller configures and activates itself; false: it waits for ros2 lifecycle set',
    ),
    ('security', 'false', ('true', 'false'), 'true: SROS2 (DDS security, Enforce), each node in its enclave'),
    ('keystore', '', None, 'SROS2 keystore directory (ceco security create-keystore DIR); with security:=true'),
)
"""name, default, choices (None: free), description; declared in this order."""
ENCLAVE_ROOT = '/ceco'
"""Each node runs in the SROS2 enclave ENCLAVE_ROOT/<node> (ceco_bringup.security)."""
SECURITY_ENV = (('ROS_SECURITY_ENABLE', 'true'), ('ROS_SECURITY_STRATEGY', 'Enforce'), ('ROS_SECURITY_KEYSTORE', None))
"""With security:=true, each node process's environment (None: the keystore argument); false: launch's own values."""
RECORDER_ENCLAVE = f'{ENCLAVE_ROOT}/ceco'
"""The recorder's enclave under security:=true (ROS_SECURITY_ENCLAVE_OVERRIDE: `ros2 bag record` takes no
--enclave): the ceco tools' enclave of `ceco security create-keystore`."""


def generate_launch_description() -> LaunchDescription:
    """The launch arguments, the resolved choices, the environment and the four node actions plus the recorder."""
    cfg = {name: LaunchConfiguration(name) for name, *_ in ARGUMENTS}
    is_baseline = EqualsSubstitution(cfg['strategy'], 'baseline')
    share = {pkg: FindPackageShare(pkg) for pkg in set(NODES.values()) | {'ceco_bringup'}}
    # the recorder's start gate: the plant, the preview node and the controller wait for its subscriptions
    # (true) or not (false)
    gate = ParameterFile(
        [PathJoinSubstitution([share['ceco_bringup'], 'config', 'recorder_gate_']), cfg['record'], '.yaml']
    )
    common = {'scenario': cfg['scenario'], 'timing': cfg['timing']}
    # a node's own environment, not launch's: SetEnvironmentVariable would secure launch_ros's internal node too
    secure_env = {
        var: IfElseSubstitution(cfg['security'], value or cfg['keystore'], EnvironmentVariable(var, default_value=''))
        for var, value in SECURITY_ENV
    }
    # the recorder: the nodes' security variables and its enclave (with security on the plant waits for it)
    override = 'ROS_SECURITY_ENCLAVE_OVERRIDE'
    recorder_env = dict(
        secure_env,
        **{
            override: IfElseSubstitution(
                cfg['security'], RECORDER_ENCLAVE, EnvironmentVariable(override, default_value='')
            )
        },
    )
    follower = dict(common, use_sim_time=ParameterValue(LaunchConfiguration('sim_time'), value_type=bool))
    managed = dict(follower, autostart=ParameterValue(cfg['autostart'], value_type=bool))

    def node(name, params, extra_files=(), action=Node, **kwargs):
        pkg = NODES[name]
        files = [PathJoinSubstitution([share[pkg], 'config', f'{name}.yaml']), *extra_files]
        return action(
            package=pkg,
            executable=name,
            name=name,
            namespace=cfg['namespace'],
            parameters=[*files, params],
            ros_arguments=['--enclave', f'{ENCLAVE_ROOT}/{name}'],
            additional_env=secure_env,
            output='screen',
            **kwargs,
        )

    mpc = node(
        'mpc_node',
        dict(managed, strategy=cfg['strategy']),
        [gate],
        LifecycleNode,
        condition=UnlessCondition(is_baseline),
    )
    baseline = node('baseline_node', managed, [gate], LifecycleNode, condition=IfCondition(is_baseline))
    active = [
        RegisterEventHandler(
            OnStateTransition(
                target_lifecycle_node=controller,
                goal_state='active',
                entities=[LogInfo(msg=f'{name} is active: commanding the plant')],
            )
        )
        for name, controller in (('mpc_node', mpc), ('baseline_node', baseline))
    ]
    return LaunchDescription(
        [
            *(
                DeclareLaunchArgument(
                    name, default_value=default, description=text, **({'choices': list(ch)} if ch else {})
                )
                for name, default, ch, text in ARGUMENTS
            ),
            # auto: true in lockstep (the plant publishes /clock and never follows it)
            SetLaunchConfiguration(
                'sim_time',
                IfElseSubstitution(
                    EqualsSubstitution(cfg['use_sim_time'], 'auto'),
                    EqualsSubstitution(cfg['timing'], 'lockstep'),
                    cfg['use_sim_time'],
                ),
            ),
            # '' -> '/', 'veh2' or '/veh2/' -> '/veh2/': the recorder's fully qualified topic names
            SetLaunchConfiguration(
                'topic_prefix',
                PythonExpression(["'/' + ''.join(p + '/' for p in ['", cfg['namespace'], "'.strip('/')] if p)"]),
            ),
            node('preview_node', follower, [gate]),
            mpc,
            baseline,
            # real time: the plant starts at once (a vehicle), unless a recorder must get step 0
            node(
                'plant_node',
                dict(common, **{'realtime.start_gate': ParameterValue(cfg['record'], value_type=bool)}),
                [gate],
            ),
            *active,
            _recorder(True, AndSubstitution(cfg['record'], LaunchConfiguration('sim_time')), recorder_env),
            _recorder(
                False, AndSubstitution(cfg['record'], NotSubstitution(LaunchConfiguration('sim_time'))), recorder_env
            ),
        ]
    )


def _recorder(sim_time: bool, when, env) -> ExecuteProcess:
    """`ros2 bag record` of the stack's topics, fully qualified (``--use-sim-time`` if ``sim_time``), in ``env``."""
    prefix = LaunchConfiguration('topic_prefix')
    topics = [t if t.startswith('/') else [prefix, t] for t in TOPICS]
    return ExecuteProcess(
        cmd=['ros2', 'bag', 'record', '-s', 'mcap', *(['--use-sim-time'] if sim_time else []), '--topics', *topics],
        name='recorder',
        output='screen',
        additional_env=env,
        condition=IfCondition(when),
        # the plant waits for the recorder: without it the stack would stall, so stop
        on_exit=[Shutdown(reason='the recorder (ros2 bag record) exited')],
    )
