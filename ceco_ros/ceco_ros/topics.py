"""The stack's topic names, in one place (plain strings: importing this module needs no rclpy).

Relative names (no leading slash) so namespaces and remapping work; ``/clock``,
``/rosout`` and ``/diagnostics`` are global by ROS 2 convention. The QoS of each
topic is in :mod:`ceco_ros.interfaces`; bag readers, the nodes' pure I/O logic and
the tools take the names from here.
"""

__all__ = [
    'TOPIC_STATE',
    'TOPIC_COMFORT',
    'TOPIC_POWER',
    'TOPIC_COMMAND',
    'TOPIC_WEATHER',
    'TOPIC_TRAFFIC',
    'TOPIC_DIAGNOSTICS',
    'TOPIC_CLOCK',
    'TOPIC_ROSOUT',
    'TOPIC_ROS_DIAGNOSTICS',
]

TOPIC_STATE = 'cabin/state'
"""ceco_msgs/CabinState: the plant's measurements, one per plant step."""
TOPIC_COMFORT = 'cabin/comfort'
"""ceco_msgs/Comfort: the occupant's scored comfort, one per plant step."""
TOPIC_POWER = 'hvac/power'
"""ceco_msgs/AcPower: the A/C powers and energies, one per plant step."""
TOPIC_COMMAND = 'hvac/command'
"""ceco_msgs/AcCommand: the supervisory command, one per control step."""
TOPIC_WEATHER = 'v2x/weather_preview'
"""ceco_msgs/WeatherPreview: ambient temperature, solar load and RH over the horizon."""
TOPIC_TRAFFIC = 'v2x/traffic_preview'
"""ceco_msgs/TrafficPreview: vehicle speed over the horizon."""
TOPIC_DIAGNOSTICS = 'controller/diagnostics'
"""ceco_msgs/ControllerDiagnostics: the controller's solve report, one per control step."""
TOPIC_CLOCK = '/clock'
"""rosgraph_msgs/Clock: the simulation clock (lockstep)."""
TOPIC_ROSOUT = '/rosout'
"""rcl_interfaces/Log: every node's log."""
TOPIC_ROS_DIAGNOSTICS = '/diagnostics'
"""diagnostic_msgs/DiagnosticArray of every node (absolute, as diagnostic_updater and the aggregator use)."""
