"""What every ceco node shares: clocks as floats, throttled notices, lifecycle plumbing.

* :class:`NodeTools` (mixin): ``wall_s()`` (steady clock [s], for wall-clock limits),
  ``clock_s()`` (the node clock [s]: /clock under use_sim_time), ``log(level, text)``,
  ``notice(key, text)`` (logged at most once per throttle period per key).
* :class:`ManagedNode`: an rclpy LifecycleNode that tracks its state as text
  (``self.lifecycle``), configures and activates itself when asked to (``autostart``), and
  releases what ``on_configure`` created on cleanup, shutdown and error (``release()``).
"""

from __future__ import annotations

from rclpy.clock import Clock, ClockType
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn

from ceco_core.supervision import Rejections

__all__ = ['NodeTools', 'ManagedNode', 'SUCCESS', 'FAILURE']

SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class NodeTools:
    """Mixin for an rclpy Node: call ``setup_tools`` in the constructor."""

    def setup_tools(self, throttle_s: float) -> None:
        """Create the steady clock and the notice throttle (``throttle_s`` [s])."""
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.notices = Rejections(throttle_s)
        """Counts and throttles the node's repeated notices (not rejections)."""

    @property
    def steady(self) -> Clock:
        """The steady clock (for timers on wall-clock time)."""
        return self._steady

    def wall_s(self) -> float:
        """Steady (monotonic wall) clock [s]."""
        return self._steady.now().nanoseconds * 1e-9

    def clock_s(self) -> float:
        """The node clock [s] (simulation time under use_sim_time)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def log(self, level: str, text: str) -> None:
        """Log ``text`` at 'debug', 'info', 'warn', 'error' or 'fatal'."""
        getattr(self.get_logger(), level)(text)

    def notice(self, key: str, text: str, level: str = 'warn') -> None:
        """Log ``text`` unless a notice of the same ``key`` was logged within the throttle period."""
        line = self.notices.add('notice', key, text, self.wall_s())
        if line:
            self.log(level, line)


class ManagedNode(NodeTools, LifecycleNode):
    """A lifecycle node that tracks its state and releases its entities.

    Subclasses create their entities in ``on_configure`` and destroy them in ``release()``;
    ``on_activate``/``on_deactivate`` call super() so the lifecycle publishers follow the state.
    """

    lifecycle = 'unconfigured'
    """'unconfigured', 'inactive', 'active' or 'finalized'."""

    def __init__(self, node_name: str, **kwargs):
        super().__init__(node_name, **kwargs)
        # rclpy 7.1 (Jazzy) raises out of the change_state service for a transition the current
        # state does not have (ros2/rclpy#1209, fixed upstream by #1319): the node would die on a
        # wrong `ros2 lifecycle set` or a second manager. Answer success=false instead, as rclcpp.
        service = self._service_change_state
        unsafe = service.callback

        def change_state(request, response):
            try:
                return unsafe(request, response)
            except _rclpy.RCLError as err:
                self.get_logger().warn(
                    f'lifecycle transition {request.transition.id} '
                    f'{request.transition.label!r} refused in state {self.lifecycle}: {err}'
                )
                response.success = False
                return response

        service.callback = change_state

    def start_managed(self, autostart: bool) -> None:
        """Call at the end of the constructor.

        With ``autostart``, configure and activate as soon as the node spins; otherwise wait for
        a lifecycle manager.
        """
        if autostart:
            self._auto = self.create_timer(0.0, self._autostart)

    def _autostart(self) -> None:
        self.destroy_timer(self._auto)
        if self.trigger_configure() == SUCCESS:
            self.trigger_activate()

    def configured(self) -> TransitionCallbackReturn:
        """Mark a successful configure (return its value from ``on_configure``)."""
        self.lifecycle = 'inactive'
        return SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        """Activate the lifecycle publishers."""
        self.lifecycle = 'active'
        return super().on_activate(state)

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        """Deactivate the lifecycle publishers."""
        self.lifecycle = 'inactive'
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        """Release everything; back to unconfigured."""
        self._release('unconfigured')
        return SUCCESS

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        """Release everything; finalized."""
        self._release('finalized')
        return SUCCESS

    def on_error(self, state) -> TransitionCallbackReturn:
        """Release everything after an error in a transition; back to unconfigured."""
        self._release('unconfigured')
        return SUCCESS

    def _release(self, new_state: str) -> None:
        if self.lifecycle in ('inactive', 'active'):
            self.release()
        self.lifecycle = new_state

    def release(self) -> None:
        """Destroy what ``on_configure`` created (override)."""
