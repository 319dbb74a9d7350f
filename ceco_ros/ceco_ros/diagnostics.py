"""/diagnostics for every ceco node.

A diagnostic_msgs/DiagnosticArray once per period of the steady (wall) clock, one
DiagnosticStatus per component, from the node's pure :class:`ceco_core.supervision.Health`
summaries.

Status names follow diagnostic_updater (``<node>: <component>``, the node's fully
qualified name without the leading slash, so two vehicles' namespaces stay apart);
``hardware_id`` is the node's namespace (``/`` without one).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType

from ceco_core.supervision import Health
from ceco_ros import interfaces

__all__ = ['diagnostic_array', 'DiagnosticsTimer']


def diagnostic_array(
    stamp, node_name: str, hardware_id: str, components: Sequence[tuple[str, Health]]
) -> DiagnosticArray:
    """One DiagnosticArray: a status per ``(component, health)``."""
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    for component, h in components:
        st = DiagnosticStatus(
            level=bytes([h.level]), name=f'{node_name}: {component}', message=h.message, hardware_id=hardware_id
        )
        st.values = [KeyValue(key=k, value=v) for k, v in h.values.items()]
        arr.status.append(st)
    return arr


class DiagnosticsTimer:
    """Publishes ``health()`` (a list of (component, Health)) on /diagnostics.

    Every ``period_s`` of the steady clock, so it keeps its pace whatever /clock does. Created
    in a node's constructor: a managed node reports in every lifecycle state.
    """

    def __init__(self, node, health: Callable[[], Sequence[tuple[str, Health]]], period_s: float = 1.0):
        self._node = node
        self._health = health
        self._name = node.get_fully_qualified_name().lstrip('/')
        self._hw = node.get_namespace()
        self.published = 0
        self._pub = node.create_publisher(DiagnosticArray, interfaces.TOPIC_ROS_DIAGNOSTICS, interfaces.QOS_DIAGNOSTICS)
        self._timer = node.create_timer(period_s, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def publish(self) -> None:
        """Publish the current health now."""
        try:
            components = self._health()
        except Exception as err:  # a report must never take the node down
            components = [('diagnostics', Health().error(f'health report failed: {err!r}'))]
        self._pub.publish(diagnostic_array(self._node.get_clock().now().to_msg(), self._name, self._hw, components))
        self.published += 1
