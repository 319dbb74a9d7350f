"""The ceco node stack for `ros2 launch` on a ROS 2 Jazzy install (apt, Docker).

    ros2 launch ceco_bringup ceco.launch.py strategy:=ceco-ioch
    ros2 launch ceco_bringup ceco.launch.py namespace:=veh1 timing:=realtime record:=true
    ros2 launch ceco_bringup ceco.launch.py --show-args

Starts the nodes `ceco run` starts with the same parameter files
(share/<package>/config/<node>.yaml, keyed `/**/<node>` so they apply in
any namespace): preview_node, the controller (mpc_node; baseline_node for
strategy:=baseline; a managed node, started with autostart:=true) and
plant_node. In lockstep the plant drives /clock and
the other two follow it (use_sim_time). record:=true adds `ros2 bag record`
(mcap) of the stack's topics, fully qualified, and makes the plant wait for
the recorder's subscriptions as under `ceco run`, so the bag starts at step 0
(if the recorder exits, everything stops).
Unlike `ceco run` it computes no metrics and keeps running after the drive
(the plant idles); Ctrl-C stops every process. Arguments: docs/ros.md, "Launch".
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction, Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

# Equal to ceco_core.contracts.STRATEGIES, ceco_core.control_grid.TIMING_MODES and
# ceco_ros.interfaces.STACK_TOPICS (tests/test_launch.py checks all three).
STRATEGIES = ('baseline', 'ceco', 'ceco-e', 'ceco-c', 'ceco-ioch')
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
# The plant's start gate with a recorder (as `ceco run` sets it): preview node,
# controller and recorder on cabin/state, the recorder on every plant output,
# plant and recorder on hvac/command.
RECORDER_GATE = {
    'lockstep.min_state_subscribers': 3,
    'lockstep.min_output_subscribers': 1,
    'lockstep.min_command_subscribers': 2,
}
# The controller's side of it: a command waits until plant and recorder have matched its publisher.
CONTROLLER_RECORDER_GATE = {'lockstep.min_command_subscribers': 2}


def generate_launch_description() -> LaunchDescription:
    """The launch arguments (namespace, strategy, timing, use_sim_time, scenario, record) and the stack.

    The processes are built by :func:`_stack` once the arguments are resolved (module docstring).
    """
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'namespace',
                default_value='',
                description='ROS namespace of the nodes and their topics, e.g. veh1 '
                '(one vehicle of several in one domain; realtime timing)',
            ),
            DeclareLaunchArgument(
                'strategy',
                default_value='ceco-ioch',
                choices=list(STRATEGIES),
                description='controller: baseline (baseline_node) or a CECO strategy (mpc_node)',
            ),
            DeclareLaunchArgument(
                'timing',
                default_value='lockstep',
                choices=list(TIMING_MODES),
                description='lockstep: accelerated, the plant drives /clock; '
                'realtime: wall-clock timers, as on a vehicle',
            ),
            DeclareLaunchArgument(
                'use_sim_time',
                default_value='auto',
                choices=['auto', 'true', 'false'],
                description='preview node and controller on /clock; auto: true in lockstep',
            ),
            DeclareLaunchArgument(
                'scenario', default_value='sc03', description='scenario name (bundled) or path of a scenario YAML file'
            ),
            DeclareLaunchArgument(
                'record',
                default_value='false',
                choices=['true', 'false'],
                description='true: ros2 bag record (mcap) of the stack topics into ./rosbag2_<date-time>',
            ),
            OpaqueFunction(function=_stack),
        ]
    )


def _stack(context):
    """The processes for the resolved launch arguments."""

    def arg(name):
        return LaunchConfiguration(name).perform(context)

    ns = arg('namespace').strip('/')
    timing = arg('timing')
    use_sim_time = timing == 'lockstep' if arg('use_sim_time') == 'auto' else arg('use_sim_time') == 'true'
    record = arg('record') == 'true'
    common = {'scenario': arg('scenario'), 'timing': timing}
    follower = dict(common, use_sim_time=use_sim_time)  # the plant publishes /clock, never follows it
    # The controllers are managed (lifecycle) nodes: autostart makes them configure and activate
    # themselves (`ros2 lifecycle get /mpc_node` then says active); `ceco run` drives them instead.
    managed = dict(follower, autostart=True, **(CONTROLLER_RECORDER_GATE if record else {}))
    if arg('strategy') == 'baseline':
        controller = _node('baseline_node', ns, managed)
    else:
        controller = _node('mpc_node', ns, dict(managed, strategy=arg('strategy')))
    actions = [
        _node('preview_node', ns, follower),
        controller,
        _node('plant_node', ns, dict(common, **(RECORDER_GATE if record else {}))),
    ]
    if record:
        prefix = f'/{ns}/' if ns else '/'
        topics = [t if t.startswith('/') else prefix + t for t in TOPICS]
        actions.append(
            ExecuteProcess(
                cmd=[
                    'ros2',
                    'bag',
                    'record',
                    '-s',
                    'mcap',
                    *(['--use-sim-time'] if use_sim_time else []),
                    '--topics',
                    *topics,
                ],
                name='recorder',
                output='screen',
                # the plant waits for the recorder: without it the stack would stall, so stop
                on_exit=[Shutdown(reason='the recorder (ros2 bag record) exited')],
            )
        )
    return actions


def _node(name, namespace, params):
    """`name` from its package with its installed parameter file, then `params`."""
    package = NODES[name]
    params_file = os.path.join(get_package_share_directory(package), 'config', f'{name}.yaml')
    return Node(
        package=package,
        executable=name,
        name=name,
        namespace=namespace,
        parameters=[params_file, params],
        output='screen',
    )
