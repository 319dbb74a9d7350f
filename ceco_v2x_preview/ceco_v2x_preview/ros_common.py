"""ROS 2 glue shared by every ceco node: topic names, QoS profiles, parameter
declaration with descriptors, time-stamp conversions.

This module imports rclpy and is used by the ``*_node.py`` modules and by
``ceco_bringup`` only; the pure cores never import it. It lives in
``ceco_v2x_preview`` because that package is the root of the dependency chain
(``ceco_controller -> ceco_plant_sim -> ceco_v2x_preview``), so every node can
import it without a package cycle.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

from builtin_interfaces.msg import Time
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ceco_v2x_preview import control_grid

# --- Topics (relative, so namespaces and remapping work) -------------------
TOPIC_STATE = 'cabin/state'
TOPIC_COMFORT = 'cabin/comfort'
TOPIC_POWER = 'hvac/power'
TOPIC_COMMAND = 'hvac/command'
TOPIC_WEATHER = 'v2x/weather_preview'
TOPIC_TRAFFIC = 'v2x/traffic_preview'
TOPIC_DIAGNOSTICS = 'controller/diagnostics'
TOPIC_CLOCK = '/clock'
TOPIC_ROSOUT = '/rosout'

# --- QoS profiles ------------------------------------------------------------
# States and commands: reliable, keep-last, volatile. In lockstep the plant
# publishes as fast as the loop turns (hundreds of messages a second); the
# depth keeps several seconds of them in the writer so a subscriber that
# falls behind (the recorder) gets every one repaired by the reliable protocol.
QOS_STATE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1000,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_COMMAND = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
# Previews: reliable + transient-local, depth 1: a late joiner (a restarted
# controller) gets the latest forecast at once.
QOS_PREVIEW = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# /clock as published by the plant (a best-effort subscriber, as rclpy's
# TimeSource uses, matches a reliable publisher).
QOS_CLOCK = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1000,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
# The recorder's subscriptions: reliable KEEP_ALL, so a recorder that falls
# behind back-pressures instead of losing samples (transient-local where the
# publisher offers it, to get the latest preview even when subscribing late).
QOS_RECORD = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
QOS_RECORD_LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
QOS_ROSOUT = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1000,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

# Every topic of the stack: name -> (ROS type name, publisher QoS, recorder QoS).
STACK_TOPICS: dict[str, tuple[str, QoSProfile, QoSProfile]] = {
    TOPIC_STATE: ('ceco_msgs/msg/CabinState', QOS_STATE, QOS_RECORD),
    TOPIC_COMFORT: ('ceco_msgs/msg/Comfort', QOS_STATE, QOS_RECORD),
    TOPIC_POWER: ('ceco_msgs/msg/AcPower', QOS_STATE, QOS_RECORD),
    TOPIC_COMMAND: ('ceco_msgs/msg/AcCommand', QOS_COMMAND, QOS_RECORD),
    TOPIC_DIAGNOSTICS: ('ceco_msgs/msg/ControllerDiagnostics', QOS_COMMAND, QOS_RECORD),
    TOPIC_WEATHER: ('ceco_msgs/msg/WeatherPreview', QOS_PREVIEW, QOS_RECORD_LATCHED),
    TOPIC_TRAFFIC: ('ceco_msgs/msg/TrafficPreview', QOS_PREVIEW, QOS_RECORD_LATCHED),
    TOPIC_CLOCK: ('rosgraph_msgs/msg/Clock', QOS_CLOCK, QOS_RECORD),
    TOPIC_ROSOUT: ('rcl_interfaces/msg/Log', QOS_ROSOUT, QOS_RECORD_LATCHED),
}

STRATEGIES = ('baseline', 'ceco', 'ceco-e', 'ceco-c', 'ceco-ioch')
"""Strategy names on the wire (AcCommand.strategy); equal to
ceco_controller.strategies.STRATEGIES (tests/test_msgs.py checks it: this
package sits below ceco_controller and cannot import it)."""

TIMING_MODES = control_grid.TIMING_MODES
"""The nodes' timing modes (defined with the control-step grid)."""

PLANT_FALLBACK_STRATEGY = 'plant-fallback'
"""AcCommand.strategy of the commands the plant's own fallback law produces."""


# --- Time stamps --------------------------------------------------------------
def stamp_from_s(t_s: float) -> Time:
    """builtin_interfaces/Time from seconds (t >= 0), exact to the nanosecond."""
    ns = int(round(t_s * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def s_from_stamp(stamp: Time) -> float:
    """Seconds from a builtin_interfaces/Time."""
    return stamp.sec + stamp.nanosec * 1e-9


# --- Parameters ----------------------------------------------------------------
def declare(node, name: str, default: Any, description: str, *,
            float_range: tuple[float, float] | None = None,
            int_range: tuple[int, int] | None = None,
            choices: Sequence[str] | None = None,
            read_only: bool = True) -> Any:
    """Declare one parameter with a full descriptor and return its value.

    `description` carries the unit; `float_range`/`int_range` become the
    descriptor's range (rclpy rejects an out-of-range value at declaration,
    with a message naming the parameter). `choices` is checked here.
    Raises ValueError with the parameter name on any invalid value.
    """
    desc = ParameterDescriptor(name=name, description=description, read_only=read_only)
    if float_range is not None:
        desc.floating_point_range = [FloatingPointRange(
            from_value=float(float_range[0]), to_value=float(float_range[1]), step=0.0)]
        desc.additional_constraints = f'{float_range[0]} <= {name} <= {float_range[1]}'
    if int_range is not None:
        desc.integer_range = [IntegerRange(
            from_value=int(int_range[0]), to_value=int(int_range[1]), step=1)]
        desc.additional_constraints = f'{int_range[0]} <= {name} <= {int_range[1]}'
    if choices is not None:
        desc.additional_constraints = f'one of {", ".join(choices)}'
    try:
        value = node.declare_parameter(name, default, desc).value
    except Exception as err:  # rclpy: InvalidParameterValueException, type errors
        raise ValueError(f'invalid parameter {name}: {err}') from None
    if isinstance(default, float):
        if isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, float) or not math.isfinite(value):
            raise ValueError(f'invalid parameter {name}={value!r}: must be a finite number')
    if float_range is not None and not float_range[0] <= value <= float_range[1]:
        raise ValueError(f'invalid parameter {name}={value!r}: must lie in '
                         f'[{float_range[0]}, {float_range[1]}]')
    if int_range is not None and not int_range[0] <= value <= int_range[1]:
        raise ValueError(f'invalid parameter {name}={value!r}: must lie in '
                         f'[{int_range[0]}, {int_range[1]}]')
    if choices is not None and value not in choices:
        raise ValueError(f'invalid parameter {name}={value!r}: must be one of '
                         f'{", ".join(choices)}')
    return value


def load_scenario_param(name: str):
    """load_scenario for a node's `scenario` parameter; errors name the parameter."""
    from ceco_v2x_preview.scenario import load_scenario
    try:
        return load_scenario(name)
    except (ValueError, OSError) as err:
        raise ValueError(f'invalid parameter scenario={name!r}: {err}') from None


def run_node(node_factory, argv=None, name: str = 'node') -> int:
    """The Jazzy main: init, construct, spin; on any stop path destroy the node
    and shut down. A ValueError while constructing (an invalid parameter) is
    reported as one clear line and exits with status 2."""
    import sys

    import rclpy
    from rclpy.executors import ExternalShutdownException

    rclpy.init(args=argv)
    node = None
    try:
        node = node_factory()
        rclpy.spin(node)
    except ValueError as err:
        print(f'[FATAL] [{name}]: {err}', file=sys.stderr, flush=True)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
