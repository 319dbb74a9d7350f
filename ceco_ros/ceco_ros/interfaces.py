"""The stack's ROS 2 interfaces, named in one place: topic names, QoS profiles, timing modes.

Imports rclpy's QoS types; used by the ``*_node.py`` modules and by ``ceco_bringup``
only (the pure cores never import it).
"""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ceco_core import control_grid

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

TIMING_MODES = control_grid.TIMING_MODES
"""The nodes' timing modes (defined with the control-step grid)."""

PLANT_FALLBACK_STRATEGY = 'plant-fallback'
"""AcCommand.strategy of the commands the plant's own fallback law produces."""
